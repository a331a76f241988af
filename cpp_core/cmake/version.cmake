# Writes OUT from IN with the checkout's git revision, at build time (the neuralyarn_version target runs it on
# every build): model and map files stamp the revision that made them, not the one CMake last configured at.
# configure_file leaves OUT untouched when its text is the same, so nothing rebuilds until the revision moves.
#   cmake -DSOURCE_DIR=... -DPROJECT_VERSION=... -DIN=version.h.in -DOUT=version.h -P version.cmake
execute_process(COMMAND git rev-parse --short=12 HEAD
                WORKING_DIRECTORY ${SOURCE_DIR}
                OUTPUT_VARIABLE NY_GIT_SHA OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
if(NOT NY_GIT_SHA)
  set(NY_GIT_SHA "unknown")
endif()
configure_file(${IN} ${OUT} @ONLY)
