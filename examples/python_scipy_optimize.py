#!/usr/bin/python3
# %% [markdown]
# # SciPy drives the piston rod
#
# scipy.optimize.minimize with SLSQP minimises the integral compliance psi1 of the piston rod over its
# design variables, with the volume fraction as an inequality constraint, using hindsight's exact
# adjoint gradient (docs/guides/python.md). hindsight's own optimizer is MMA (`hindsight optimize`); this
# shows that any optimizer can drive the model through the module.
#
#     PYTHONPATH=build/python python3 examples/python_scipy_optimize.py [--iterations 5] [--coarse]

# %%
import argparse

import numpy as np
from scipy.optimize import minimize

import hindsight

parser = argparse.ArgumentParser(description="SLSQP on the piston rod with the volume constraint")
parser.add_argument("--iterations", type=int, default=5, help="SLSQP iterations (maxiter)")
parser.add_argument("--coarse", action="store_true", help="20 x 4 elements, 4 modes")
args, _ = parser.parse_known_args()

config = {"rod": {"elementsAlongLength": 20, "elementsThroughHeight": 4, "modeCount": 4}} if args.coarse else {}
rod = hindsight.PistonRod(config)
volume_bound = rod.config["optimization"]["volumeFraction"]
lower = rod.config["rod"]["designLowerBound"]
v0 = rod.design_variables(rod.x0)

# %% One evaluation per design, shared by the objective and the constraint.
cache = {}


def evaluate(v):
    key = v.tobytes()
    if key not in cache:
        cache.clear()
        cache[key] = rod.evaluate(rod.design_grid(np.clip(v, lower, 1.0)), gradient=True, psi2=False)
    return cache[key]


scale = evaluate(v0).psi1  # psi1(x0) = 1 after scaling, as MMA's objective_scale
history = []


def objective(v):
    r = evaluate(v)
    return r.psi1 / scale, r.dpsi1_dv / scale


def volume_slack(v):  # >= 0 when feasible
    return volume_bound - evaluate(v).volume_fraction


def volume_slack_gradient(v):
    return -evaluate(v).dvolume_dv


def record(v):
    r = evaluate(v)
    history.append((r.psi1, r.volume_fraction))
    print(f"iteration {len(history):3d}  psi1 {r.psi1:.6f}  V/V0 {r.volume_fraction:.4f}", flush=True)


# %% SLSQP with bounds [designLowerBound, 1] and the volume constraint.
start = evaluate(v0)
result = minimize(objective, v0, jac=True, method="SLSQP", bounds=[(lower, 1.0)] * v0.size,
                  constraints=[{"type": "ineq", "fun": volume_slack, "jac": volume_slack_gradient}],
                  options={"maxiter": args.iterations, "ftol": 1e-9}, callback=record)
final = evaluate(result.x)
print(f"SLSQP: {result.message} after {result.nit} iterations")
print(f"psi1 {start.psi1:.6f} -> {final.psi1:.6f}, volume fraction {start.volume_fraction:.4f} -> "
      f"{final.volume_fraction:.4f} (bound {volume_bound})")
feasible = final.volume_fraction <= volume_bound + 1e-6
print(f"scipy drove the rod: psi1 decreased: {'yes' if final.psi1 < start.psi1 else 'NO'}, "
      f"volume constraint held: {'yes' if feasible else 'NO'}")
