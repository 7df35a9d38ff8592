"""Shared fixtures of the Python module's tests (run by ctest as python.pytest, label python).

The session writes into a temp folder of its own (TMPDIR, tempfile and pytest's tmp_path point at it, and
so does every program a test starts); it is removed at the end, and a test that leaves anything else
there fails the session, naming it (the suite leaves the temp directory as it found it)."""
import os
import shutil
import tempfile

import pytest

_scratch = None


def pytest_configure(config):
    global _scratch
    _scratch = tempfile.mkdtemp(prefix="hindsight-pytest-")
    os.environ["TMPDIR"] = _scratch
    tempfile.tempdir = _scratch
    # pytest's tmp_path folders inside it too (by default pytest keeps its last three runs' folders in the
    # system temp directory).
    if not config.option.basetemp:
        config.option.basetemp = os.path.join(_scratch, "pytest-basetemp")


def pytest_sessionfinish(session, exitstatus):
    if _scratch is None:
        return
    # pytest's tmp_path folders are removed with the scratch folder.
    left = sorted(name for name in os.listdir(_scratch) if name != "pytest-basetemp")
    shutil.rmtree(_scratch, ignore_errors=True)
    if left:
        print(f"\nconftest: the tests left {len(left)} entries in the temp directory: {' '.join(left)}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED

# A small rod that evaluates in about a second (the CLI tests' coarse mesh).
COARSE = {"rod": {"elementsAlongLength": 20, "elementsThroughHeight": 4, "modeCount": 4}}
COARSE_SET = ["--set", "rod.elementsAlongLength=20", "--set", "rod.elementsThroughHeight=4", "--set", "rod.modeCount=4"]
# A tiny rod with a short simulation: milliseconds per evaluation (leak and repetition tests).
TINY = {"rod": {"elementsAlongLength": 8, "elementsThroughHeight": 2, "modeCount": 2, "endTime": 0.02,
                "rampTime": 0.01, "eslSamples": 4},
        "simulation": {"step": 1e-3}}


@pytest.fixture(scope="session")
def cli():
    """The hindsight executable built with the module (ctest sets HINDSIGHT_CLI)."""
    path = os.environ.get("HINDSIGHT_CLI") or shutil.which("hindsight")
    if not path:
        pytest.skip("no hindsight executable: built with HINDSIGHT_BUILD_CLI=OFF (ctest sets HINDSIGHT_CLI)")
    if not os.path.exists(path):
        pytest.fail(f"HINDSIGHT_CLI = {path} does not exist")
    return path
