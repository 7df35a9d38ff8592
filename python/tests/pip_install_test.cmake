# ctest driver: the Python package installed the usual way, offline, with Debian's tools (README,
# docs/guides/installing.md): a fresh virtual environment that sees Debian's NumPy, then
# `pip install --no-build-isolation .` from the checkout (pyproject.toml, setup.py building the extension
# in BUILD_DIR), then an import and one gradient from outside the checkout.
# Usage: cmake -DPYTHON=... -DSOURCE_DIR=... -DBUILD_DIR=... -DWORK_DIR=... -P pip_install_test.cmake
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(ENV{HINDSIGHT_CMAKE_BUILD_DIR} "${BUILD_DIR}")
set(ENV{PIP_NO_INDEX} "1")              # offline: nothing may come from a package index
set(ENV{PIP_DISABLE_PIP_VERSION_CHECK} "1")
set(ENV{PYTHONPATH} "")
set(venv "${WORK_DIR}/venv")
foreach(step
    "${PYTHON};-m;venv;--system-site-packages;${venv}"
    "${venv}/bin/pip;install;--no-build-isolation;--no-deps;${SOURCE_DIR}"
    "${venv}/bin/python;-c;import hindsight, numpy, os, sys; assert hindsight.__file__.startswith(sys.prefix), hindsight.__file__; r = hindsight.classic_gradient('decay', numpy.array([0.5, 2.0])); print(hindsight.__version__, r.psi, r.gradient); assert os.path.exists(os.path.join(os.path.dirname(hindsight.__file__), '__init__.pyi'))")
  execute_process(COMMAND ${step} WORKING_DIRECTORY "${WORK_DIR}" RESULT_VARIABLE code OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  message("${out}")
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "step failed (${code}): ${step}\n${out}\n${err}")
  endif()
endforeach()
