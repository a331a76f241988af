# Usage errors of `neuralyarn` exit 1 with a message naming the option (README: "Bad parameters are rejected with a
# message that names the parameter, and the exit code is 1"), not CLI11's own codes; --help and --version exit 0.
# Arguments: -DCLI=<neuralyarn>
function(run expect_rc pattern)
  execute_process(COMMAND ${CLI} ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL expect_rc OR NOT "${out}${err}" MATCHES "${pattern}")
    message(FATAL_ERROR "neuralyarn ${ARGN}: exit ${rc}, expected ${expect_rc} and '${pattern}'\n${out}${err}")
  endif()
endfunction()

run(1 "--layers: Value 0 not in range" cycles-scene --layers 0 --out unused.xml)
run(1 "--unit-scale: value 'nan' is not a finite number" cycles-scene --unit-scale nan --out unused.xml)
run(1 "--layer-pitch: value 1.5 is outside" cycles-scene --layers 2 --layer-pitch 1.5 --out unused.xml)
run(1 "not expected: --no-such-option" cycles-scene --no-such-option --out unused.xml)
run(1 "subcommand is required")
run(1 "--paths" gather --preset fleece --paths)
run(0 "cycles-scene" --help)
run(0 "\\+" --version)
