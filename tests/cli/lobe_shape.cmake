# The shipped model's lobe shapes against the explicit ply, in CI (issue 17): two independent small gathers
# (3e6 paths, seeds 11 and 12) and `neuralyarn check --maps-b`, which removes their noise, must keep the
# worst R and M L1 of the theta_i bins but the grazing one below MAX ("R,M"). The limits are today's values
# plus 15 %: repeated with seeds 13/14 they moved by 1 % at most, and the models before the relative M loss and
# the R azimuth table (model v2) read R 100 %, M 34 % (fleece) and R 85 %, M 47 % (gabardine); those before
# the R lobe's TT part (model v3) read R 45 % (silk, limit 17 %) and 59 % (gabardine, limit 31 %).
# The models re-baked on the maps of D32 (a path crosses the fiber it scatters into) read, worst R / M:
# fleece 32.8 / 28.5, silk 12.8 / 39.3, polyester 38.9 / 27.6, cotton 18.6 / 33.6, gabardine 27.3 / 26.4 %,
# 5-7 % below the M limits of fleece, polyester and cotton (the limits were kept, not raised).
# The R lobe over its fiber nodes (D38) reads worst R 23.8 / 12.3 / 25.3 / 14.1 / 22.7 % (fleece, silk,
# polyester, cotton, gabardine; silk keeps the surface fiber): the R limits are those plus 15 %, which the
# models before read 32.8, 38.9, 18.6 and 27.3 % against (all but silk's fail them).
# Since D42 the models are baked over 32 fiber cross-sections; the gathers here take the model's own (its
# provenance: packing seed and cross-sections), so the maps are independent draws of the same ply, their A/B
# difference path noise only. Those models read worst R / M
# 23.8 / 27.1 (fleece), 14.7 / 36.0 (silk), 21.9 / 26.7 (polyester), 13.0 / 32.8 (cotton), 22.8 / 24.8 %
# (gabardine): all limits kept but silk's R, 0.15 -> 0.17 (its 32-cross-section R reads 14.7 against 12.3 for
# the one-cross-section model on its own maps; on 2e7-path maps 14.0 against 12.4, scripts/bench_lobes.sh).
file(MAKE_DIRECTORY ${OUT})
file(READ ${MODEL} model_json)
string(JSON packing_seed ERROR_VARIABLE no_seed GET "${model_json}" provenance maps packing_seed)
string(JSON layouts ERROR_VARIABLE no_layouts GET "${model_json}" provenance maps layouts)
if(no_seed)
  set(packing_seed 1)
endif()
if(no_layouts)  # a model of one cross-section, before D42
  set(layouts 1)
endif()
foreach(seed 11 12)
  execute_process(COMMAND ${CLI} gather --preset ${PRESET} --paths 3e6 --seed ${seed}
                          --packing-seed ${packing_seed} --layouts ${layouts} --quiet
                          --out ${OUT}/${PRESET}_${seed}.nyrdm RESULT_VARIABLE rc ERROR_VARIABLE e OUTPUT_QUIET)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "gather ${PRESET} seed ${seed} failed (${rc}): ${e}")
  endif()
endforeach()
execute_process(COMMAND ${CLI} check ${MODEL} --maps ${OUT}/${PRESET}_11.nyrdm --maps-b ${OUT}/${PRESET}_12.nyrdm
                        --max-lobe-error ${MAX} RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
string(REGEX MATCH "worst L1 but the grazing bin[^\n]*" worst "${o}")
message(STATUS "${PRESET}: ${worst} (limits ${MAX})")
file(REMOVE ${OUT}/${PRESET}_11.nyrdm ${OUT}/${PRESET}_12.nyrdm)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${PRESET}: ${e}${worst}")
endif()
