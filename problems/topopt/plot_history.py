#!/usr/bin/python3
"""psi1 over the iterations of one or two hindsight topology optimizations (e.g. the psi1 and the
psi2 route): the compliance history of each run and its final design.

usage: plot_history.py RESULTS.h5 [RESULTS2.h5] --out FILE.png

Reads the results files written by `hindsight optimize` (layout in problems/topopt/results_file.h) with h5py
and draws with matplotlib (Debian: python3-h5py, python3-matplotlib). For every file psi1 is drawn over
the iterations (solid); for an ESL run also the psi2 it minimised (dashed). Below the history, the last
stored design of every file (density 1 black, 0 white, joint A on the left). A run with operating
scenarios (/scenarios in the file) draws psi1 of every scenario (thin lines, named) and
the worst one of each iteration ringed. Axis labels take the unit and description of each column from
history_columns.json beside this script (generated from problems/topopt/history_schema.h, the one table
of the history's columns); a results file missing one of its columns is refused.
"""
import argparse
import json
import os
import sys


def history_columns():
    """The history's columns (name, type, unit, description, reproducible, optional) as
    problems/topopt/history_schema.h defines them, read from history_columns.json next to this file."""
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "history_columns.json")) as f:
        return {column["name"]: column for column in json.load(f)["columns"]}


def axis_label(column):
    """'description [unit]' of a history column, the description cut at its first parenthesis or period."""
    entry = history_columns()[column]
    words = entry["description"].split(" (")[0].rstrip(".")
    return f"{words} [{entry['unit']}]"


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def load(path):
    import h5py

    with h5py.File(path, "r") as f:
        if text(f.attrs["format"]) != "hindsight-topology-results":
            raise SystemExit(f"{path}: not a hindsight topology results file")
        config = json.loads(text(f.attrs["configuration"]))
        history = {name: f["history"][name][()] for name in f["history"]}
        missing = [name for name, column in history_columns().items()
                   if not column["optional"] and name not in history]
        if missing:
            raise SystemExit(f"{path}: /history lacks the column(s) {', '.join(missing)}")
        designs = f["designs"][()]
        scenarios = f["scenarios"]["psi1"][()] if "scenarios" in f else None
        finished = int(f.attrs["finished"]) == 1
    return {"path": path, "config": config, "history": history, "designs": designs, "finished": finished,
            "scenarios": scenarios}


def draw(runs, out=None):
    """The figure of one or two runs, each a dict with config, history (columns), designs, finished (as
    load() returns and hindsight.read_results() too); saved to `out` when given. Returns the figure.
    Shared with the Python module (hindsight.plot_comparison), which reads the files with its own checked
    reader."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(9, 4.2 + 1.0 * len(runs)))
    grid = fig.add_gridspec(1 + len(runs), 1, height_ratios=[4.0] + [1.0] * len(runs), hspace=0.6)
    axis = fig.add_subplot(grid[0])
    colors = ["tab:blue", "tab:red"]
    for index, run in enumerate(runs):
        objective = run["config"]["optimization"]["objective"]
        label = "psi1 route (exact adjoint)" if objective == "psi1" else "psi2 route (ESL)"
        iterations = run["history"]["iteration"]
        psi1 = run["history"]["psi1"]
        color = colors[index % len(colors)]
        scenarios = run.get("scenarios")  # hindsight.read_results() has none without scenarios
        if scenarios is not None:
            names = [scenario["name"] for scenario in run["config"].get("scenarios", [])]
            for s, name in enumerate(names):
                axis.plot(iterations, scenarios[:, s], "-", marker=".",
                          label=f"{label}: psi1 of scenario {name}, final {scenarios[-1, s]:.4g}")
            # The history's psi1 is the worst scenario's (largest w_s psi_s / psi_s(x0)): ringed.
            axis.plot(iterations, psi1, "o", markerfacecolor="none", markeredgecolor="black",
                      label=f"{label}: the worst scenario of each iteration")
        else:
            axis.plot(iterations, psi1, "-", color=color, marker=".", label=f"{label}: psi1, final {psi1[-1]:.4f}")
        if objective == "psi2":
            axis.plot(iterations, run["history"]["psi2"], "--", color=color, label=f"{label}: psi2 (minimised)")
        if len(iterations) == 0:
            continue
        design_axis = fig.add_subplot(grid[1 + index])
        design = run["designs"][-1]
        design_axis.imshow(design, cmap="gray_r", vmin=0.0, vmax=1.0, origin="lower", aspect="equal",
                           interpolation="nearest")
        state = "final" if run["finished"] else "latest"
        design_axis.set_title(f"{label}: {state} design (iteration {int(iterations[-1])}), "
                              f"V/V0 = {run['history']['volume_fraction'][-1]:.3f}", fontsize=9)
        design_axis.set_xticks([])
        design_axis.set_yticks([])
    axis.set_xlabel("iteration")
    axis.set_ylabel(axis_label("psi1"))
    axis.set_title("Piston rod: integral compliance over the MMA iterations")
    axis.grid(True, alpha=0.3)
    # Logarithmic: the early transients of a run and the final factor between the routes both show.
    axis.set_yscale("log")
    axis.legend(fontsize=8)
    if out is not None:
        fig.savefig(out, dpi=120, bbox_inches="tight")
    return fig


def main():
    import matplotlib

    matplotlib.use("Agg")  # a file, no display; set here so that draw() leaves a notebook's backend alone
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("results", nargs="+", help="one or two results.h5 files")
    parser.add_argument("--out", required=True, help="PNG file to write")
    args = parser.parse_args()
    if len(args.results) > 2:
        parser.error("give one or two results files")
    runs = [load(path) for path in args.results]
    draw(runs, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
