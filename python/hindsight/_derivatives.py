"""Derivatives generated for a problem written in Python (docs/guides/python.md, "Problems without
hand-written derivatives"): the complex step of Squire & Trapp ("Using complex variables to estimate
derivatives of real functions", SIAM Review 1998) over the user's own NumPy functions.

For a real-analytic f, f(x + i h e_j) = f(x) + i h df/dx_j - h^2/2 d2f/dx_j^2 - i h^3/6 ... so
Im f(x + i h e_j) / h = df/dx_j + O(h^2) with no subtraction: with h = 1e-30 the O(h^2) term is far below
round-off, and the derivative is exact to the last bits of the function's own evaluation (no step-size
trade-off, unlike finite differences). A state Jacobian costs n evaluations of F in complex arithmetic,
(dF/dp)^T w and dG/dp cost np each.

What the user's functions must do: accept complex arrays and compute with the arithmetic and NumPy's
analytic functions (+ - * / **, np.sin, np.exp, np.sqrt, ...), build their result from their inputs
(np.array([...]), np.zeros_like(z), np.empty(n, dtype=z.dtype)) and return it. Not allowed, because they
lose the imaginary part: abs/np.abs, np.maximum/np.minimum, comparisons and branches on the state,
float(...), .real, assigning into a float64 array (NumPy's ComplexWarning; turned into an error here).
Every generated derivative is checked once, at the first point it is needed, against central finite
differences; a mismatch (the sign of a function that is not complex-safe) raises ValueError naming the
method, so a wrong derivative cannot reach a gradient silently at that point.
"""
import warnings

import numpy as np

# NumPy 1.25 moved the warning to np.exceptions; Debian 12's NumPy 1.24 has it at the top level.
ComplexWarning = getattr(getattr(np, "exceptions", None), "ComplexWarning", None) or np.ComplexWarning

STEP = 1e-30  # the complex step: O(h^2) = 1e-60 relative truncation, no cancellation
# The finite-difference check: central differences with step 1e-6 (1 + |x|) are good to ~1e-9 relative for
# smooth functions; a derivative that is wrong (a dropped imaginary part) is off by O(1).
CHECK_STEP = 1e-6
CHECK_TOLERANCE = 1e-5

_DERIVATIVE_METHODS = ("rhs_jacobian", "rhs_parameter_vjp", "integrand_state_gradient",
                       "integrand_parameter_gradient", "initial_state_vjp", "terminal_gradient")


def missing_derivatives(problem):
    """The derivative methods `problem` lacks (None counts as absent), in a fixed order."""
    def has(name):
        return getattr(problem, name, None) is not None
    missing = [name for name in _DERIVATIVE_METHODS if not has(name)]
    if "rhs_jacobian" in missing and has("rhs_state_vjp"):
        missing.remove("rhs_jacobian")  # the engine uses the given vector-Jacobian product
    if not has("terminal"):
        missing = [name for name in missing if name != "terminal_gradient"]
    return missing


