# ny_image_mean(<image> <region> <out>): the mean R;G;B of an EXR over the pixel region "WxH+X+Y" ("" for the
# whole image), by oiiotool. No statistics (an unreadable image) is a fatal error.
function(ny_image_mean image region out)
  set(cut "")
  if(region)
    set(cut --cut ${region})
  endif()
  execute_process(COMMAND oiiotool ${image} --ch R,G,B ${cut} --printstats OUTPUT_VARIABLE s ERROR_VARIABLE e)
  string(REGEX MATCH "Stats Avg: ([0-9.eE+-]+) ([0-9.eE+-]+) ([0-9.eE+-]+)" _ "${s}")
  if("${CMAKE_MATCH_3}" STREQUAL "")
    message(FATAL_ERROR "no statistics for ${image} (region '${region}'): ${s}${e}")
  endif()
  set(${out} "${CMAKE_MATCH_1};${CMAKE_MATCH_2};${CMAKE_MATCH_3}" PARENT_SCOPE)
endfunction()
