# Runs CMD (a ;-list) and passes only if it exits non-zero AND its output matches REGEX: a clean, explained
# failure (not a crash: a signal or an exit code above 128 fails the test too).
#   cmake -DCMD=a;b;c -DREGEX=... -P expect_failure.cmake
execute_process(COMMAND ${CMD} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
if(rc EQUAL 0)
  message(FATAL_ERROR "expected a failure, got exit code 0")
endif()
if(NOT rc MATCHES "^[0-9]+$" OR rc GREATER 128)
  message(FATAL_ERROR "expected a clean error exit, got '${rc}' (a crash?)")
endif()
if(NOT "${out}${err}" MATCHES "${REGEX}")
  message(FATAL_ERROR "exit code ${rc}, but the output does not match '${REGEX}'")
endif()
