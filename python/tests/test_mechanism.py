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