def _call(problem, method, *args):
    """problem.method(*args) as a complex128 1-D or 2-D array; NumPy's ComplexWarning (an imaginary part
    dropped by assigning into a float array) is an error naming the method."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", ComplexWarning)
        try:
            value = getattr(problem, method)(*args)
        except ComplexWarning as error:
            raise ValueError(f"problem.{method} dropped the imaginary part of a complex input ({error}); "
                             "generated derivatives need arrays of the input's dtype "
                             "(np.zeros_like(z), np.empty(n, dtype=z.dtype))") from None
        except TypeError as error:
            raise ValueError(f"problem.{method} cannot be evaluated in complex arithmetic for generated "
                             f"derivatives ({error}); write it with +, -, *, /, ** and NumPy's analytic "
                             "functions, or give its derivatives (docs/guides/python.md)") from None
    return np.asarray(value, dtype=np.complex128)


def _complex_step(function, x, count):
    """d function / d x (column j = derivative in x_j) of a function of a real vector, by the complex step;
    `function` maps a complex vector to a scalar or a 1-D array."""
    columns = []
    for j in range(count):
        shifted = x.astype(np.complex128)
        shifted[j] += 1j * STEP
        columns.append(np.imag(function(shifted)) / STEP)
    if not columns:
        return np.zeros((np.size(np.real(function(x.astype(np.complex128)))), 0))
    return np.column_stack([np.atleast_1d(c) for c in columns])


def _finite_difference(function, x, count):
    """The same derivative by central differences (the check)."""
    columns = []
    for j in range(count):
        h = CHECK_STEP * (1.0 + abs(x[j]))
        up, down = x.astype(np.complex128), x.astype(np.complex128)
        up[j] += h
        down[j] -= h
        columns.append(np.real(function(up) - function(down)) / (2.0 * h))
    return np.column_stack([np.atleast_1d(c) for c in columns]) if columns else None


class GeneratedDerivatives:
    """`problem` with its missing derivative methods generated by the complex step (module docstring).
    Methods the problem has are used as they are; hindsight.gradient and hindsight.simulate wrap a
    problem in this when it lacks any (derivatives="generated" forces every one to be generated)."""

    def __init__(self, problem, force=False):
        self._problem = problem
        for attribute in ("state_size", "parameter_size"):
            if not hasattr(problem, attribute):
                raise ValueError(f"problem needs an attribute {attribute}")
        for method in ("initial_state", "rhs"):
            if getattr(problem, method, None) is None:
                raise ValueError(f"problem needs a method {method}")
        self.state_size = int(problem.state_size)
        self.parameter_size = int(problem.parameter_size)
        self.name = getattr(problem, "name", type(problem).__name__)
        self.generated = list(_DERIVATIVE_METHODS if force else missing_derivatives(problem))
        if force and getattr(problem, "terminal", None) is None:
            self.generated.remove("terminal_gradient")
        self._checked = set()
        for name in ("initial_state", "rhs", "integrand", "terminal", "rhs_state_vjp"):
            if getattr(problem, name, None) is not None:
                setattr(self, name, getattr(problem, name))
        if getattr(problem, "integrand", None) is None:  # a forward-only problem: psi = phi (or 0)
            self.integrand = lambda t, z, p: 0.0
        for name in _DERIVATIVE_METHODS:
            if name in self.generated:
                setattr(self, name, getattr(self, "_generated_" + name))
            elif getattr(problem, name, None) is not None:
                setattr(self, name, getattr(problem, name))
        if getattr(self, "terminal", None) is None:
            self.terminal_gradient = None

    def _check(self, method, exact, function, x, count):
        """Compares a generated derivative with central differences once per method (module docstring)."""
        if method in self._checked:
            return
        self._checked.add(method)
        reference = _finite_difference(function, x, count)
        if reference is None:
            return
        scale = 1.0 + max(np.max(np.abs(exact)), np.max(np.abs(reference)))
        error = np.max(np.abs(exact - reference))
        if not error <= CHECK_TOLERANCE * scale:
            raise ValueError(
                f"the generated derivative of problem.{method.replace('_jacobian', '').replace('_vjp', '')} "
                f"differs from finite differences by {error:.3g} (scale {scale:.3g}): the function is not "
                "complex-safe (abs, np.maximum, comparisons or branches on the state, float(), .real); give "
                "its derivative by hand (docs/guides/python.md)")

    def _generated_rhs_jacobian(self, t, z, p):
        function = lambda zc: _call(self._problem, "rhs", t, zc, p.astype(np.complex128))
        jacobian = _complex_step(function, z, self.state_size)
        self._check("rhs_jacobian", jacobian, function, z, self.state_size)
        return jacobian

    def _generated_rhs_parameter_vjp(self, t, z, p, w):
        function = lambda pc: _call(self._problem, "rhs", t, z.astype(np.complex128), pc)
        jacobian = _complex_step(function, p, self.parameter_size)
        self._check("rhs_parameter_vjp", jacobian, function, p, self.parameter_size)
        return jacobian.T @ w if self.parameter_size else np.zeros(0)

    def _integrand(self, t):
        if getattr(self._problem, "integrand", None) is None:
            return None
        return lambda z, p: _call(self._problem, "integrand", t, z, p)

    def _generated_integrand_state_gradient(self, t, z, p):
        integrand = self._integrand(t)
        if integrand is None:
            return np.zeros(self.state_size)
        function = lambda zc: integrand(zc, p.astype(np.complex128))
        gradient = _complex_step(function, z, self.state_size)[0]
        self._check("integrand_state_gradient", gradient, lambda zc: np.atleast_1d(function(zc)), z, self.state_size)
        return gradient

    def _generated_integrand_parameter_gradient(self, t, z, p):
        integrand = self._integrand(t)
        if integrand is None or self.parameter_size == 0:
            return np.zeros(self.parameter_size)
        function = lambda pc: integrand(z.astype(np.complex128), pc)
        gradient = _complex_step(function, p, self.parameter_size)[0]
        self._check("integrand_parameter_gradient", gradient, lambda pc: np.atleast_1d(function(pc)), p,
                    self.parameter_size)
        return gradient

    def _generated_initial_state_vjp(self, p, lam):
        if self.parameter_size == 0:
            return np.zeros(0)
        function = lambda pc: _call(self._problem, "initial_state", pc)
        jacobian = _complex_step(function, p, self.parameter_size)
        self._check("initial_state_vjp", jacobian, function, p, self.parameter_size)
        return jacobian.T @ lam

    def _generated_terminal_gradient(self, z, p):
        n = self.state_size
        both = np.concatenate([z, p])
        function = lambda x: np.atleast_1d(_call(self._problem, "terminal", x[:n], x[n:]))
        gradient = _complex_step(function, both, both.size)[0]
        self._check("terminal_gradient", gradient, function, both, both.size)
        return gradient[:n], gradient[n:]
