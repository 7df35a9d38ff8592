"""hindsight from Python: exact adjoint gradients with interchangeable trajectory storage, the piston
rod of Held, Knueffer & Seifried and its topology optimization (docs/guides/python.md).

    import hindsight
    rod = hindsight.PistonRod(rod={"modeCount": 8})          # config dict and/or overrides
    r = rod.evaluate(rod.x0, gradient=True, storage="binomial:checkpoints=50")
    r.psi1, r.dpsi1_dx                                          # float, NumPy (ny, nx)

    history = hindsight.optimize({"optimization": {"iterations": 10}}, out="run", callback=print)
    hindsight.gradient(my_problem, p, integrator="rk4", step=1e-3)   # a problem written in Python
    hindsight.simulate(my_problem, p, times=[0.5, 1.0])        # forward only: the trajectory
    hindsight.storage_specs()                                   # strategies, keys, documentation
    hindsight.checkpoint_schedule("binomial:checkpoints=10", steps=1000)   # actions for your own stepper
    hindsight.read_results("run")                              # history, designs, configuration

Errors: bad input raises ValueError with the CLI's message; numerical failures raise
hindsight.NumericalError and storage failures hindsight.StorageError (both RuntimeError).
"""
import operator
import os as _os

from . import _hindsight
from ._hindsight import NumericalError, StorageError, storage_strategy_names
from .checkpoint_schedule import (CheckpointSchedule, Copy, EndForward, EndReverse, Forward, Move, Reverse,
                                  StorageType, checkpoint_schedule)
from . import checkpoint_schedules  # noqa: F401  (the adapter: checkpoint_schedules' own classes)

__version__ = _hindsight.__version__
__all__ = ["PistonRod", "Mechanism", "Result", "NumericalError", "StorageError", "gradient", "classic_gradient",
           "simulate", "optimize", "read_results", "history_columns", "plot_comparison", "storage_specs",
           "storage_strategy_names", "schedule", "check_storage_spec", "config", "checkpoint_schedule", "StorageType",
           "Forward", "Reverse", "Copy", "Move", "EndForward", "EndReverse", "CheckpointSchedule"]


class Result(dict):
    """A dict whose keys are also attributes: r.psi1 is r["psi1"]."""

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    def __dir__(self):
        return list(self.keys()) + list(super().__dir__())

    def __repr__(self):
        def short(value):
            shape = getattr(value, "shape", None)
            return f"<array {shape}>" if shape is not None and len(shape) > 0 else repr(value)
        return "Result(" + ", ".join(f"{k}={short(v)}" for k, v in self.items()) + ")"


def config(config=None, **overrides):
    """The complete configuration (every field, defaults included) as a dict, after the same checks as
    the CLI's --config/--set: `config` is a dict of sections (the JSON file's content), a path to a JSON
    file or None; overrides are sections given as dicts (rod={"modeCount": 8}) or "section.field" keys
    (**{"simulation.step": 2e-4}). ValueError names the field and the allowed range."""
    return _hindsight._make_config(config, **overrides)


