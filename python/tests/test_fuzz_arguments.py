"""Fuzzing the Python module's arguments as tests/fuzz does the C++ readers: configuration values of
every Python and NumPy type (configuration dicts, keyword overrides, scenario lists) and design arrays of
every dtype and shape. Each call either succeeds or raises ValueError naming what it refused -- never a
TypeError, SystemError or a bare RuntimeError from a conversion, and never a silently changed value.
HINDSIGHT_FUZZ_SEED picks other inputs, HINDSIGHT_FUZZ_SCALE runs more of them."""
import math
import os
import random

import numpy as np
import pytest

import hindsight
from conftest import TINY

SEED = int(os.environ.get("HINDSIGHT_FUZZ_SEED", "20261126"))
SCALE = int(os.environ.get("HINDSIGHT_FUZZ_SCALE", "1"))

VALUES = [None, True, False, 0, 1, -1, 2, 40, 41, 2**31, 2**63, -(2**63), 2**64, 0.5, -0.0, 1e-300, 1e300,
          float("nan"), float("inf"), float("-inf"), 1 + 2j, 0j, "", "rk4", "trbdf2", "full", "psi2", "nan",
          "binomial:checkpoints=0", "hermite:every=7,tolerance=0.5", [], [1, 2], {}, {"x": 1}, (1, 2),
          b"bytes", np.int64(3), np.int32(-1), np.uint64(2**63), np.float64(0.25), np.float32(1.5),
          np.float64("nan"), np.bool_(True), np.complex128(1j), np.array(2.0), object()]
FIELDS = {"rod": ["crankSpeed", "modeCount", "endTime", "rampTime", "elementsAlongLength", "designLowerBound"],
          "simulation": ["step", "integrator", "storage", "adaptive", "relativeTolerance"],
          "optimization": ["iterations", "moveLimit", "volumeFraction", "aggregate"]}
SCENARIO_FIELDS = ["name", "crankSpeed", "rampTime", "endTime", "crankRadius", "weight", "unknown"]


def is_number(value):
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_accepted(config, section, field, value):
    """An accepted number keeps its value; an accepted non-finite or complex one is a bug."""
    if not is_number(value) or section not in config or field not in config[section]:
        return
    stored = config[section][field]
    assert math.isfinite(float(value)), f"{section}.{field} = {value!r} accepted"
    assert float(stored) == float(value), f"{section}.{field} = {value!r} stored as {stored!r}"


def test_configuration_values_of_every_type():
    rng = random.Random(SEED)
    for _ in range(400 * SCALE):
        section = rng.choice(list(FIELDS))
        field = rng.choice(FIELDS[section])
        value = rng.choice(VALUES)
        how = rng.randrange(3)
        try:
            if how == 0:
                config = hindsight.config({**TINY, section: {**TINY.get(section, {}), field: value}})
            elif how == 1:
                config = hindsight.config(TINY, **{f"{section}.{field}": value})
            else:
                config = hindsight.config(TINY, **{section: {field: value}})
        except ValueError as error:
            assert str(error), (section, field, value)
            continue
        check_accepted(config, section, field, value)


def test_scenario_lists_of_every_shape():
    rng = random.Random(SEED + 1)
    for _ in range(300 * SCALE):
        scenarios = []
        for index in range(rng.randrange(4)):
            scenario = {"name": rng.choice(["a", "b", "", "a", 3, None])} if rng.random() < 0.9 else {}
            for _ in range(rng.randrange(3)):
                scenario[rng.choice(SCENARIO_FIELDS)] = rng.choice(VALUES)
            scenarios.append(scenario if rng.random() > 0.05 else rng.choice(VALUES))
        config = {**TINY, "scenarios": scenarios if rng.random() > 0.05 else rng.choice(VALUES)}
        try:
            accepted = hindsight.config(config)
        except ValueError as error:
            assert str(error)
            continue
        for stored in accepted.get("scenarios", []):
            for key, value in stored.items():
                if isinstance(value, float):
                    assert math.isfinite(value), (key, value, scenarios)


def test_design_arrays_of_every_dtype_and_shape():
    rod = hindsight.PistonRod(TINY)
    x0 = rod.x0
    rng = random.Random(SEED + 2)
    candidates = [x0, x0.astype(np.float32), x0.astype(np.int64), x0.astype(complex), x0.astype(str),
                  x0.astype(object), x0.astype(bool), x0.T, x0.ravel(), x0[:, :-1], x0.tolist(), [[1.0]],
                  np.full(x0.shape, np.nan), np.full(x0.shape, 2.0), np.zeros(x0.shape), "x0", None, 3.0]
    for _ in range(60 * SCALE):
        x = rng.choice(candidates)
        try:
            variables = rod.design_variables(x)
        except ValueError as error:
            assert str(error)
            continue
        # Accepted: a real array of the grid's shape whose values are the design variables unchanged.
        array = np.asarray(x)
        assert array.dtype.kind in "fiu" and array.shape == x0.shape, (array.dtype, array.shape)
        assert np.all(np.isfinite(variables))
