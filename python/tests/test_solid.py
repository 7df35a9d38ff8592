"""The rod as a solid through the module (rod.elementsThroughThickness >= 1): designs and gradients are
(nz, ny, nx) arrays, and psi1 and dpsi1/dx are `hindsight evaluate`'s bit for bit."""
import json
import subprocess

import h5py
import numpy as np
import pytest

import hindsight

SOLID = {"elementsAlongLength": 12, "elementsThroughHeight": 4, "elementsThroughThickness": 2,
         "modeCount": 6, "endTime": 1.0, "rampTime": 1.0}


def test_solid_rod_evaluates_as_the_cli_does(cli, tmp_path):
    rod = hindsight.PistonRod(rod=SOLID)
    assert rod.shape == (2, 4, 12)
    assert rod.design_count == 10 * 4 * 2
    r = rod.evaluate(rod.x0, gradient=True, psi2=False)
    assert r.psi1 > 0.0
    assert r.dpsi1_dx.shape == (2, 4, 12)
    # The end columns are not design variables: zero gradient there.
    assert np.all(r.dpsi1_dx[:, :, 0] == 0.0) and np.all(r.dpsi1_dx[:, :, -1] == 0.0)
    gradient = tmp_path / "g.h5"
    args = [cli, "evaluate", "--json", "--gradient", str(gradient), "--force"]
    for key, value in SOLID.items():
        args += ["--set", f"rod.{key}={value}"]
    expected = json.loads(subprocess.run(args, check=True, capture_output=True, text=True).stdout)
    assert r.psi1 == expected["psi1"]
    with h5py.File(gradient, "r") as f:
        assert f["dpsi1_dx"][()].tobytes() == r.dpsi1_dx.tobytes()


def test_a_bad_layer_count_names_the_field():
    with pytest.raises(ValueError, match="rod.elementsThroughThickness"):
        hindsight.PistonRod(rod={"elementsThroughThickness": -1})


def test_a_plate_shaped_design_is_refused_for_the_solid():
    rod = hindsight.PistonRod(rod=SOLID)
    with pytest.raises(ValueError, match=r"\(nz, ny, nx\) = \(2, 4, 12\)"):
        rod.evaluate(np.full((4, 12), 0.5), gradient=False, psi2=False)