class PistonRod:
    """The piston-rod model of `hindsight evaluate`. The configuration is checked at construction
    (ValueError naming the field, as the CLI). Designs are NumPy arrays of shape (ny, nx) over all
    elements: row 0 at the bottom, column 0 at joint A; the end columns are not design variables and
    hold 1."""

    def __init__(self, config=None, **overrides):
        self._rod = _hindsight.PistonRod(config, **overrides)

    @property
    def config(self):
        """The complete configuration as a dict."""
        return self._rod.config

    @property
    def x0(self):
        """The uniform initial design, shape (ny, nx)."""
        return self._rod.x0

    @property
    def shape(self):
        """(ny, nx) = (rod.elementsThroughHeight, rod.elementsAlongLength); the solid member's
        (rod.elementsThroughThickness >= 1) designs are (nz, ny, nx)."""
        return self._rod.shape

    @property
    def design_count(self):
        """Number of design variables (the inner columns' elements)."""
        return self._rod.design_count

    def design_variables(self, x):
        """The design variables (1-D, the order of the C++ model) of a (ny, nx) design, checked."""
        return self._rod.design_variables(x)

    def design_grid(self, values, interface_value=1.0):
        """The (ny, nx) array of design variables `values`; end columns get `interface_value`."""
        return self._rod.design_grid(values, interface_value)

    def evaluate(self, x=None, gradient=True, storage=None, adjoint=None, integrator=None, psi2=True):
        """psi1, psi2, volume fraction and frequencies of design x (default x0); with gradient=True also
        dpsi1_dx, dpsi2_dx, dvolume_dx as (ny, nx) arrays (0 in the end columns), exactly as
        `hindsight evaluate --gradient` computes them, and dpsi1_dv, dpsi2_dv, dvolume_dv over the
        design variables (the order of design_variables(), for optimizers working on them). storage, adjoint and integrator override
        simulation.storage / adjoint / integrator for this call (checked as the CLI's flags).
        psi2 is None when skipped (psi2=False, or adaptive steps). The GIL is released meanwhile;
        Ctrl-C raises KeyboardInterrupt."""
        if x is None:
            x = self.x0
        return Result(self._rod._evaluate(x, gradient, storage, adjoint, integrator, psi2))

    def __repr__(self):
        shape = self.shape
        layers = f"nz={shape[0]}, " if len(shape) == 3 else ""
        return f"PistonRod({layers}ny={shape[-2]}, nx={shape[-1]}, design_count={self.design_count})"


# The C++ behind optimize() and schedule() words its errors for the command line (its flags); Python
# callers get the same message with their own keywords instead.
_CLI_WORDS = [("use --resume to continue it or --force to overwrite it",
               "pass resume=True to continue it or force=True to overwrite it"),
              ("--resume and --force exclude each other", "resume=True and force=True exclude each other"),
              ("--resume:", "resume=True:"), ("--resume", "resume=True"), ("--force", "force=True"),
              ("--out", "out"), ("--state-bytes", "state_bytes"), ("--stage-bytes", "stage_bytes"),
              ("--actions", "actions=True"), ("--bound", "bound=True"), ("--steps", "steps"),
              ("--stages", "stages"),
              ("--costs", "costs"), ("--storage", "spec")]


def _in_python_words(error):
    """The same exception type with the CLI's flags in the message replaced by Python's keywords."""
    message = str(error)
    for cli, python in _CLI_WORDS:
        message = message.replace(cli, python)
    if message == str(error):
        return error
    return type(error)(message)


class Mechanism(PistonRod):
    """The flexible member (the rod section) inside a planar mechanism you describe
    (docs/tutorials/own_mechanism.md): `description` is the `mechanism` section as a dict, or a path to
    a JSON file that has one (examples/mechanisms/four_bar.json); `config` and the overrides are the
    other sections, as for PistonRod. evaluate(), x0 and the rest are PistonRod's. ValueError names
    the body, joint or field of a bad description."""

    def __init__(self, description, config=None, **overrides):
        if isinstance(description, (str, _os.PathLike)):
            import json
            with open(description) as f:
                loaded = json.load(f)
            if not isinstance(loaded, dict) or "mechanism" not in loaded:
                raise ValueError(f"'{description}' has no mechanism section")
            merged = {k: v for k, v in loaded.items() if k != "mechanism"}
            description = loaded["mechanism"]
        else:
            merged = {}
        if not isinstance(description, dict):
            raise ValueError("description must be a dict (the mechanism section) or a path to a JSON file")
        if isinstance(config, dict):
            for section, fields in config.items():
                merged.setdefault(section, {})
                if isinstance(fields, dict) and isinstance(merged[section], dict):
                    merged[section].update(fields)
                else:
                    merged[section] = fields
        elif config is not None:
            raise ValueError("config must be a dict of sections or None (the description carries the mechanism)")
        merged["mechanism"] = description
        super().__init__(merged, **overrides)


