# `neuralyarn --version` names the revision the binary was built from (model and map files stamp the same
# string): a build after a commit must not keep the revision CMake configured at.
execute_process(COMMAND git rev-parse --short=12 HEAD WORKING_DIRECTORY ${SRC} OUTPUT_VARIABLE sha
                OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(STATUS "not a git checkout: nothing to compare")
  return()
endif()
execute_process(COMMAND ${CLI} --version OUTPUT_VARIABLE v OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT v MATCHES "\\+${sha}$")
  message(FATAL_ERROR "neuralyarn --version says '${v}', the checkout is at ${sha}")
endif()
message(STATUS "${v}")
