"""hindsight.Mechanism: a described mechanism (docs/tutorials/own_mechanism.md) evaluates as the CLI's
--config does, and a bad description raises ValueError naming the element."""
import json
import os
import subprocess

import pytest

import hindsight
from conftest import COARSE, COARSE_SET

FOUR_BAR = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "mechanisms", "four_bar.json")


def test_four_bar_equals_cli(cli):
    m = hindsight.Mechanism(FOUR_BAR, **COARSE)
    r = m.evaluate(m.x0, gradient=True)
    out = subprocess.run([cli, "evaluate", "--json", "--config", FOUR_BAR] + COARSE_SET,
                         check=True, capture_output=True, text=True).stdout
    assert r.psi1 == json.loads(out)["psi1"]
    assert r.dpsi1_dx.shape == m.x0.shape


def test_description_as_a_dict():
    with open(FOUR_BAR) as f:
        description = json.load(f)["mechanism"]
    a = hindsight.Mechanism(description, **COARSE).evaluate(gradient=False)
    b = hindsight.Mechanism(FOUR_BAR, **COARSE).evaluate(gradient=False)
    assert a.psi1 == b.psi1


def test_bad_joint_is_named():
    with open(FOUR_BAR) as f:
        description = json.load(f)["mechanism"]
    description["joints"][2]["point1"] = "C"
    with pytest.raises(ValueError, match=r"mechanism.joints\[rockerPin\].point1 = 'C'"):
        hindsight.Mechanism(description, **COARSE)


def test_scenarios_of_a_described_mechanism_optimize_from_python(tmp_path):
    # examples/mechanisms/four_bar_scenarios.json: the drivers' speeds, a ramp and gravity per scenario
    # (docs/guides/mpi_and_threads.md); one update, every scenario's history in the results file.
    with open(os.path.join(os.path.dirname(FOUR_BAR), "four_bar_scenarios.json")) as f:
        config = json.load(f)
    config["rod"] = {"elementsAlongLength": 20, "elementsThroughHeight": 4, "modeCount": 3, "endTime": 2.5}
    config["optimization"]["iterations"] = 1
    hindsight.optimize(config, out=str(tmp_path / "run"))
    results = hindsight.read_results(str(tmp_path / "run" / "results.h5"))
    assert results["scenarios"].shape == (2, 4)
    psi1 = results["scenarios"][0]
    assert len(set(psi1.tolist())) == 4  # four different operating cases
    config["scenarios"][0]["drivers"] = {"motr": {"speed": 3.0}}
    with pytest.raises(ValueError, match=r"scenarios\[0\]\.drivers\.motr is not a driver of the mechanism"):
        hindsight.optimize(config, out=str(tmp_path / "bad"))
    assert not (tmp_path / "bad").exists()
