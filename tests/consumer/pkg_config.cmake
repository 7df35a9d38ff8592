# ctest driver: install the built project into a scratch prefix and compile two programs with the
# compiler and pkg-config alone, as a Makefile would: the README's C++ example (main.cpp, the engine:
# hindsight-engine.pc) and examples/own_ode.cpp (engine and storage, static: pkg-config --static
# hindsight); each must run and pass its own check.
# Usage: cmake -DBUILD_DIR=... -DWORK_DIR=... -DREADME=... -DEXAMPLE=... -DCXX=... -P pkg_config.cmake
find_program(PKG_CONFIG pkg-config REQUIRED)
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix
                OUTPUT_QUIET RESULT_VARIABLE code)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${code})")
endif()
file(GLOB_RECURSE pc_files "${WORK_DIR}/prefix/*/hindsight.pc")
list(GET pc_files 0 pc_file)
get_filename_component(pc_dir "${pc_file}" DIRECTORY)
set(ENV{PKG_CONFIG_PATH} "${pc_dir}")

file(READ "${README}" page)
string(FIND "${page}" "\n```cpp\n" start)
math(EXPR start "${start} + 8")
string(SUBSTRING "${page}" ${start} -1 rest)
string(FIND "${rest}" "\n```" end)
math(EXPR end "${end} + 1")
string(SUBSTRING "${rest}" 0 ${end} block)
file(WRITE "${WORK_DIR}/main.cpp" "${block}")

foreach(case "readme|${WORK_DIR}/main.cpp|hindsight-engine|--shared" "own_ode|${EXAMPLE}|hindsight|--static")
  string(REPLACE "|" ";" case "${case}")
  list(GET case 0 name)
  list(GET case 1 source)
  list(GET case 2 package)
  list(GET case 3 static)  # --shared is pkg-config's default: dependencies of static libraries left out
  execute_process(COMMAND ${PKG_CONFIG} --cflags --libs ${static} ${package} OUTPUT_VARIABLE flags
                  RESULT_VARIABLE code ERROR_VARIABLE err OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "pkg-config ${package} failed: ${err}")
  endif()
  separate_arguments(flags UNIX_COMMAND "${flags}")
  set(program "${WORK_DIR}/${name}")
  execute_process(COMMAND ${CXX} -std=c++17 -O1 ${source} -o ${program} ${flags} RESULT_VARIABLE code
                  OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "compiling ${source} with pkg-config ${package} failed:\n${flags}\n${err}")
  endif()
  execute_process(COMMAND ${program} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  message("${name} (pkg-config ${static} ${package}): ${out}")
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${program} failed (${code}): ${out}${err}")
  endif()
endforeach()
