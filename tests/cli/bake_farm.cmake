# Bakes two small yarns on a Dask local cluster of 2 workers (scripts/bake_farm.py); a re-run skips both; the
# farm's model is the one `neuralyarn bake` makes alone with the same options (its kernel array, tables and
# sampling parameters equal: bakes do not depend on threads or on where they run; only timings differ).
set(args --paths 2e5 --bins 12x48x24x48 --t-steps 50 --r-steps 50 --m-steps 50 --t-samples 2000
         --r-samples 2000 --m-samples 20000 --fit-samples 1000)
file(REMOVE_RECURSE ${OUT})
execute_process(COMMAND ${PY} ${SRC}/scripts/bake_farm.py --out ${OUT} --presets fleece silk -- ${args}
                RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
if(NOT rc EQUAL 0 OR NOT o MATCHES "2 done, 0 skipped, 0 failed")
  message(FATAL_ERROR "bake_farm failed (${rc}): ${o}${e}")
endif()
execute_process(COMMAND ${PY} ${SRC}/scripts/bake_farm.py --out ${OUT} --presets fleece silk -- ${args}
                RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
if(NOT rc EQUAL 0 OR NOT o MATCHES "0 done, 2 skipped, 0 failed")
  message(FATAL_ERROR "the re-run did not skip the finished bakes (${rc}): ${o}${e}")
endif()
execute_process(COMMAND ${CLI} bake --preset fleece --threads 2 ${args} --out ${OUT}/alone.json
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE e)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "neuralyarn bake failed (${rc}): ${e}")
endif()
# The same model: everything but timings and dates (provenance, seconds).
execute_process(COMMAND ${PY} -c "import json, sys; a, b = (json.load(open(p)) for p in sys.argv[1:3]); keys = ['kernel_flat', 'fallback', 'calibration', 'r_shape', 'sampling', 'albedo_M']; bad = [k for k in keys if a.get(k) != b.get(k)]; print('differs:', bad) if bad else None; sys.exit(1 if bad or 'kernel_flat' not in a else 0)"
                        ${OUT}/fleece.json ${OUT}/alone.json RESULT_VARIABLE rc OUTPUT_VARIABLE o)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the farm's fleece model differs from the one baked alone: ${o}")
endif()
file(GLOB left ${OUT}/.*)
if(left)
  message(FATAL_ERROR "temporary files left: ${left}")
endif()
