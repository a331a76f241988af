# bake -> check -> train -> fit on small data: each verb runs, writes what it says, and prints its numbers.
# Arguments: -DCLI=<neuralyarn> -DOUT=<directory>
file(REMOVE_RECURSE ${OUT})
file(MAKE_DIRECTORY ${OUT})
set(SMALL --t-steps 300 --r-steps 300 --m-steps 300 --m-samples 100000 --t-samples 20000 --r-samples 20000 --fit-samples 5000)

function(run_ok)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  set(LAST_OUT "${out}" PARENT_SCOPE)
endfunction()

run_ok(${CLI} bake --preset silk --paths 3e5 --bins 6x24x12x24 --quiet ${SMALL}
       --maps-out ${OUT}/silk.nyrdm --image ${OUT}/silk.png --out ${OUT}/silk.json)
foreach(f silk.nyrdm silk.png silk.json)
  if(NOT EXISTS ${OUT}/${f})
    message(FATAL_ERROR "bake did not write ${f}")
  endif()
endforeach()
if(NOT LAST_OUT MATCHES "network M 6-21-21-3.*sampling proxy +kappa_R [0-9.]+.*albedo vs map +mean abs error [0-9.]+")
  message(FATAL_ERROR "bake output lacks the summary:\n${LAST_OUT}")
endif()

run_ok(${CLI} check ${OUT}/silk.json --maps ${OUT}/silk.nyrdm --image ${OUT}/check.png --theta-i 30 --phi-i 90
       --forward-peaks --forward-shape arc)
if(NOT LAST_OUT MATCHES "energy vs map +R: mean relative error [0-9.]+ %" OR NOT EXISTS ${OUT}/check.png OR
   NOT LAST_OUT MATCHES "forward peak .*TT arc.*theta_i \\| share of M \\| width \\(deg\\) +\\| explained \\| ceiling")
  message(FATAL_ERROR "check output incomplete:\n${LAST_OUT}")
endif()
# --json writes the numbers as the bake stores them ("fidelity"): the same keys as the baked model's object.
run_ok(${CLI} check ${OUT}/silk.json --maps ${OUT}/silk.nyrdm --json ${OUT}/check.json)
file(READ ${OUT}/check.json checked)
file(READ ${OUT}/silk.json baked)
string(JSON baked_fidelity GET "${baked}" fidelity)
foreach(key albedo_mae_rel M_energy_rel_by_theta_i lobes)
  string(JSON v ERROR_VARIABLE missing GET "${checked}" ${key})
  string(JSON w ERROR_VARIABLE missing_baked GET "${baked_fidelity}" ${key})
  if(missing OR missing_baked)
    message(FATAL_ERROR "check --json lacks '${key}' (or the bake's fidelity does): ${missing} ${missing_baked}")
  endif()
endforeach()

run_ok(${CLI} train --maps ${OUT}/silk.nyrdm --out ${OUT}/trained.json --quiet ${SMALL} --m-widths 6-16-16-16-3)
file(READ ${OUT}/trained.json model)
if(NOT model MATCHES "\"format\": \"neuralyarn-model\"" OR NOT model MATCHES "6,[ \n]*16,[ \n]*16,[ \n]*16,[ \n]*3")
  message(FATAL_ERROR "train wrote an unexpected model")
endif()

# --m-choice image: the M candidates chosen by their close-up images against the maps' (D53), named in the provenance.
run_ok(${CLI} train --maps ${OUT}/silk.nyrdm --out ${OUT}/chosen.json --quiet ${SMALL} --m-candidates 2 --m-choice image)
file(READ ${OUT}/chosen.json model)
string(JSON score GET "${model}" provenance m_candidates score)
string(JSON n LENGTH "${model}" provenance m_candidates candidates)
if(NOT score MATCHES "close-up's whole frame" OR NOT n EQUAL 2)
  message(FATAL_ERROR "train --m-choice image did not score its candidates by the image fit: ${score} (${n})")
endif()
# ... and its report names that score, not the 4D one.
if(NOT LAST_OUT MATCHES "kept #[12]\n +score: mean over the front" OR LAST_OUT MATCHES "M lobe L1")
  message(FATAL_ERROR "train --m-choice image reported another score:\n${LAST_OUT}")
endif()

# --m-choice image-centre: the frame and the close-up's central region (D54), named so.
run_ok(${CLI} train --maps ${OUT}/silk.nyrdm --out ${OUT}/chosen_centre.json --quiet ${SMALL} --m-candidates 2
       --m-choice image-centre)