def optimize(config=None, out="results", resume=False, force=False, callback=None, verbose=False, **overrides):
    """Runs the topology optimization of `hindsight optimize` into directory `out` (results.h5 after every
    iteration, pictures, resumable). callback(record) is called after each iteration once it is on
    disk, with a dict: every column of history_columns() by name, and converged (the stopping rule held
    there);
    returning a false value other than None (False, 0) stops the run (its results stay valid and
    resumable); returning None continues. resume=True on a directory without results.h5 raises
    ValueError (a mistyped `out` must not start a fresh run). verbose=True prints the progress lines.
    Returns read_results(out) plus results_path and stopped_by_callback."""
    try:
        run = _hindsight._optimize(config, _os.fspath(out), resume, force, callback, verbose, **overrides)
    except ValueError as error:
        raise _in_python_words(error) from None
    result = read_results(run["results_path"])
    result["stopped_by_callback"] = run["stopped_by_callback"]
    return result


def read_results(path):
    """A results directory (or its results.h5) read with every check of the C++ reader (StorageError
    naming the dataset when one fails): history (dict of NumPy columns, one per entry of
    history_columns(), int32 or float64 as the file stores them),
    designs (K, ny, nx), configuration (dict), finished, next_design, final_frequencies_hz, final_modes;
    for runs with scenarios also scenarios (K, S: every scenario's psi1 per iteration, in the order of
    configuration["scenarios"]), scenario_psi2 (K, S) and scenario_objective_scale (S: psi_s(x0)); the
    history's psi1/psi2 are then the worst scenario's."""
    path = _os.fspath(path)
    if _os.path.isdir(path):
        path = _os.path.join(path, "results.h5")
    result = Result(_hindsight._read_results(path))
    result["path"] = path
    result["config"] = result["configuration"]  # the name the shared plotting code uses
    return result


def history_columns():
    """The columns of an optimization's history, in file order: a list of dicts (name, type "int32" or
    "float64", unit, description, reproducible: the same bits on every run of a configuration, optional:
    absent from files written before the column existed). The one table of the C++ library
    (problems/topopt/history_schema.h) that also drives the results file, `hindsight verify` and
    `hindsight plot`."""
    return [Result(column) for column in _hindsight._history_columns()]


def plot_comparison(*runs, out=None):
    """The Fig.-4 comparison of `hindsight plot`: psi1 over the iterations of one or two runs (e.g. the
    psi1 and the psi2 route) and their latest designs. Each run is a results directory or a
    read_results() dict. Saves to `out` when given; returns the matplotlib figure."""
    from . import _plot_history
    if not 1 <= len(runs) <= 2:
        raise ValueError("plot_comparison: give one or two runs")
    loaded = [run if isinstance(run, dict) else read_results(run) for run in runs]
    return _plot_history.draw(loaded, out)


# Solver options of the C++ IntegratorOptions (engine/integrator.h) by their Python names, and the words
# of its messages put into them.
_SOLVER_OPTIONS = ("min_step", "max_step", "max_steps", "newton_tolerance", "newton_max_iterations", "rho_infinity")
_SOLVER_WORDS = [("IntegratorOptions.absoluteTolerances", "atol"), ("absoluteTolerances", "atol"),
                 ("relativeTolerance", "rtol"), ("absoluteTolerance", "atol"), ("minStep", "min_step"),
                 ("maxSteps", "max_steps"), ("maxStep", "max_step"), ("newtonTolerance", "newton_tolerance"),
                 ("newtonMaxIterations", "newton_max_iterations"), ("rhoInfinity", "rho_infinity"),
                 ("IntegratorOptions.", ""), ("IntegratorOptions: ", "")]


def _solver_arguments(step, t0, t1, rtol, atol, solver):
    """Checked floats/ints for the C++ side: bools, strings and complex numbers are a TypeError naming
    the argument; atol is a float or a 1-D float64 array (one tolerance per state)."""
    import numpy as np

    def real(name, value):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise TypeError(f"{name} must be a real number, not {type(value).__name__} {value!r}")
        return float(value)

    if np.ndim(atol) == 0:
        atol = real("atol", atol)
    else:
        values = np.asarray(atol)
        if values.ndim != 1 or not (np.issubdtype(values.dtype, np.floating) or np.issubdtype(values.dtype, np.integer)):
            raise TypeError(f"atol must be a real number or a 1-D array of real numbers (one per state), "
                            f"not {values.dtype} of shape {values.shape}")
        atol = np.ascontiguousarray(values, dtype=np.float64)
    options = {}
    for name, value in solver.items():
        if name not in _SOLVER_OPTIONS:
            raise TypeError(f"unknown solver option {name!r}; known: {', '.join(_SOLVER_OPTIONS)}")
        if value is None:
            continue
        if name in ("max_steps", "newton_max_iterations"):
            options[name] = _schedule_integer(name, value, 1, 2**62 if name == "max_steps" else 2**31 - 1)
        else:
            options[name] = real(name, value)
    return real("step", step), real("t0", t0), real("t1", t1), real("rtol", rtol), atol, options


