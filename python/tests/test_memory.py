"""No leak over 1000 evaluations: the resident set size after 1000 gradient evaluations of a tiny rod
(and 1000 Python-problem gradients) stays where it was after a warm-up."""
import numpy as np

import hindsight
from conftest import TINY


def rss_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


def test_no_leak_over_1000_rod_evaluations():
    rod = hindsight.PistonRod(TINY)
    x = rod.x0
    for _ in range(100):  # warm-up: allocator pools, NumPy caches
        rod.evaluate(x, gradient=True)
    before = rss_bytes()
    for _ in range(1000):
        r = rod.evaluate(x, gradient=True)
    grown = rss_bytes() - before
    # Measured: 16 KiB of growth (page granularity). A leaked result (its dict, summary and ~10 arrays,
    # over 2 KB) or a leaked trajectory (21 states) per call would add 1-2 MB over 1000 calls.
    assert grown < 512 * 1024, grown
    assert r.psi1 > 0


def test_no_leak_over_1000_python_problem_gradients():
    class Decay:
        state_size, parameter_size = 1, 1

        def initial_state(self, p):
            return np.ones(1)

        def rhs(self, t, z, p):
            return -p[0] * z

        def rhs_jacobian(self, t, z, p):
            return np.array([[-p[0]]])

        def rhs_parameter_vjp(self, t, z, p, w):
            return -z * w

        def integrand(self, t, z, p):
            return z[0] ** 2

        def integrand_state_gradient(self, t, z, p):
            return 2 * z

        def integrand_parameter_gradient(self, t, z, p):
            return np.zeros(1)

    p = np.array([0.7])
    for _ in range(100):
        hindsight.gradient(Decay(), p, step=0.1)
    before = rss_bytes()
    for _ in range(1000):
        r = hindsight.gradient(Decay(), p, step=0.1)
    grown = rss_bytes() - before
    assert grown < 512 * 1024, grown
    # psi = (1 - exp(-2kT)) / (2k) to RK4 accuracy at h = 0.1.
    assert abs(r.psi - (1 - np.exp(-1.4)) / 1.4) < 1e-5