file(READ ${OUT}/chosen_centre.json model)
string(JSON score GET "${model}" provenance m_candidates score)
if(NOT score MATCHES "close-up's whole frame and central region")
  message(FATAL_ERROR "train --m-choice image-centre did not score the central region too: ${score}")
endif()

run_ok(${CLI} fit ${OUT}/trained.json --maps ${OUT}/silk.nyrdm --samples 3000 --out ${OUT}/refit.json)
if(NOT LAST_OUT MATCHES "sampling proxy" OR NOT EXISTS ${OUT}/refit.json)
  message(FATAL_ERROR "fit output incomplete:\n${LAST_OUT}")
endif()

# fit leaves no fidelity numbers of the lobes before it: it drops them, or measures them again with --check-maps.
run_ok(${CLI} fit ${OUT}/silk.json --maps ${OUT}/silk.nyrdm --samples 3000 --out ${OUT}/refit_plain.json)
file(READ ${OUT}/refit_plain.json model)
if(NOT model MATCHES "\"fidelity\": {}" OR NOT model MATCHES "\"refit\": {")
  message(FATAL_ERROR "fit kept the fidelity numbers of the model before it")
endif()
run_ok(${CLI} fit ${OUT}/silk.json --maps ${OUT}/silk.nyrdm --samples 3000 --check-maps ${OUT}/silk.nyrdm
       --out ${OUT}/refit_checked.json)
file(READ ${OUT}/refit_checked.json model)
if(NOT LAST_OUT MATCHES "energy vs map" OR NOT model MATCHES "\"fidelity\": {[^}]*\"albedo")
  message(FATAL_ERROR "fit --check-maps did not measure the fidelity again:\n${LAST_OUT}")
endif()
# A ply has no plies: R node frames of its surface are refused, and nothing is written.
execute_process(COMMAND ${CLI} fit ${OUT}/silk.json --maps ${OUT}/silk.nyrdm --r-surface-spread 0.6
                        --out ${OUT}/refit_frames.json RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "yarn-level model" OR EXISTS ${OUT}/refit_frames.json)
  message(FATAL_ERROR "R node frames were accepted for a ply (${rc}): ${err}")
endif()

# fit --retrain-r trains the R network again (D65): the bake's RGB network (3-7-7-3, the default) becomes the one of
# the widths asked for, named in the provenance; widths that are neither 3 -> 1 nor 3 -> 3 are refused, and
# nothing is written.
file(READ ${OUT}/silk.json baked_model)
string(JSON baked GET "${baked_model}" networks R widths 3)
run_ok(${CLI} fit ${OUT}/silk.json --maps ${OUT}/silk.nyrdm --samples 3000 --retrain-r --r-widths 3-7-7-1
       --r-steps 300 --r-samples 20000 --out ${OUT}/refit_r.json)
file(READ ${OUT}/refit_r.json model)
string(JSON outputs GET "${model}" networks R widths 3)
string(JSON retrained GET "${model}" provenance refit retrained)
if(NOT baked EQUAL 3 OR NOT outputs EQUAL 1 OR NOT retrained STREQUAL "R 3-7-7-1" OR NOT LAST_OUT MATCHES "network R 3-7-7-1")
  message(FATAL_ERROR "fit --retrain-r: baked R outputs ${baked}, re-fitted ${outputs} (${retrained}):\n${LAST_OUT}")
endif()
execute_process(COMMAND ${CLI} fit ${OUT}/silk.json --maps ${OUT}/silk.nyrdm --retrain-r --r-widths 3-7-7-2
                        --out ${OUT}/refit_r2.json RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "maps 3 inputs to 3 outputs \\(RGB\\) or to 1" OR EXISTS ${OUT}/refit_r2.json)
  message(FATAL_ERROR "an R network of two outputs was accepted (${rc}): ${err}")
endif()

# A model for silk checked against fleece maps is refused with a message, and nothing is written.
run_ok(${CLI} gather --preset fleece --paths 2e4 --bins 6x24x12x24 --quiet --out ${OUT}/fleece.nyrdm)
execute_process(COMMAND ${CLI} check ${OUT}/silk.json --maps ${OUT}/fleece.nyrdm RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "gathered for preset 'fleece'")
  message(FATAL_ERROR "mismatched maps were accepted (${rc}): ${err}")
endif()
