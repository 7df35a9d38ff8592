# Builds the manual with every warning an error: Doxygen (API reference, WARN_AS_ERROR in the Doxyfile)
# into OUT/api, then Sphinx (-W) into OUT. Usage: see docs/CMakeLists.txt.
file(REMOVE_RECURSE ${OUT})
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