def _in_solver_words(error):
    message = str(error)
    for cpp, python in _SOLVER_WORDS:
        message = message.replace(cpp, python)
    return error if message == str(error) else type(error)(message)


def _with_derivatives(problem, derivatives):
    """The problem as the engine gets it: derivatives="auto" generates the missing derivative methods
    (hindsight._derivatives: complex step, checked against finite differences), "given" uses only the
    problem's own (a missing one is a ValueError), "generated" generates every one."""
    from . import _derivatives
    if derivatives == "given":
        return problem
    if derivatives == "generated":
        return _derivatives.GeneratedDerivatives(problem, force=True)
    if derivatives != "auto":
        raise ValueError(f"derivatives = {derivatives!r} must be 'auto', 'given' or 'generated'")
    missing = _derivatives.missing_derivatives(problem)
    needs_integrand = getattr(problem, "integrand", None) is None
    return _derivatives.GeneratedDerivatives(problem) if missing or needs_integrand else problem


def gradient(problem, p, integrator="rk4", step=1e-3, t0=0.0, t1=1.0, storage="full", adjoint="discrete",
             adaptive=False, rtol=1e-6, atol=1e-9, derivatives="auto", **solver):
    """psi = int_t0^t1 G(t, z, p) dt + phi(z(t1), p) and dpsi/dp for z' = F(t, z, p), z(t0) = z0(p), a
    problem written in Python. `problem` has attributes state_size and parameter_size and methods
    (arrays are 1-D NumPy float64 copies):
        initial_state(p) -> z0                 rhs(t, z, p) -> F
        integrand(t, z, p) -> G
    and, optionally, its derivatives (any that are missing are generated, derivatives="auto"):
        rhs_jacobian(t, z, p) -> dF/dz (n, n)  and/or  rhs_state_vjp(t, z, p, w) -> (dF/dz)^T w
        rhs_parameter_vjp(t, z, p, w) -> (dF/dp)^T w
        integrand_state_gradient(t, z, p) -> dG/dz
        integrand_parameter_gradient(t, z, p) -> dG/dp
        initial_state_vjp(p, lam) -> (dz0/dp)^T lam
    optional: terminal(z, p) -> phi (with terminal_gradient(z, p) -> (dphi/dz, dphi/dp)), name.
    derivatives: "auto" (generate the missing ones by the complex step, exact to round-off for functions
    written with complex-safe NumPy operations; docs/guides/python.md), "given" (only the problem's own:
    a missing one is a ValueError) or "generated" (every one generated, ignoring the problem's).
    atol is a float or one tolerance per state (adaptive steps and CVODES); solver options of the C++
    integrator by keyword: min_step, max_step, max_steps, newton_tolerance, newton_max_iterations,
    rho_infinity.
    Returns Result(psi, gradient, times, summary). Runs the C++ engine (any integrator, storage spec or
    adjoint route) calling back into Python, so it is slower than a C++ problem (docs/guides/python.md)."""
    import numpy as np
    p = np.ascontiguousarray(p, dtype=np.float64)
    step, t0, t1, rtol, atol, options = _solver_arguments(step, t0, t1, rtol, atol, solver)
    engine_problem = _with_derivatives(problem, derivatives)
    try:
        return Result(_hindsight._gradient(engine_problem, p, integrator, step, t0, t1, storage, adjoint,
                                           bool(adaptive), rtol, atol, options))
    except (ValueError, NumericalError) as error:
        raise _in_solver_words(error) from None


