#!/usr/bin/python3
"""What a problem written in Python costs next to the same problem in C++ (docs/guides/python.md).

Two problems of problems/classic, each once as a Python class (NumPy arrays, every derivative a Python
call) and once in C++ (hindsight.classic_gradient), both through the same engine call: rk4, fixed step,
full storage, discrete adjoint. The damped oscillator y'' + c y' + k y = 0 (python/tests/test_problem.py;
in C++ a SecondOrderProblem behind the first-order adapter) and the decay z' = -k z (in C++ a plain
first-order Problem, the cheapest possible step). Prints the median of --repeat runs and the ratio.

    PYTHONPATH=build/python python3 bench/python_overhead.py [--steps 10000] [--repeat 5]
"""
import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python", "tests"))
import hindsight  # noqa: E402
from test_problem import Oscillator  # noqa: E402


class Decay:
    """z' = -k z, z(0) = a, psi = int z^2 dt, p = (k, a): problems/classic ExponentialDecay in Python."""
    state_size, parameter_size, name = 1, 2, "python-decay"

    def initial_state(self, p):
        return np.array([p[1]])

    def initial_state_vjp(self, p, lam):
        return np.array([0.0, lam[0]])

    def rhs(self, t, z, p):
        return -p[0] * z

    def rhs_jacobian(self, t, z, p):
        return np.array([[-p[0]]])

    def rhs_parameter_vjp(self, t, z, p, w):
        return np.array([-z[0] * w[0], 0.0])

    def integrand(self, t, z, p):
        return z[0] * z[0]

    def integrand_state_gradient(self, t, z, p):
        return 2.0 * z

    def integrand_parameter_gradient(self, t, z, p):
        return np.zeros(2)


def median_seconds(run, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=10000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    t1 = 10.0
    step = t1 / args.steps
    print(f"rk4, {args.steps} steps over [0, {t1}], full storage, discrete adjoint; median of {args.repeat} runs")
    for name, problem, p in [("oscillator", Oscillator(), np.array([4.0, 0.3, 1.2])),
                             ("decay", Decay(), np.array([0.7, 1.3]))]:
        python_seconds, py = median_seconds(lambda: hindsight.gradient(problem, p, step=step, t1=t1), args.repeat)
        cpp_seconds, cpp = median_seconds(lambda: hindsight.classic_gradient(name, p, step=step, t1=t1), args.repeat)
        difference = float(np.max(np.abs(py.gradient - cpp.gradient) / np.abs(cpp.gradient)))
        calls = py.summary["rhs_evaluations"] + py.summary["jacobian_evaluations"]
        steps = py.summary["steps"]
        print(f"{name:10s} python {python_seconds * 1e3:8.1f} ms ({python_seconds / steps * 1e6:6.1f} us/step, "
              f"{calls} rhs + jacobian calls)  C++ {cpp_seconds * 1e3:7.2f} ms ({cpp_seconds / steps * 1e6:6.3f} us/step)"
              f"  ratio {python_seconds / cpp_seconds:5.0f}x  max rel. gradient difference {difference:.1e}")
    # The rod: the module's own cost around one evaluation (configuration, conversions, the interrupt poll
    # once per step), i.e. the call's wall time minus the phases the evaluation times itself.
    rod = hindsight.PistonRod()
    x0 = rod.x0
    wrapper = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        r = rod.evaluate(x0, gradient=True)
        wall = time.perf_counter() - start
        wrapper.append((wall, wall - sum(r.seconds.values())))
    wall, outside = sorted(wrapper)[len(wrapper) // 2]
    print(f"rod 200 x 12 at x0, psi1 + psi2 + gradients: {wall:.3f} s per call, of which {outside * 1e3:.1f} ms outside "
          f"the evaluation's timed phases (model, simulation, chain, ESL)")


if __name__ == "__main__":
    main()
