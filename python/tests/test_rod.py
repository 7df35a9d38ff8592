"""The rod through the module equals `hindsight evaluate` bit for bit (psi1 and dpsi1/dx), at x0 and at
a random design; per-call storage and adjoint choices go through the same checks."""
import json
import subprocess

import h5py
import numpy as np
import pytest

import hindsight
from conftest import COARSE, COARSE_SET


def cli_evaluate(cli, tmp_path, extra, design=None):
    gradient = tmp_path / "g.h5"
    args = [cli, "evaluate", "--json", "--gradient", str(gradient), "--force"] + extra
    if design is not None:
        path = tmp_path / "x.h5"
        with h5py.File(path, "w") as f:
            f["x"] = design
        args += ["--design", str(path)]
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    result = json.loads(out)
    with h5py.File(gradient, "r") as f:
        fields = {name: f[name][()] for name in f}
    return result, fields


def assert_bitwise(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    assert a.dtype == b.dtype == np.float64
    # Equal bits, not only equal values (-0.0 vs 0.0 and NaN payloads would differ).
    assert a.tobytes() == b.tobytes(), np.max(np.abs(a - b))


def test_default_rod_at_x0_equals_cli_bitwise(cli, tmp_path):
    rod = hindsight.PistonRod()
    r = rod.evaluate(rod.x0, gradient=True)
    expected, fields = cli_evaluate(cli, tmp_path, [])
    assert_bitwise(r.psi1, expected["psi1"])
    assert_bitwise(r.dpsi1_dx, fields["dpsi1_dx"])
    assert_bitwise(r.psi2, expected["psi2"])
    assert_bitwise(r.dpsi2_dx, fields["dpsi2_dx"])
    assert_bitwise(r.dvolume_dx, fields["dvolume_dx"])
    assert r.volume_fraction == expected["volume_fraction"]
    assert list(r.frequencies_hz) == expected["frequencies_hz"]
    assert r.summary["steps"] == expected["summary"]["steps"]
    assert r.summary["storage"] == expected["summary"]["storage"]
    assert r.dpsi1_dx.shape == rod.shape == (12, 200)
    assert np.all(r.dpsi1_dx[:, 0] == 0) and np.all(r.dpsi1_dx[:, -1] == 0)


def test_random_design_equals_cli_bitwise(cli, tmp_path):
    rod = hindsight.PistonRod(COARSE)
    rng = np.random.default_rng(16)
    x = rod.x0.copy()
    x[:, 1:-1] = rng.uniform(0.2, 1.0, size=x[:, 1:-1].shape)
    r = rod.evaluate(x, gradient=True, storage="binomial:checkpoints=20")
    expected, fields = cli_evaluate(cli, tmp_path, COARSE_SET + ["--storage", "binomial:checkpoints=20"], design=x)
    assert r.summary["storage"] == "binomial:checkpoints=20"
    assert r.summary["recomputed_steps"] > 0
    assert_bitwise(r.psi1, expected["psi1"])
    assert_bitwise(r.dpsi1_dx, fields["dpsi1_dx"])
    assert_bitwise(r.psi2, expected["psi2"])
    # An exact strategy changes no bit: the same design with full storage.
    full = rod.evaluate(x, gradient=True, storage="full")
    assert_bitwise(full.dpsi1_dx, r.dpsi1_dx)


def test_overrides_equal_the_config_dict_and_section_field_keys():
    a = hindsight.PistonRod(COARSE)
    b = hindsight.PistonRod(rod={"modeCount": 4, "elementsAlongLength": 20}, **{"rod.elementsThroughHeight": 4})
    assert a.config == b.config
    assert a.config["rod"]["modeCount"] == 4
    # The end time below the default ramp time is fine when the ramp time comes with it (any order).
    hindsight.PistonRod(rod={"endTime": 0.5, "rampTime": 0.25})


def test_config_from_a_json_file(tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps(COARSE))
    assert hindsight.PistonRod(str(path)).config == hindsight.PistonRod(COARSE).config


def test_design_round_trip_and_finite_difference_of_dpsi1():
    rod = hindsight.PistonRod(COARSE)
    x = rod.x0
    v = rod.design_variables(x)
    assert v.shape == (rod.design_count,)
    assert np.array_equal(rod.design_grid(v), x)
    r = rod.evaluate(x, gradient=True, psi2=False)
    assert r.psi2 is None and r.dpsi2_dx is None
    # One central difference on an inner element: the gradient is the derivative of psi1.
    row, column, h = 1, 7, 1e-5
    plus, minus = x.copy(), x.copy()
    plus[row, column] += h
    minus[row, column] -= h
    fd = (rod.evaluate(plus, gradient=False, psi2=False).psi1 -
          rod.evaluate(minus, gradient=False, psi2=False).psi1) / (2 * h)
    assert abs(fd - r.dpsi1_dx[row, column]) <= 1e-5 * abs(fd) + 1e-12, (fd, r.dpsi1_dx[row, column])


def test_storage_specs_come_from_the_factory():
    specs = hindsight.storage_specs()
    names = [s.name for s in specs]
    assert names == hindsight.storage_strategy_names()
    assert {"full", "binomial", "online", "disk", "lossy", "hermite", "multilevel"} <= set(names)
    for spec in specs:
        assert spec.summary and spec.key_docs
        assert all(doc for doc in spec.key_docs.values()), spec.name
        assert hindsight.check_storage_spec(spec.example)
    binomial = next(s for s in specs if s.name == "binomial")
    assert "checkpoints" in binomial.key_docs and binomial.exact is True
    # The registry's prediction: a predicted row is predicted by schedule(), the others say why not
    # and schedule() refuses them with that reason.
    for spec in specs:
        assert isinstance(spec.predicted, bool)
        if spec.predicted:
            assert spec.not_predicted == ""
        else:
            assert spec.not_predicted, spec.name
            with pytest.raises(ValueError, match="is not predicted"):
                hindsight.schedule(spec.example, steps=10, state_bytes=16, stages=1)
    assert binomial.predicted and next(s for s in specs if s.name == "online").predicted
    hindsight.schedule(binomial.example, steps=10, state_bytes=16, stages=1)


def test_full_order_model_equals_cli_bitwise(cli, tmp_path):
    # Half a second of the mechanism (the ramp up to speed): 500 implicit steps instead of 3000.
    settings = {"model": "full", "integrator": "trbdf2", "step": 1e-3}
    rod = hindsight.PistonRod(COARSE, simulation=settings, **{"rod.endTime": 0.5, "rod.rampTime": 0.4})
    r = rod.evaluate(gradient=True)
    expected, fields = cli_evaluate(cli, tmp_path, COARSE_SET + ["--model", "full", "--integrator", "trbdf2",
                                                                  "--set", "simulation.step=1e-3",
                                                                  "--set", "rod.rampTime=0.4", "--set", "rod.endTime=0.5"])
    assert r.model == expected["model"] == "full"
    assert r.psi2 is None and r.frequencies_hz is None
    assert r.state_size == expected["state_size"]
    assert_bitwise(r.psi1, expected["psi1"])
    assert_bitwise(r.dpsi1_dx, fields["dpsi1_dx"])


def test_evaluations_from_threads_equal_serial_ones():
    from concurrent.futures import ThreadPoolExecutor

    from conftest import TINY
    rod = hindsight.PistonRod(TINY)
    rng = np.random.default_rng(3)
    designs = []
    for _ in range(6):
        x = rod.x0.copy()
        x[:, 1:-1] = rng.uniform(0.1, 1.0, size=x[:, 1:-1].shape)
        designs.append(x)
    serial = [rod.evaluate(x, gradient=True) for x in designs]
    with ThreadPoolExecutor(max_workers=3) as pool:
        parallel = list(pool.map(lambda x: rod.evaluate(x, gradient=True), designs))
    for a, b in zip(serial, parallel):
        assert_bitwise(a.psi1, b.psi1)
        assert_bitwise(a.dpsi1_dx, b.dpsi1_dx)
