# `neuralyarn surface` and `cycles-scene --level surface` from the command line (issue 18, D44): a sheet of parallel
# plies walked with a ply-level model writes a surface file that a scene of the sheet's quad then draws; a patch
# without its period, and a yarn-level model on a file without yarns, are refused with one line and exit code 1.
file(MAKE_DIRECTORY ${OUT})
set(plies "")
foreach(j RANGE 0 20)
  math(EXPR y "(${j} - 10) * 4")
  string(APPEND plies "[-400, ${y}, 0, 400, ${y}, 0],")
endforeach()
string(REGEX REPLACE ",$" "" plies "${plies}")
set(quad "\"surface\": {\"vertices\": [-40, -40, 0, 40, -40, 0, 40, 40, 0, -40, 40, 0], \"triangles\": [0, 1, 2, 0, 2, 3]}")
file(WRITE ${OUT}/sheet.json "{\"format\": \"neuralyarn-plies 1\", \"ply_radius\": 1, \"plies\": [${plies}], \"period\": [4, 4], ${quad}}")
file(WRITE ${OUT}/no_period.json "{\"format\": \"neuralyarn-plies 1\", \"ply_radius\": 1, \"plies\": [${plies}]}")

function(run expect_rc pattern)
  execute_process(COMMAND ${CLI} ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL expect_rc)
    message(FATAL_ERROR "neuralyarn ${ARGN}: exit ${rc}, expected ${expect_rc}\n${out}${err}")
  endif()
  if(NOT "${out}${err}" MATCHES "${pattern}")
    message(FATAL_ERROR "neuralyarn ${ARGN}: output does not match '${pattern}':\n${out}${err}")
  endif()
endfunction()

run(0 "wrote ${OUT}/sheet_surface.json" surface --plies ${OUT}/sheet.json --model ${MODELS}/fleece.json --paths 2e4
    --quiet --out ${OUT}/sheet_surface.json)
file(READ ${OUT}/sheet_surface.json s)
if(NOT s MATCHES "\"format\": \"neuralyarn-surface 1\"" OR NOT s MATCHES "\"level\": \"plies\"")
  message(FATAL_ERROR "not a surface file of the ply level:\n${s}")
endif()
run(0 "0 curves" cycles-scene --preset fleece --plies ${OUT}/sheet.json --level surface --surface ${OUT}/sheet_surface.json
    --out ${OUT}/sheet.xml)
file(READ ${OUT}/sheet.xml x)
if(NOT x MATCHES "<mesh P=" OR NOT x MATCHES "<rgb_curves name=\"w0\"")
  message(FATAL_ERROR "the surface scene has no mesh or no weight curves")
endif()
run(1 "^neuralyarn: error: [^\n]*has no 'period'[^\n]*\n$" surface --plies ${OUT}/no_period.json
    --model ${MODELS}/fleece.json --out ${OUT}/x.json)
run(1 "^neuralyarn: error: [^\n]*yarn-level model[^\n]*has no yarns[^\n]*\n$" surface --plies ${OUT}/sheet.json
    --model ${MODELS}/fleece_yarn.json --out ${OUT}/x.json)
if(EXISTS ${OUT}/x.json)
  message(FATAL_ERROR "a refused surface wrote its file")
endif()
