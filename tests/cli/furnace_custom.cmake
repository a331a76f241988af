# The white furnace (tests/cpp/test_furnace.cpp) on a yarn beyond the presets (issue 19): a small bake of
# tests/data/good_custom.json at the paper's map resolution (2e6 paths, short training: its networks are
# rough, which is what the calibration's bound must cope with), then the furnace tests on that model only.
file(MAKE_DIRECTORY ${OUT})
execute_process(COMMAND ${CLI} bake --params ${PARAMS} --paths 2e6 --seed 5 --t-steps 2000 --r-steps 2000
                        --m-steps 4000 --out ${OUT}/custom.json
                RESULT_VARIABLE rc ERROR_VARIABLE e OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "bake of ${PARAMS} failed (${rc}): ${e}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E env NY_FURNACE_MODELS=${OUT}/custom.json NY_FURNACE_ONLY_LISTED=1
                        ${TESTS} --gtest_filter=Furnace.*
                RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
string(REGEX MATCHALL "[^\n]*(largest white-furnace|sampled furnace)[^\n]*" lines "${o}")
message(STATUS "${lines}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "furnace on ${OUT}/custom.json failed:\n${o}${e}")
endif()
