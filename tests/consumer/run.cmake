# ctest driver: install the built project into a scratch prefix, build a consumer project against it
# (with CONSUMER_ARGS, e.g. dependencies disabled), run it.
# With MARKDOWN=FILE the consumer is taken from that page instead of SOURCE_DIR, exactly as written (the
# README's example, the C++ tutorial).
# With SWAP=1 as well, the page's sentence "Swap `FullStorage` for `EXPRESSION` (`<HEADER>`, component
# `COMPONENT`" is applied to the program as a reader would: HEADER replaces the full_storage.h include,
# `const auto storage = EXPRESSION;` the FullStorage line, *storage the argument, and COMPONENT the
# CMake block's component. The consumer's output must then equal the unswapped program's (same gradient).
# CONSUMER_ARGS (dependencies disabled) hold only when COMPONENT is engine, as the engine claims to need
# nothing else; for another component the consumer is built with its dependencies found.
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
  set(program_file ${CMAKE_MATCH_2})
  if(SWAP)
    if(NOT page MATCHES "Swap `FullStorage` for `([^`]+)`[ \n]+\\(`<([^>]+)>`, component `([a-z]+)`")
      message(FATAL_ERROR "${MARKDOWN} has no sentence \"Swap `FullStorage` for `EXPRESSION` (`<HEADER>`, component `NAME`\"")
    endif()
    set(expression "${CMAKE_MATCH_1}")
    set(header "${CMAKE_MATCH_2}")
    set(component "${CMAKE_MATCH_3}")
    foreach(pattern "#include <hindsight/engine/full_storage.h>" "hindsight::FullStorage storage;" ", storage)"
                    "COMPONENTS engine" "hindsight::engine")
      string(FIND "${block_cpp}${block_cmake}" "${pattern}" found)
      if(found EQUAL -1)
        message(FATAL_ERROR "${MARKDOWN}: the example has no '${pattern}' for the swap sentence to replace")
      endif()
    endforeach()
    string(REPLACE "#include <hindsight/engine/full_storage.h>" "#include <${header}>" block_cpp "${block_cpp}")
    string(REPLACE "hindsight::FullStorage storage;" "const auto storage = ${expression};" block_cpp "${block_cpp}")
    string(REPLACE ", storage)" ", *storage)" block_cpp "${block_cpp}")
    string(REPLACE "COMPONENTS engine" "COMPONENTS ${component}" block_cmake "${block_cmake}")
    string(REPLACE "hindsight::engine" "hindsight::${component}" block_cmake "${block_cmake}")
    if(NOT component STREQUAL "engine")
      message("the swap sentence names component ${component}: built with its dependencies found")
      set(consumer_args "")
    endif()
    message("swapped program:\n${block_cpp}\n${block_cmake}")
  endif()
  file(WRITE "${SOURCE_DIR}/CMakeLists.txt" "${block_cmake}")
  file(WRITE "${SOURCE_DIR}/${program_file}" "${block_cpp}")
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
if(SWAP)
  # The unswapped program, from the consumer test that ran it (install.readme_consumer), printed the
  # same line: the strategy changes the memory, not the gradient.
  if(NOT EXISTS "${UNSWAPPED_WORK_DIR}/build/${executable}")
    message(FATAL_ERROR "no unswapped program in ${UNSWAPPED_WORK_DIR}/build (run install.readme_consumer first)")
  endif()
  execute_process(COMMAND "${UNSWAPPED_WORK_DIR}/build/${executable}" OUTPUT_VARIABLE unswapped RESULT_VARIABLE code)
  if(NOT code EQUAL 0 OR NOT out STREQUAL unswapped)
    message(FATAL_ERROR "the swapped program printed\n${out}but the README's program printed\n${unswapped}")
  endif()
endif()
