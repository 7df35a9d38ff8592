# ctest driver: install the built project into a scratch prefix, build a consumer project against it
# (with CONSUMER_ARGS, e.g. dependencies disabled), run it.
# With MARKDOWN=FILE the consumer is taken from that page instead of SOURCE_DIR, exactly as written (the
# README's example, the C++ tutorial).
separate_arguments(consumer_args UNIX_COMMAND "${CONSUMER_ARGS}")
set(executable consumer)
if(MARKDOWN)
  # The page's first ```cmake block is CMakeLists.txt; its add_executable(NAME SOURCE) names the program
  # to run and the file the page's first ```cpp block is written to.
  file(READ "${MARKDOWN}" page)
  set(SOURCE_DIR "${WORK_DIR}/source")
  file(REMOVE_RECURSE "${SOURCE_DIR}")
  set(blocks "")
  foreach(language cmake cpp)
    string(FIND "${page}" "\n```${language}\n" start)
    if(start EQUAL -1)
      message(FATAL_ERROR "${MARKDOWN} has no ```${language} block")
    endif()
    string(LENGTH "\n```${language}\n" length)
    math(EXPR start "${start} + ${length}")
    string(SUBSTRING "${page}" ${start} -1 rest)
    string(FIND "${rest}" "\n```" end)
    math(EXPR end "${end} + 1")
    string(SUBSTRING "${rest}" 0 ${end} block_${language})
  endforeach()
  if(NOT block_cmake MATCHES "add_executable\\(([A-Za-z0-9_]+) ([A-Za-z0-9_.]+)\\)")
    message(FATAL_ERROR "the ```cmake block of ${MARKDOWN} has no add_executable(NAME SOURCE)")
  endif()
  set(executable ${CMAKE_MATCH_1})
  file(WRITE "${SOURCE_DIR}/CMakeLists.txt" "${block_cmake}")
  file(WRITE "${SOURCE_DIR}/${CMAKE_MATCH_2}" "${block_cpp}")
endif()
foreach(step
    "${CMAKE_COMMAND};--install;${BUILD_DIR};--prefix;${WORK_DIR}/prefix"
    "${CMAKE_COMMAND};-S;${SOURCE_DIR};-B;${WORK_DIR}/build;-G;Ninja;-DCMAKE_BUILD_TYPE=Release;-DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix;${consumer_args}"
    "${CMAKE_COMMAND};--build;${WORK_DIR}/build"
    "${WORK_DIR}/build/${executable}")
  execute_process(COMMAND ${step} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  message("${out}")
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "step failed (${code}): ${step}\n${out}\n${err}")
  endif()
endforeach()
