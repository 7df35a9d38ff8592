"""Shared fixtures of the Python module's tests (run by ctest as python.pytest, label python)."""
import os
import shutil

import pytest

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
