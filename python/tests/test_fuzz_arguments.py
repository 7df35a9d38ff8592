"""Fuzzing the Python module's arguments as tests/fuzz does the C++ readers: configuration values of
every Python and NumPy type (configuration dicts, keyword overrides, scenario lists) and design arrays of
every dtype and shape. Each call either succeeds or raises ValueError naming what it refused -- never a
TypeError, SystemError or a bare RuntimeError from a conversion, and never a silently changed value.
HINDSIGHT_FUZZ_SEED picks other inputs, HINDSIGHT_FUZZ_SCALE runs more of them."""
import copy
import json
import math
import operator
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


class _Decay:
    """z' = -p0 z, z(0) = 1, psi = int z dt, with no derivatives (they are generated)."""
    state_size, parameter_size = 1, 1

    def initial_state(self, p):
        return np.ones(1) + 0.0 * p[0]

    def rhs(self, t, z, p):
        return -p[0] * z

    def integrand(self, t, z, p):
        return z[0]


SOLVER_VALUES = [None, True, 0, 1, -1, 3, 10**6, 2**63, 0.5, 1e-3, -0.0, 1e-300, 1e300, float("nan"),
                 float("inf"), 1j, "1e-3", np.float32(1e-3), np.int64(5), np.bool_(False), [1e-3], object()]
TOLERANCES = [1e-9, 0.0, -1.0, float("nan"), [1e-9], np.array([1e-9]), np.array([1e-9, 1e-9]), np.array([[1e-9]]),
              np.array([np.inf]), np.array(["a"]), np.array([1e-9], dtype=np.float32), np.array([1], dtype=np.int64),
              np.array([1e-9 + 0j]), [], True, "1e-9", None]
TIMES = [None, [], [0.0], [0.01], [0.005, 0.0], np.linspace(0, 0.01, 4), [0.02], [-1.0], [float("nan")],
         [[0.0]], ["a"], np.array([0.005], dtype=np.float32), 0.005, np.array([1 + 1j])]
NAMES = ["step", "t0", "t1", "rtol", "min_step", "max_step", "max_steps", "newton_tolerance", "newton_max_iterations",
         "rho_infinity", "bogus"]


def test_solver_arguments_of_every_type():
    """simulate/gradient/classic_gradient with hostile numbers, tolerances, output times and options:
    a result honouring them, or ValueError/TypeError/NumericalError naming the argument; never a grid
    longer than max_steps or a step longer than asked for."""
    rng = random.Random(SEED + 3)
    for _ in range(150 * SCALE):
        kwargs = {"t1": 0.01, "step": 1e-3}
        for _ in range(rng.randrange(3)):
            kwargs[rng.choice(NAMES)] = rng.choice(SOLVER_VALUES)
        if rng.random() < 0.4:
            kwargs["atol"] = rng.choice(TOLERANCES)
        if rng.random() < 0.3:
            kwargs.update(integrator=rng.choice(["dopri5", "trbdf2", "generalized-alpha", "nope"]),
                          adaptive=rng.random() < 0.5)
        call = rng.randrange(3)
        times = rng.choice(TIMES)
        try:
            if call == 0:
                r = hindsight.simulate(_Decay(), np.array([2.0]), times=times, **kwargs)
            elif call == 1:
                r = hindsight.gradient(_Decay(), np.array([2.0]), **kwargs)
            else:
                r = hindsight.classic_gradient("decay", np.array([2.0, 1.0]), **kwargs)
        except (ValueError, TypeError, hindsight.NumericalError) as error:
            assert str(error), kwargs
            assert not isinstance(error, RuntimeError) or isinstance(error, hindsight.NumericalError), error
            continue
        assert np.all(np.isfinite(r.times)), kwargs
        on_grid = call != 0 or times is None
        if on_grid and not kwargs.get("adaptive"):
            # A fixed-step grid: no step longer than asked for, no more steps than max_steps.
            step = float(kwargs["step"])
            span = float(kwargs.get("t1", 0.01)) - float(kwargs.get("t0", 0.0))
            assert np.max(np.diff(r.times)) <= min(step, span) * (1 + 1e-9), kwargs
        max_steps = kwargs.get("max_steps")
        if on_grid and isinstance(max_steps, (int, np.integer)) and not isinstance(max_steps, (bool, np.bool_)):
            assert len(r.times) - 1 <= max_steps, kwargs


