# The explicit-fiber reference converges: renders of the same close-up that differ only in their seed agree
# in the ply region's mean colour. Backlit cotton is the hard case (fireflies: fiber paths of tens of events
# whose weight grew with every event, kernel/fiber_bsdf.h); this test keeps the sampler that bounds them.
#   cmake -DNY=<neuralyarn> -DCYCLES=<cycles> -DOUT=<dir> -DPRESET=<preset> -DLIGHTS=<rig> -DSAMPLES=<n>
#         -DSEEDS="1;2;..." -DTOL=<relative> -P seeds_agree.cmake
# Prints "seed spread R G B" (the largest relative distance of a seed's channel mean from the seeds' mean).
include(${CMAKE_CURRENT_LIST_DIR}/image_mean.cmake)
file(MAKE_DIRECTORY "${OUT}")
set(means "")
foreach(seed ${SEEDS})
  set(base "${OUT}/seeds_${PRESET}_${LIGHTS}_${seed}")
  execute_process(COMMAND ${NY} cycles-scene --preset ${PRESET} --lights ${LIGHTS} --ply-length 48 --seed ${seed}
                          --width 160 --height 80 --out ${base}.xml RESULT_VARIABLE rc ERROR_VARIABLE e)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "cycles-scene failed: ${e}")
  endif()
  execute_process(COMMAND ${CYCLES} --background --quiet --samples ${SAMPLES} --threads 2 --width 160 --height 80
                          --output ${base}.exr ${base}.xml RESULT_VARIABLE rc ERROR_VARIABLE e)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "cycles failed on seed ${seed}: ${e}")
  endif()
  # The ply's middle: 120 x 8 pixels where it crosses the frame (as render_check.cmake).
  ny_image_mean(${base}.exr 120x8+20+36 mean)
  string(REPLACE ";" "," mean "${mean}")
  list(APPEND means "${mean}")
endforeach()
execute_process(COMMAND python3 -c "
import sys
tol = float(sys.argv[1])
v = [[float(x) for x in s.split(',')] for s in sys.argv[2:]]
m = [sum(c) / len(c) for c in zip(*v)]
spread = [max(abs(s[c] / m[c] - 1) for s in v) for c in range(3)]
print('seed means', ' | '.join(' '.join('%.5f' % x for x in s) for s in v))
print('seed spread R G B', ' '.join('%.4f' % x for x in spread), 'tolerance', tol)
sys.exit(0 if all(x <= tol for x in spread) else 1)" ${TOL} ${means} RESULT_VARIABLE rc OUTPUT_VARIABLE o)
message("${o}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the seeds disagree beyond ${TOL}: the explicit-fiber reference does not converge")
endif()
