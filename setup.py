"""Builds the extension hindsight._hindsight with CMake for pip (pyproject.toml has the metadata).

The build directory is $HINDSIGHT_CMAKE_BUILD_DIR, else the checkout's build/ when the README's set-up
configured it (only the target hindsight_python is built there, so nothing is compiled twice), else a
fresh build/python-package with tests, benchmarks, examples, the tool and the manual switched off.
"""
import glob
import os
import re
import shutil
import subprocess
import sys

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

ROOT = os.path.dirname(os.path.abspath(__file__))


def project_version():
    """The version of CMakeLists.txt's project(), the one place it is set."""
    with open(os.path.join(ROOT, "CMakeLists.txt"), encoding="utf-8") as f:
        return re.search(r"project\(hindsight VERSION ([0-9.]+)", f.read()).group(1)


def cmake_build_dir():
    explicit = os.environ.get("HINDSIGHT_CMAKE_BUILD_DIR")
    if explicit:
        return os.path.abspath(explicit)
    readme_build = os.path.join(ROOT, "build")
    if os.path.exists(os.path.join(readme_build, "CMakeCache.txt")):
        return readme_build
    return os.path.join(ROOT, "build", "python-package")


class BuildWithCMake(build_py):
    """Copies the pure-Python files (build_py), then builds and adds the extension and the shared plot code."""

    def run(self):
        super().run()
        build = cmake_build_dir()
        if not os.path.exists(os.path.join(build, "CMakeCache.txt")):
            configure = ["cmake", "-S", ROOT, "-B", build, "-DCMAKE_BUILD_TYPE=Release",
                         f"-DPython3_EXECUTABLE={sys.executable}", "-DHINDSIGHT_BUILD_PYTHON=ON",
                         "-DHINDSIGHT_BUILD_TESTS=OFF", "-DHINDSIGHT_BUILD_BENCH=OFF", "-DHINDSIGHT_BUILD_CLI=OFF",
                         "-DHINDSIGHT_BUILD_EXAMPLES=OFF", "-DHINDSIGHT_BUILD_DOCS=OFF"]
            if shutil.which("ninja"):
                configure += ["-G", "Ninja"]
            if shutil.which("ccache"):
                configure += ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache", "-DCMAKE_C_COMPILER_LAUNCHER=ccache"]
            subprocess.check_call(configure)
        jobs = str(os.cpu_count() or 1)
        subprocess.check_call(["cmake", "--build", build, "--target", "hindsight_python", "-j", jobs])
        built = os.path.join(build, "python", "hindsight")
        extensions = glob.glob(os.path.join(built, "_hindsight*.so"))
        if len(extensions) != 1:
            raise RuntimeError(f"expected one extension _hindsight*.so in {built}, found {extensions}")
        target = os.path.join(self.build_lib, "hindsight")
        os.makedirs(target, exist_ok=True)
        for path in extensions + [os.path.join(built, name) for name in ("_plot_history.py", "history_columns.json")]:
            shutil.copy2(path, target)


class BinaryDistribution(Distribution):
    """The wheel holds a compiled extension: tag it for this platform and Python."""

    def has_ext_modules(self):
        return True


os.makedirs(os.path.join(ROOT, "build", "setuptools"), exist_ok=True)
setup(version=project_version(), cmdclass={"build_py": BuildWithCMake}, distclass=BinaryDistribution,
      options={"build": {"build_base": os.path.join("build", "setuptools")},
               "egg_info": {"egg_base": os.path.join("build", "setuptools")}})