SEEDS = os.path.join(os.path.dirname(__file__), "..", "..", "tests", "fuzz", "seeds")
MECHANISM_LISTS = ["rigidBodies", "joints", "drivers", "springs", "free"]
MECHANISM_FIELDS = ["name", "mass", "inertia", "position", "angle", "points", "type", "body1", "point1", "body2",
                    "point2", "axis", "joint", "law", "speed", "rampTime", "offset", "stiffness", "restLength",
                    "damping", "body", "coordinate", "velocity", "colour"]
MECHANISM_VALUES = VALUES + [[0.0, 0.0], [np.float32(0.5), 1], [float("nan"), 0.0], [1e300, -1e300], [1, 2, 3],
                             np.array([0.5, 0.25]), "ground", "rod", "A", "B", "revolute", "fixed", "angle"]


def mechanism_seeds():
    """The mechanism sections of tests/fuzz/seeds/mechanism_*.json (the C++ fuzz tests' seeds)."""
    seeds = []
    for name in sorted(os.listdir(SEEDS)):
        if name.startswith("mechanism_"):
            with open(os.path.join(SEEDS, name)) as f:
                seeds.append(json.load(f)["mechanism"])
    assert len(seeds) >= 5
    return seeds


def test_mechanism_descriptions_of_every_type():
    """hindsight.Mechanism with hostile dicts: fields of every Python and NumPy type, keys deleted, elements
    duplicated or dropped, references to nothing. A Mechanism or ValueError naming the mechanism section;
    an accepted one evaluates to a finite psi1 or raises NumericalError."""
    rng = random.Random(SEED + 4)
    seeds = mechanism_seeds()
    accepted = 0
    for _ in range(250 * SCALE):
        description = copy.deepcopy(rng.choice(seeds))
        for _ in range(1 + rng.randrange(3)):
            name = rng.choice(MECHANISM_LISTS)
            elements = description.get(name)
            element = rng.choice(elements) if isinstance(elements, list) and elements else None
            how = rng.randrange(6)
            if how == 0:
                description[name] = rng.choice(MECHANISM_VALUES)
            elif how == 1 and element is not None:
                elements.append(copy.deepcopy(element))
            elif how == 2 and element is not None and isinstance(element, dict) and element:
                del element[rng.choice(list(element))]
            elif how == 3:
                description[rng.choice(["gravity", "flexibleMember", "ground", "unknown"])] = rng.choice(MECHANISM_VALUES)
            elif element is not None and isinstance(element, dict):
                element[rng.choice(MECHANISM_FIELDS)] = rng.choice(MECHANISM_VALUES)
        try:
            mechanism = hindsight.Mechanism(description, TINY)
        except ValueError as error:
            assert "mechanism" in str(error), (str(error), description)
            continue
        accepted += 1
        try:
            r = mechanism.evaluate(gradient=False, psi2=False)
        except hindsight.NumericalError as error:
            assert str(error)
            continue
        assert math.isfinite(r.psi1) and r.psi1 >= 0, description
    assert accepted > 10


def test_mechanism_configuration_sections_of_every_type():
    """The description's companion sections (the `config` argument) and overrides of every type."""
    rng = random.Random(SEED + 5)
    seeds = mechanism_seeds()
    for _ in range(100 * SCALE):
        section = rng.choice(list(FIELDS) + ["scenarios", "mechanism", "unknown"])
        value = rng.choice(VALUES)
        config = {**TINY}
        if section in FIELDS:
            config[section] = {**TINY.get(section, {}), rng.choice(FIELDS[section]): value}
        else:
            config[section] = value if rng.random() < 0.5 else [{"name": "a", "crankSpeed": value}]
        try:
            hindsight.Mechanism(rng.choice(seeds), config)
        except ValueError as error:
            assert str(error), (section, value)


SCHEDULE_SPECS = ["full", "binomial:checkpoints=10", "binomial:checkpoints=10,stages=1", "online:checkpoints=8",
                  "cams:checkpoints=4", "multilevel:ram=1KiB,disk=1MiB,costs=1:1:0:0", "multilevel:ram=512,disk=4KiB",
                  "disk:dir=/tmp", "hermite", "lossy:codec=zfp,tolerance=1e-6", "revolve", "", "full:budget=-1",
                  "binomial:checkpoints=10\x00", None, 3, b"full"]
