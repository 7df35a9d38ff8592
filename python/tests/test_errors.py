"""C++ exceptions map to Python with the CLI's messages: bad input -> ValueError, numerical failures
-> hindsight.NumericalError, storage failures -> hindsight.StorageError (both RuntimeError)."""
import subprocess

import numpy as np
import pytest

import hindsight
from conftest import COARSE, COARSE_SET, TINY


def cli_error(cli, args):
    run = subprocess.run([cli, "evaluate"] + args, capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    prefix = "hindsight: error: "
    assert run.stderr.startswith(prefix), run.stderr
    return run.stderr[len(prefix):].strip()


def test_exception_classes():
    assert issubclass(hindsight.NumericalError, RuntimeError)
    assert issubclass(hindsight.StorageError, RuntimeError)
    assert not issubclass(hindsight.NumericalError, hindsight.StorageError)


def test_bad_config_is_value_error_with_the_cli_message(cli):
    with pytest.raises(ValueError) as error:
        hindsight.PistonRod(rod={"modeCount": 0})
    assert str(error.value) == cli_error(cli, ["--set", "rod.modeCount=0"])
    assert "'rod.modeCount' = 0 is outside the allowed range [1, 40]" in str(error.value)
    with pytest.raises(ValueError, match="unknown"):
        hindsight.PistonRod(rod={"noSuchField": 1})
    with pytest.raises(ValueError, match="section.field"):
        hindsight.PistonRod(modeCount=4)


def test_bad_flag_values_are_value_errors_naming_the_key(cli):
    rod = hindsight.PistonRod(COARSE)
    with pytest.raises(ValueError) as error:
        rod.evaluate(gradient=False, storage="binomial:checkpoints=0")
    # The CLI names its flag (--storage), the module the keyword (storage); the rest is the same text.
    expected = cli_error(cli, COARSE_SET + ["--storage", "binomial:checkpoints=0"])
    assert str(error.value) == expected.replace("--storage", "storage")
    with pytest.raises(ValueError, match="discrete"):
        rod.evaluate(gradient=False, adjoint="magic")


def test_bad_designs_are_value_errors():
    rod = hindsight.PistonRod(COARSE)
    with pytest.raises(ValueError, match=r"shape \(ny, nx\) = \(4, 20\)"):
        rod.evaluate(np.ones((20, 4)))
    x = rod.x0.copy()
    x[2, 5] = 1.5
    with pytest.raises(ValueError, match=r"design x: x\[2\]\[5\] \(row 2, column 5\) = 1.5 is outside \[0.010000, 1\]"):
        rod.evaluate(x)
    x = rod.x0.copy()
    x[0, 0] = 0.5
    with pytest.raises(ValueError, match="end columns are not design variables"):
        rod.evaluate(x)
    x = rod.x0.copy()
    x[1, 1] = np.nan
    with pytest.raises(ValueError, match="nan"):
        rod.evaluate(x)


def test_storage_failure_is_storage_error():
    rod = hindsight.PistonRod(TINY)
    with pytest.raises(hindsight.StorageError, match="would exceed its budget of 16 B"):
        rod.evaluate(gradient=True, storage="full:budget=16B")
    with pytest.raises(hindsight.StorageError, match="cannot use directory '/proc/nonexistent/x'"):
        rod.evaluate(gradient=True, storage="disk:dir=/proc/nonexistent/x")
    # The module stays usable.
    assert rod.evaluate(gradient=True).psi1 > 0


def test_numerical_failure_is_numerical_error():
    # An explicit (RK4) step far beyond the stability limit of the rod's fastest mode: the state grows
    # without bound, and the mechanism's position solve is the first to refuse it, naming the time.
    rod = hindsight.PistonRod(TINY, simulation={"integrator": "rk4", "step": 1e-2}, rod={"endTime": 2.0, "rampTime": 1.0,
                                                                     "eslSamples": 5})
    with pytest.raises(hindsight.NumericalError, match=r"move by .* far too large \(at t = "):
        rod.evaluate(gradient=True)


def test_numerical_failure_of_a_python_problem():
    class Blowup:
        state_size, parameter_size = 1, 1

        def initial_state(self, p):
            return np.array([1.0])

        def rhs(self, t, z, p):
            return np.array([np.inf])

        def rhs_jacobian(self, t, z, p):
            return np.zeros((1, 1))

        def rhs_parameter_vjp(self, t, z, p, w):
            return np.zeros(1)

        def integrand(self, t, z, p):
            return 0.0

        def integrand_state_gradient(self, t, z, p):
            return np.zeros(1)

        def integrand_parameter_gradient(self, t, z, p):
            return np.zeros(1)

    with pytest.raises(hindsight.NumericalError):
        hindsight.gradient(Blowup(), np.ones(1))


def test_unreadable_results_are_storage_errors(tmp_path):
    bad = tmp_path / "results.h5"
    bad.write_bytes(b"not hdf5")
    with pytest.raises(hindsight.StorageError, match="results.h5"):
        hindsight.read_results(tmp_path)


def test_python_values_are_converted_or_refused_naming_the_field():
    # NaN reaches the field's own check (it was a JSON parse error), NumPy scalars are numbers.
    with pytest.raises(ValueError, match="crankSpeed"):
        hindsight.PistonRod(TINY, rod={"crankSpeed": float("nan")})
    rod = hindsight.PistonRod(TINY, rod={"modeCount": np.int64(2), "crankSpeed": np.float64(20.0)})
    assert rod.config["rod"]["modeCount"] == 2 and rod.config["rod"]["crankSpeed"] == 20.0
    with pytest.raises(ValueError, match=r"rod.crankSpeed = \(20\+1j\) must be a real number, not complex"):
        hindsight.PistonRod(TINY, rod={"crankSpeed": 20 + 1j})
    with pytest.raises(ValueError, match="not a configuration value"):
        hindsight.PistonRod(TINY, rod={"crankSpeed": object()})


def test_designs_of_complex_or_string_arrays_are_refused():
    rod = hindsight.PistonRod(TINY)
    x = rod.x0
    with pytest.raises(ValueError, match="design x must hold real numbers .* not dtype complex128"):
        rod.evaluate(x.astype(complex) + 0.1j, gradient=False)
    with pytest.raises(ValueError, match="design x must hold real numbers .* not dtype <U"):
        rod.evaluate(x.astype(str), gradient=False)
    # Integer arrays are real numbers.
    assert rod.evaluate(np.ones(x.shape, dtype=np.int64), gradient=False).psi1 > 0


def test_a_callback_returning_a_false_value_stops_the_run(tmp_path):
    for index, answer in enumerate((0, False, np.False_)):
        out = tmp_path / f"stop_{index}"
        result = hindsight.optimize(TINY, out=out, callback=lambda record: answer, optimization={"iterations": 3})
        assert result["stopped_by_callback"], answer
        assert len(result["history"]["iteration"]) == 1, answer
    result = hindsight.optimize(TINY, out=tmp_path / "none", callback=lambda record: None,
                                optimization={"iterations": 1})
    assert not result["stopped_by_callback"]
