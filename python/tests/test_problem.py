"""A problem written in Python: the damped oscillator y'' + c y' + k y = 0, y(0) = y0, y'(0) = 0,
psi = int_0^T y^2 dt, p = (k, c, y0), against its closed-form psi and gradient (the closed form
differentiated by complex step, exact to round-off) and against the same problem in C++."""
import cmath

import numpy as np
import pytest

import hindsight


class OscillatorByVjp:
    """(dF/dz)^T w instead of the Jacobian: enough for explicit methods."""
    state_size = 2
    parameter_size = 3
    name = "python-oscillator"

    def initial_state(self, p):
        return np.array([p[2], 0.0])

    def initial_state_vjp(self, p, lam):
        return np.array([0.0, 0.0, lam[0]])

    def rhs(self, t, z, p):
        return np.array([z[1], -p[0] * z[0] - p[1] * z[1]])

    def rhs_state_vjp(self, t, z, p, w):
        return np.array([-p[0] * w[1], w[0] - p[1] * w[1]])

    def rhs_parameter_vjp(self, t, z, p, w):
        return np.array([-z[0] * w[1], -z[1] * w[1], 0.0])

    def integrand(self, t, z, p):
        return z[0] * z[0]

    def integrand_state_gradient(self, t, z, p):
        return np.array([2.0 * z[0], 0.0])

    def integrand_parameter_gradient(self, t, z, p):
        return np.zeros(3)


class Oscillator(OscillatorByVjp):
    """With the dense Jacobian (implicit methods and CVODES need it); rhs_state_vjp = None: not given."""
    rhs_state_vjp = None

    def rhs_jacobian(self, t, z, p):
        return np.array([[0.0, 1.0], [-p[0], -p[1]]])


def exact_psi(k, c, y0, T):
    """problems/classic Oscillator::exactObjective, in complex arithmetic."""
    s = -c / 2
    w = cmath.sqrt(k - c * c / 4)
    a = y0
    b = -s * a / w
    alpha, beta = 2 * s, 2 * w
    e = cmath.exp(alpha * T)
    i0 = (e - 1) / alpha
    den = alpha * alpha + beta * beta
    ic = (e * (alpha * cmath.cos(beta * T) + beta * cmath.sin(beta * T)) - alpha) / den
    is_ = (e * (alpha * cmath.sin(beta * T) - beta * cmath.cos(beta * T)) + beta) / den
    return (a * a + b * b) / 2 * i0 + (a * a - b * b) / 2 * ic + a * b * is_


def exact_gradient(p, T):
    h = 1e-30
    g = []
    for i in range(3):
        q = [complex(v) for v in p]
        q[i] += 1j * h
        g.append(exact_psi(*q, T).imag / h)
    return np.array(g)


P = np.array([4.0, 0.3, 1.2])
T = 5.0


@pytest.mark.parametrize("problem", [Oscillator(), OscillatorByVjp()], ids=["jacobian", "vjp"])
def test_oscillator_matches_closed_form(problem):
    r = hindsight.gradient(problem, P, integrator="rk4", step=1e-3, t1=T)
    assert r.summary["steps"] == 5000
    assert r.summary["method"] == "rk4"
    psi = exact_psi(*P, T).real
    g = exact_gradient(P, T)
    # RK4 at h = 1e-3: errors ~1e-12; a wrong or missing term (e.g. the initial-state VJP, which is
    # the whole of dpsi/dy0) would be O(1).
    assert abs(r.psi - psi) <= 1e-9 * abs(psi)
    np.testing.assert_allclose(r.gradient, g, rtol=1e-8, atol=0)


def test_same_bits_as_the_cpp_oscillator_and_exact_storages():
    py = hindsight.gradient(Oscillator(), P, integrator="rk4", step=1e-2, t1=T)
    cpp = hindsight.classic_gradient("oscillator", P, integrator="rk4", step=1e-2, t1=T)
    np.testing.assert_allclose(py.gradient, cpp.gradient, rtol=1e-12)
    assert abs(py.psi - cpp.psi) <= 1e-12 * abs(cpp.psi)
    checkpointed = hindsight.gradient(Oscillator(), P, integrator="rk4", step=1e-2, t1=T,
                                      storage="binomial:checkpoints=7")
    assert checkpointed.summary["recomputed_steps"] > 0
    assert checkpointed.gradient.tobytes() == py.gradient.tobytes()


@pytest.mark.parametrize("integrator,adjoint,adaptive", [("dopri5", "discrete", True), ("trbdf2", "discrete", False),
                                                         ("dopri5", "continuous", True), ("rk4", "cvodes", False)])
def test_other_integrators_and_routes(integrator, adjoint, adaptive):
    r = hindsight.gradient(Oscillator(), P, integrator=integrator, step=1e-3, t1=T, adjoint=adjoint,
                           adaptive=adaptive, rtol=1e-10, atol=1e-12)
    assert r.summary["adjoint"] == adjoint
    np.testing.assert_allclose(r.gradient, exact_gradient(P, T), rtol=1e-5)


def test_terminal_term():
    class WithTerminal(Oscillator):
        def terminal(self, z, p):
            return 0.5 * z[1] ** 2

        def terminal_gradient(self, z, p):
            return np.array([0.0, z[1]]), np.zeros(3)

    base = hindsight.gradient(Oscillator(), P, step=1e-2, t1=T)
    r = hindsight.gradient(WithTerminal(), P, step=1e-2, t1=T)
    # Central differences of the computed psi (the discrete adjoint is its exact derivative).
    for i in range(3):
        h = 1e-6 * max(1.0, abs(P[i]))
        q1, q2 = P.copy(), P.copy()
        q1[i] += h
        q2[i] -= h
        fd = (hindsight.gradient(WithTerminal(), q1, step=1e-2, t1=T).psi -
              hindsight.gradient(WithTerminal(), q2, step=1e-2, t1=T).psi) / (2 * h)
        assert abs(fd - r.gradient[i]) <= 1e-6 * abs(fd) + 1e-9
    assert r.psi > base.psi


def test_bad_problems_are_value_errors():
    class NoRhs:
        state_size, parameter_size = 2, 3
    with pytest.raises(ValueError, match="problem needs a method initial_state"):
        hindsight.gradient(NoRhs(), P)
    with pytest.raises(ValueError, match="rhs_jacobian"):  # only the problem's own derivatives
        hindsight.gradient(NoRhs(), P, derivatives="given")

    class WrongShape(Oscillator):
        def rhs(self, t, z, p):
            return np.zeros(3)
    with pytest.raises(ValueError, match=r"problem.rhs must return an array of shape \(2,\)"):
        hindsight.gradient(WrongShape(), P)
    with pytest.raises(ValueError, match="problem.parameter_size = 3"):
        hindsight.gradient(Oscillator(), np.zeros(2))
    with pytest.raises(ValueError, match="unknown storage strategy 'nope'"):
        hindsight.gradient(Oscillator(), P, storage="nope")


def test_python_exceptions_propagate_unchanged():
    class Raising(Oscillator):
        def integrand(self, t, z, p):
            if t > 0.5:
                raise ZeroDivisionError("from the integrand")
            return 0.0
    with pytest.raises(ZeroDivisionError, match="from the integrand"):
        hindsight.gradient(Raising(), P, t1=1.0)