SCHEDULE_COUNTS = [1, 2, 7, 1000, 2**24, 2**31, 4 * 10**18, 4 * 10**18 + 1, 0, -1, 2**63, 2**64, 2.9, 2.0, True,
                   None, "100", np.int64(1000), np.int32(64), np.uint64(2**63), np.float64(8.0), np.bool_(True),
                   1j, [10], object()]
SCHEDULE_COSTS = [None, "1:1:0:0", "1e-4:2e-4:1e-5:1e-5", "1e30:1e30:1e30:1e30", "1e308:1:0:0", "0:1:0:0",
                  "1:1:0", "nan:1:0:0", "", "1:1:0:0:0", 1.0, b"1:1:0:0", ["1:1:0:0"]]


def test_schedule_arguments_of_every_type():
    """schedule() with hostile arguments: a sound prediction, or TypeError/ValueError naming the argument
    (steps, state_bytes, stages, costs, spec); never another exception or a wrapped-around count."""
    rng = random.Random(SEED + 6)
    sound = 0
    for _ in range(400 * SCALE):
        # Each argument valid three times in four, so that the hostile one is the one refused.
        spec = rng.choice(SCHEDULE_SPECS[:8] if rng.random() < 0.75 else SCHEDULE_SPECS)
        steps = rng.choice(SCHEDULE_COUNTS[:6] + [np.int64(1000)] if rng.random() < 0.75 else SCHEDULE_COUNTS)
        state_bytes = rng.choice([8, 64, 65544, np.int32(64)] if rng.random() < 0.75 else
                                 SCHEDULE_COUNTS + [8 * (2**31 - 1)])
        stages = rng.choice([1, 4, 64] if rng.random() < 0.75 else [0, 65, 2.5, "4", None, True, np.int64(7)])
        costs = rng.choice(SCHEDULE_COSTS[:4] if rng.random() < 0.75 else SCHEDULE_COSTS)
        actions = rng.random() < 0.1
        if (actions or str(spec).startswith(("online", "multilevel"))) and isinstance(steps, int) and steps > 10**5:
            continue  # simulated plans and action streams: small N only (time, not a property)
        try:
            p = hindsight.schedule(spec, steps, state_bytes, stages=stages, costs=costs, actions=actions)
        except (TypeError, ValueError) as error:
            message = str(error)
            assert any(word in message for word in ("steps", "state_bytes", "stages", "costs", "spec", "storage",
                                                    "full", "binomial", "online", "cams", "multilevel", "disk",
                                                    "hermite", "lossy")), message
            continue
        sound += 1
        assert p.steps == operator.index(steps)
        for key in ("recomputed_steps", "rhs_evaluations", "states_stored", "disk_writes", "disk_reads",
                    "peak_ram_bytes", "peak_disk_bytes"):
            assert 0 <= p[key] < 2**63, (key, p[key], spec, steps, state_bytes)
        assert math.isfinite(p.total_cost) and p.total_cost > 0
    assert sound > 20


def test_schedule_found_inputs():
    """Inputs test_schedule_arguments_of_every_type found: NumPy's bool_ was read as 1 step (its __index__ is
    deprecated, not gone), a spec that is not a string gave pybind11's "incompatible function arguments"."""
    with pytest.raises(TypeError, match="steps"):
        hindsight.schedule("full", np.bool_(True), 64)
    with pytest.raises(TypeError, match="stages"):
        hindsight.schedule("full", 10, 64, stages=np.bool_(True))
    for spec in (3, None, b"full"):
        with pytest.raises(TypeError, match="spec must be a storage spec string"):
            hindsight.schedule(spec, 10, 64)


def test_mechanism_non_finite_values_are_named_as_given():
    """A NaN or infinity from a dict was reported as "= null" (JSON's rendering of it)."""
    description = mechanism_seeds()[2]
    for value, shown in ((float("nan"), "nan"), (float("inf"), "inf"), (-float("inf"), "-inf")):
        bad = copy.deepcopy(description)
        bad["rigidBodies"][1]["mass"] = value
        with pytest.raises(ValueError, match=rf"mechanism.rigidBodies\[rocker\].mass = {shown} must be a finite"):
            hindsight.Mechanism(bad, TINY)
