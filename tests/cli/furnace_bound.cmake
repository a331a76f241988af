# `neuralyarn furnace MODEL --bound` (decisions D28): a shipped model is already bounded between its
# calibration centres, so the verb lowers no node and writes the file it read, byte for byte (a shipped file of an
# older layout stays in it);
# --out without --bound, and a model that does not exist, are refused and write nothing.
# Arguments: -DCLI=<neuralyarn> -DMODEL=<shipped model> -DOUT=<directory>
file(REMOVE_RECURSE ${OUT})
file(MAKE_DIRECTORY ${OUT})

foreach(step IN ITEMS "${MODEL};${OUT}/resaved.json" "${OUT}/resaved.json;${OUT}/bound.json")
  list(GET step 0 in)
  list(GET step 1 written_to)
  execute_process(COMMAND ${CLI} furnace ${in} --bound --out ${written_to}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0 OR NOT out MATCHES "bound between the calibration centres: 0 of 1980 nodes lowered")
    message(FATAL_ERROR "the shipped model was not bounded already (${rc}):\n${out}\n${err}")
  endif()
endforeach()
# The written model is the one it read: the same file, so the same calibration and fallback tables.
file(READ ${MODEL} original)
file(READ ${OUT}/resaved.json shipped)
file(READ ${OUT}/bound.json written)
if(NOT original STREQUAL shipped)
  message(FATAL_ERROR "--bound rewrote a model it did not lower")
endif()
string(JSON shipped_cal GET "${shipped}" kernel_flat)
string(JSON written_cal GET "${written}" kernel_flat)
string(JSON shipped_fb GET "${shipped}" fallback)
string(JSON written_fb GET "${written}" fallback)
if(NOT shipped_cal STREQUAL written_cal OR NOT shipped_fb STREQUAL written_fb)
  message(FATAL_ERROR "--bound changed a model it did not lower")
endif()

execute_process(COMMAND ${CLI} furnace ${MODEL} --out ${OUT}/lone.json RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR EXISTS ${OUT}/lone.json OR NOT err MATCHES "--out requires --bound")
  message(FATAL_ERROR "--out without --bound was accepted (${rc}): ${err}")
endif()
execute_process(COMMAND ${CLI} furnace ${OUT}/missing.json --bound RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR EXISTS ${OUT}/missing.json OR NOT err MATCHES "cannot open")
  message(FATAL_ERROR "a missing model was accepted (${rc}): ${err}")
endif()
