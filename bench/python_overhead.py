#!/usr/bin/python3
"""What a problem written in Python costs next to the same problem in C++ (README "Python").

The damped oscillator y'' + c y' + k y = 0, psi = int y^2 dt, p = (k, c, y0), once as the Python class
of python/tests/test_problem.py (NumPy arrays, every derivative a Python call) and once as the C++
problem of problems/classic (hindsight.classic_gradient), both through the same engine call: rk4,
fixed step, full storage, discrete adjoint. Prints the median of --repeat runs of each and the ratio.

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
    p = np.array([4.0, 0.3, 1.2])
    t1 = 10.0
    step = t1 / args.steps
    python_seconds, py = median_seconds(lambda: hindsight.gradient(Oscillator(), p, step=step, t1=t1), args.repeat)
    cpp_seconds, cpp = median_seconds(lambda: hindsight.classic_gradient("oscillator", p, step=step, t1=t1),
                                      args.repeat)
    difference = float(np.max(np.abs(py.gradient - cpp.gradient) / np.abs(cpp.gradient)))
    calls = py.summary["rhs_evaluations"] + py.summary["jacobian_evaluations"]
    print(f"oscillator, rk4, {py.summary['steps']} steps, full storage, discrete adjoint; median of {args.repeat}")
    print(f"python problem: {python_seconds * 1e3:9.2f} ms  ({python_seconds / py.summary['steps'] * 1e6:.1f} us/step, "
          f"{calls} rhs + jacobian calls)")
    print(f"C++ problem:    {cpp_seconds * 1e3:9.2f} ms  ({cpp_seconds / cpp.summary['steps'] * 1e6:.3f} us/step)")
    print(f"ratio python / C++: {python_seconds / cpp_seconds:.0f}x; max relative gradient difference {difference:.1e}")


if __name__ == "__main__":
    main()
