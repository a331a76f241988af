# Renders a neuralyarn scene with the patched standalone Cycles and checks the image.
#
#   cmake -DNY=<neuralyarn> -DCYCLES=<cycles> -DOUT=<dir> -DNAME=<name> -DSCENE_ARGS="a;b;..."
#         -DSAMPLES=<n> -DCHECK=<finite|furnace> -P render_check.cmake
#
# finite:  no NaN/Inf anywhere and the ply region is not black (mean > 1e-3);
# furnace: the ply region of a white-furnace render averages within [LOW, HIGH] (albedo-1 fibers under a
#          uniform white environment must vanish: energy conservation of the closure inside Cycles);
# predicted: the ply region equals, within relative TOL, what `cycles-scene --predict-region` printed
#          (the aggregated model's image mean from the core library for the same pixels, under the
#          environment or a distant-light rig).
if(NOT EXISTS "${CYCLES}")
  message(FATAL_ERROR "patched Cycles not built at ${CYCLES}: run scripts/build_cycles.sh (scripts/test.sh does)")
endif()
include(${CMAKE_CURRENT_LIST_DIR}/image_mean.cmake)
file(MAKE_DIRECTORY "${OUT}")
set(scene "${OUT}/${NAME}.xml")
set(image "${OUT}/${NAME}.exr")
execute_process(COMMAND ${NY} cycles-scene ${SCENE_ARGS} --out ${scene} RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cycles-scene failed: ${o}${e}")
endif()
if(CHECK STREQUAL "predicted")
  string(REGEX MATCH "predicted model ([0-9.eE+-]+) ([0-9.eE+-]+) ([0-9.eE+-]+)" _ "${o}")
  set(expected "${CMAKE_MATCH_1};${CMAKE_MATCH_2};${CMAKE_MATCH_3}")
  if(NOT CMAKE_MATCH_3)
    message(FATAL_ERROR "cycles-scene printed no prediction: ${o}")
  endif()
endif()
execute_process(COMMAND ${CYCLES} --background --quiet --samples ${SAMPLES} --threads 2 --width 160 --height 80
                        --output ${image} ${scene}
                RESULT_VARIABLE rc OUTPUT_VARIABLE o ERROR_VARIABLE e)
if(NOT rc EQUAL 0 OR NOT EXISTS "${image}")
  message(FATAL_ERROR "cycles failed (${rc}): ${o}${e}")
endif()
if(e MATCHES "error")
  message(FATAL_ERROR "cycles reported an error: ${e}")
endif()

# Whole image: finite.
execute_process(COMMAND oiiotool --stats ${image} OUTPUT_VARIABLE stats RESULT_VARIABLE rc)
string(REGEX MATCH "NanCount: ([0-9]+) ([0-9]+) ([0-9]+)" _ "${stats}")
set(nan "${CMAKE_MATCH_1}${CMAKE_MATCH_2}${CMAKE_MATCH_3}")
string(REGEX MATCH "InfCount: ([0-9]+) ([0-9]+) ([0-9]+)" _ "${stats}")
set(inf "${CMAKE_MATCH_1}${CMAKE_MATCH_2}${CMAKE_MATCH_3}")
if(NOT nan STREQUAL "000" OR NOT inf STREQUAL "000")
  message(FATAL_ERROR "non-finite pixels: NaN ${nan}, Inf ${inf}\n${stats}")
endif()

# The ply region (REGION, default the 8 middle rows) where the ply crosses the frame (radius 1 at distance
# 12, vertical fov 0.9: the ply is ~14 pixels high at 160 x 80).
if(NOT REGION)
  set(REGION 120x8+20+36)
endif()
ny_image_mean(${image} ${REGION} mean)
list(GET mean 0 r)
list(GET mean 1 g)
list(GET mean 2 b)
message(STATUS "${NAME}: ply region mean ${r} ${g} ${b}")
if(CHECK STREQUAL "finite")
  if(r LESS 0.001 AND g LESS 0.001 AND b LESS 0.001)
    message(FATAL_ERROR "the ply region is black: ${r} ${g} ${b}")
  endif()
elseif(CHECK STREQUAL "predicted")
  # CMake has no floating-point arithmetic: Debian's python3 checks |rendered - predicted| <= TOL predicted + 5e-4.
  message(STATUS "${NAME}: rendered ${r} ${g} ${b}, predicted ${expected}")
  execute_process(COMMAND python3 -c "import sys; r=[float(x) for x in sys.argv[1:4]]; p=[float(x) for x in sys.argv[4:7]]; t=float(sys.argv[7]); bad=[(a,b) for a,b in zip(r,p) if abs(a-b)>t*b+5e-4]; print('mismatch', bad) if bad else None; sys.exit(1 if bad else 0)"
                          ${r} ${g} ${b} ${expected} ${TOL} RESULT_VARIABLE rc OUTPUT_VARIABLE o)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "aggregated ply: rendered ${r} ${g} ${b}, predicted ${expected} (tolerance ${TOL} relative): ${o}")
  endif()
elseif(CHECK STREQUAL "furnace")
  foreach(v ${r} ${g} ${b})
    if(v LESS "${LOW}" OR v GREATER "${HIGH}")
      message(FATAL_ERROR "white furnace: ply region mean ${v} outside [${LOW}, ${HIGH}]")
    endif()
  endforeach()
endif()