def classic_gradient(name, p, integrator="rk4", step=1e-3, t0=0.0, t1=1.0, storage="full", adjoint="discrete",
                     adaptive=False, rtol=1e-6, atol=1e-9, **solver):
    """gradient() for a C++ problem of problems/classic: "oscillator" (p = k, c, y0), "decay" (p = k, a) or
    "pendulum" (p = m, L, c, th0). The reference for a problem written in Python (docs/guides/python.md measures
    the overhead with it); the GIL is released."""
    import numpy as np
    p = np.ascontiguousarray(p, dtype=np.float64)
    step, t0, t1, rtol, atol, options = _solver_arguments(step, t0, t1, rtol, atol, solver)
    try:
        return Result(_hindsight._classic_gradient(name, p, integrator, step, t0, t1, storage, adjoint,
                                                   bool(adaptive), rtol, atol, options))
    except (ValueError, NumericalError) as error:
        raise _in_solver_words(error) from None


def simulate(problem, p, times=None, observer=None, integrator="rk4", step=1e-3, t0=0.0, t1=1.0, adaptive=False,
             rtol=1e-6, atol=1e-9, **solver):
    """The forward simulation alone (no gradient) of a problem written in Python (as for gradient(); only
    state_size, parameter_size, initial_state and rhs are required, integrand is optional) or of a
    C++ problem of problems/classic by name ("oscillator", "decay", "pendulum"; the GIL is released).
    Returns Result(times, states, psi, stopped_by_observer, summary):
      - times=None: the integrator's own grid t_0..t_N and the state there, states (N+1, n), bit for bit
        what the gradient's forward sweep computes;
      - times=array: the states at those times (in [t0, t1], any order), by cubic Hermite interpolation
        between the grid points around each (from the states and F there; exact at grid points, error
        O(h^4) in between, below rk4's own O(h^4) and above dopri5's O(h^5): ask for the grid
        (times=None) or a smaller step when that matters).
    observer(t, z), when given, is called at every grid point as the sweep reaches it; returning a false
    value other than None stops the simulation there (psi is then None, the trajectory ends there).
    psi is the objective int G dt + phi (0 without integrand). Options as for gradient(); implicit
    integrators use problem.rhs_jacobian, generated when missing (docs/guides/python.md)."""
    import numpy as np
    p = np.ascontiguousarray(p, dtype=np.float64)
    step, t0, t1, rtol, atol, options = _solver_arguments(step, t0, t1, rtol, atol, solver)
    if observer is not None and not callable(observer):
        raise TypeError(f"observer must be callable or None, not {type(observer).__name__}")
    wanted = None
    if times is not None:
        wanted = np.asarray(times)
        if wanted.ndim != 1 or not (np.issubdtype(wanted.dtype, np.floating) or np.issubdtype(wanted.dtype, np.integer)):
            raise TypeError(f"times must be None or a 1-D array of real numbers, not {wanted.dtype} of shape {wanted.shape}")
        wanted = wanted.astype(np.float64)
        if not np.all(np.isfinite(wanted)) or np.any(wanted < t0) or np.any(wanted > t1):
            raise ValueError(f"times must be finite and within [t0, t1] = [{t0!r}, {t1!r}]")
    engine_problem = problem if isinstance(problem, str) else _with_derivatives(problem, "auto")
    try:
        run = _hindsight._simulate(engine_problem, p, integrator, step, t0, t1, bool(adaptive), rtol, atol, options,
                                   observer, True, wanted is not None)
    except (ValueError, NumericalError) as error:
        raise _in_solver_words(error) from None
    result = Result(psi=run["psi"], stopped_by_observer=run["stopped_by_observer"], summary=run["summary"])
    if wanted is None:
        result["times"], result["states"] = run["times"], run["states"]
    else:
        if run["stopped_by_observer"] and run["times"].size and np.any(wanted > run["times"][-1]):
            raise ValueError("the observer stopped the simulation before the last of `times`")
        result["times"] = wanted
        result["states"] = _hermite(run["times"], run["states"], run["rates"], wanted)
    return result


