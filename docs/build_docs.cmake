# Builds the manual with every warning an error: Doxygen (API reference, WARN_AS_ERROR in the Doxyfile)
# into OUT/api, then Sphinx (-W) into OUT. Usage: see docs/CMakeLists.txt.
set(ENV{HINDSIGHT_VERSION} "${VERSION}")  # the version Sphinx prints (docs/conf.py)
# The doctrees go too: a stale Sphinx environment has kept pages it had seen outside a toctree out of
# the rebuilt one, failing the build on a warning the sources no longer cause.
file(REMOVE_RECURSE ${OUT} ${OUT}/../doctrees)
file(MAKE_DIRECTORY ${OUT})
execute_process(COMMAND ${SPHINX} -W --keep-going -q -b html -d ${OUT}/../doctrees ${SOURCE} ${OUT}
                RESULT_VARIABLE code)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "sphinx-build failed (${code}): every warning above is an error")
endif()
execute_process(COMMAND ${DOXYGEN} ${DOXYFILE} RESULT_VARIABLE code)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "doxygen failed (${code}): every warning above is an error")
endif()
message("manual: ${OUT}/index.html, API reference: ${OUT}/api/index.html")
