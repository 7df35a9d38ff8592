#!/usr/bin/python3
# %% [markdown]
# # Storage strategies on the piston rod: time against memory
#
# One gradient dpsi1/dx of the piston rod per trajectory-storage strategy (docs/guides/python.md), with the
# run summary of each: forward + backward seconds, peak bytes in memory, bytes on disk, recomputed
# steps, and how far the gradient is from the one with every state kept ("full"). Exact strategies
# must give the same bits; interpolating or lossy ones a small, measured difference.
#
#     PYTHONPATH=build/python python3 examples/python_storage_sweep.py --out sweep.png [--coarse]
#
# Each `# %%` block is a notebook cell (Jupyter, VS Code); run as a script it prints a table and saves
# the figure.

# %%
import argparse
import shutil
import tempfile

import numpy as np

import hindsight

parser = argparse.ArgumentParser(description="time against memory of the storage strategies on the rod")
parser.add_argument("--out", default="storage_sweep.png", help="figure to write (PNG)")
parser.add_argument("--coarse", action="store_true", help="20 x 4 elements, 4 modes: seconds instead of a minute")
args, _ = parser.parse_known_args()  # parse_known_args: also runs in a notebook kernel

# RK4 at h = 1e-4 (the reference integration): hermite interpolates with the state derivative, which
# the default generalized-alpha does not provide.
config = {"simulation": {"integrator": "rk4", "step": 1e-4}}
if args.coarse:
    config["rod"] = {"elementsAlongLength": 20, "elementsThroughHeight": 4, "modeCount": 4}
rod = hindsight.PistonRod(config)
x = rod.x0
scratch = tempfile.mkdtemp(prefix="hindsight-sweep-")

# %% The strategies: every documented one, several budgets for the checkpointing ones.
for spec in hindsight.storage_specs():
    print(f"{spec.name:11s} {spec.summary}")
strategies = ["full", "binomial:checkpoints=10", "binomial:checkpoints=50", "binomial:checkpoints=200",
              "online:checkpoints=50", "hermite:every=4", "hermite:every=8", "lossy:codec=zfp,tolerance=1e-12",
              "lossy:codec=round,tolerance=1e-6", f"disk:dir={scratch}", f"multilevel:ram=256KiB,disk=1GiB,dir={scratch}"]

# %% One gradient per strategy.
rows = []
reference = None
for spec in strategies:
    r = rod.evaluate(x, gradient=True, storage=spec, psi2=False)
    s = r.summary
    if reference is None:
        reference = r.dpsi1_dx
    error = float(np.max(np.abs(r.dpsi1_dx - reference)) / np.max(np.abs(reference)))
    bitwise = r.dpsi1_dx.tobytes() == reference.tobytes()
    rows.append(dict(spec=spec, seconds=s["forward_seconds"] + s["backward_seconds"], memory=s["peak_bytes_in_memory"],
                     disk=s["bytes_on_disk"], recomputed=s["recomputed_steps"], error=error, bitwise=bitwise,
                     exact=next(d.exact for d in hindsight.storage_specs() if d.name == spec.split(":")[0])))
shutil.rmtree(scratch)  # the disk strategies' folder (they remove their files, not the folder)
print(f"\n{'storage':52s} {'seconds':>8s} {'memory':>10s} {'disk':>10s} {'recomputed':>10s}  max rel. error")
for row in rows:
    print(f"{row['spec'][:52]:52s} {row['seconds']:8.3f} {row['memory']:10d} {row['disk']:10d} "
          f"{row['recomputed']:10d}  {'bitwise' if row['bitwise'] else format(row['error'], '.1e')}")

# %% Time against memory.
import matplotlib  # noqa: E402

if __name__ == "__main__":
    matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

figure, axis = plt.subplots(figsize=(8, 5))
for row in rows:
    marker = "o" if row["exact"] else "s"
    axis.plot(row["memory"], row["seconds"], marker, color="tab:blue" if row["exact"] else "tab:orange")
    axis.annotate(row["spec"].split(",dir=")[0].replace(f"dir={scratch}", "dir=tmp"), (row["memory"], row["seconds"]),
                  fontsize=7, xytext=(4, 2), textcoords="offset points")
axis.set_xscale("log")
axis.set_xlabel("peak bytes in memory (storage + time grid)")
axis.set_ylabel("forward + backward seconds")
axis.set_title(f"Piston rod {rod.shape[1]} x {rod.shape[0]}: one gradient per storage strategy "
               "(circles exact, squares approximate)", fontsize=9)
axis.grid(True, which="both", alpha=0.3)
figure.savefig(args.out, dpi=120, bbox_inches="tight")
print("figure written to", args.out)

# %% The check a test can rely on: exact strategies give the same bits as "full".
exact_ok = all(row["bitwise"] for row in rows if row["exact"])
approximate_small = all(row["error"] < 1e-3 for row in rows if not row["exact"])
print(f"sweep: {len(rows)} storages, exact ones bitwise equal to full: {'yes' if exact_ok else 'NO'}, "
      f"approximate ones within 1e-3: {'yes' if approximate_small else 'NO'}")