def _hermite(grid, states, rates, wanted):
    """The cubic Hermite interpolant of (grid, states, rates = F) at `wanted`; at a grid point, the state."""
    import numpy as np
    if len(grid) == 1:  # an observer stopped the simulation at t0
        return np.repeat(states[:1], len(wanted), axis=0)
    k = np.clip(np.searchsorted(grid, wanted, side="right") - 1, 0, len(grid) - 2)
    h = grid[k + 1] - grid[k]
    s = ((wanted - grid[k]) / h)[:, None]
    h = h[:, None]
    h00 = (1 + 2 * s) * (1 - s) ** 2
    h10 = s * (1 - s) ** 2
    h01 = s ** 2 * (3 - 2 * s)
    h11 = s ** 2 * (s - 1)
    return h00 * states[k] + h10 * h * rates[k] + h01 * states[k + 1] + h11 * h * rates[k + 1]


def storage_specs():
    """Every storage strategy of the C++ factory with its keys and their documentation: a list of dicts
    (name, summary, exact, example, key_docs = {key: doc}, predicted: whether schedule() predicts it,
    not_predicted: why not, else "")."""
    return [Result(entry) for entry in _hindsight._storage_specs()]


def schedule(spec, steps, state_bytes, stages=4, costs=None, actions=False, stage_bytes=0, bound=False):
    """What storage strategy `spec` will do for `steps` fixed steps of states of `state_bytes` bytes,
    without running a model (the C++ of `hindsight schedule`; full, disk, binomial, online, multilevel, cams incl. online=1):
    forward and recomputed steps, rhs evaluations for `stages` right-hand sides per step, reads, writes and
    peak bytes per level, and the predicted cost under `costs` = "uf:ub:wd:rd" (seconds). With
    actions=True the dict also holds the action stream as text. `stage_bytes`: the rhs data a problem
    keeps per stage with the stage values (`--stage-bytes`; a SecondOrderProblem of f coordinates
    8 (f + f (f + 1) / 2), the rod's 10 modes 520). bound=True (multilevel plans, `--bound`) adds
    "lower_bound": no schedule of H-Revolve's family on these levels has a smaller schedule part
    (docs/theory/storage.md, "A certificate for large N"). ValueError names a bad argument."""
    if not isinstance(spec, str):
        raise TypeError(f"spec must be a storage spec string such as 'binomial:checkpoints=50', not "
                        f"{type(spec).__name__} {spec!r}")
    steps = _schedule_integer("steps", steps, 1, 4_000_000_000_000_000_000)
    state_bytes = _schedule_integer("state_bytes", state_bytes, 8, 8 * 2147483647)
    stages = _schedule_integer("stages", stages, 1, 64)
    stage_bytes = _schedule_integer("stage_bytes", stage_bytes, 0, 8 * 2147483647)
    if costs is not None and not isinstance(costs, str):
        raise TypeError(f"costs must be a string 'uf:ub:wd:rd' or None, not {type(costs).__name__}")
    if not isinstance(actions, bool):
        raise TypeError(f"actions must be True or False, not {type(actions).__name__}")
    if not isinstance(bound, bool):
        raise TypeError(f"bound must be True or False, not {type(bound).__name__}")
    try:
        return Result(_hindsight._schedule(spec, steps, state_bytes, stages, costs or "", actions, stage_bytes,
                                           bound))
    except ValueError as error:
        raise _in_python_words(error) from None


def _schedule_integer(name, value, low, high):
    """An integer argument of schedule(): ints and NumPy integers; bools, floats (2.9 would be read as 2)
    and strings are a TypeError, values outside [low, high] a ValueError naming the argument."""
    if type(value) is int:  # the common case, without importing NumPy (a stream's first action waits for it)
        if not low <= value <= high:
            raise ValueError(f"{name} = {value} must be an integer in [{low}, {high}]")
        return value
    import numpy as np
    # NumPy's bool_ still has a (deprecated) __index__: True would be read as 1 step, like bool.
    if isinstance(value, (bool, np.bool_)) or not hasattr(value, "__index__"):
        raise TypeError(f"{name} must be an integer in [{low}, {high}], not {type(value).__name__} {value!r}")
    value = operator.index(value)
    if not low <= value <= high:
        raise ValueError(f"{name} = {value} must be an integer in [{low}, {high}]")
    return value


def check_storage_spec(spec):
    """Parses `spec` with the C++ factory: the normalized spec, or ValueError naming the bad key/value."""
    return _hindsight._check_storage_spec(spec)
