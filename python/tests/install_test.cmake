# ctest driver: install the built project into a scratch prefix and import the package there with
# Debian's python3, the package directory found by site.getsitepackages([PREFIX]) (Debian's rules),
# from a directory outside the source and build trees.
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix}
                RESULT_VARIABLE code OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "install failed (${code}): ${err}")
endif()
set(script [=[
import os, site, sys
prefix = sys.argv[1]
sys.path[:0] = [p for p in site.getsitepackages([prefix]) if os.path.isdir(p)]
import hindsight
assert hindsight.__file__.startswith(prefix), hindsight.__file__
rod = hindsight.PistonRod({"rod": {"elementsAlongLength": 20, "elementsThroughHeight": 4, "modeCount": 4}})
r = rod.evaluate(rod.x0, gradient=False)
assert r.psi1 > 0, r.psi1
print("installed package", os.path.dirname(hindsight.__file__), "psi1", r.psi1)
]=])
execute_process(COMMAND ${PYTHON} -c "${script}" ${prefix} WORKING_DIRECTORY ${WORK_DIR}
                RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}")
if(NOT code EQUAL 0)
  message(FATAL_ERROR "import from the installed prefix failed (${code}):\n${out}\n${err}")
endif()
