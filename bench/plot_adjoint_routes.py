#!/usr/bin/python3
"""Accuracy against cost of the adjoint routes, from adjoint_routes_bench's JSON output.

Usage: /usr/bin/python3 bench/plot_adjoint_routes.py bench/adjoint_routes.json [bench/adjoint_routes.png] [--table]

Uses the median aggregates (run with --benchmark_repetitions=3). The PNG has one panel per problem:
gradient relative error (against the tight reference of the benchmark) over CPU time per gradient,
one line per route/variant through its tolerances. --table prints the medians as a Markdown table;
for CVODES it adds the backward right-hand sides (lambda'), the state VJPs, the nonlinear iterations
and the linear-solver setups (counters of bench::gradientWithCounters; "-" for the other routes).
"""
import collections
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def load(path):
    with open(path) as f:
        data = json.load(f)
    rows = []
    for b in data["benchmarks"]:
        if b.get("run_type") == "aggregate" and b.get("aggregate_name") != "median":
            continue
        name = b.get("run_name", b["name"]).replace("/min_time:0.050", "")
        problem, route, variant, rtol = name.split("/")
        rows.append(
            dict(
                problem=problem,
                route=route,
                variant=variant,
                rtol=float(rtol.split(":")[1]),
                real_ms=b["real_time"],
                cpu_ms=b["cpu_time"],
                error=b["gradient_error"],
                steps=int(b["steps"]),
                rhs=int(b["rhs_evals"]),
                jac=int(b["jac_evals"]),
                stored=int(b["stored"]),
                bwd_rhs=b.get("bwd_rhs"),
                vjps=b.get("vjps"),
                nl_iters=b.get("nl_iters"),
                setups=b.get("setups"),
            )
        )
    return data["context"], rows


def count(value):
    return "-" if value is None else str(int(value))


def table(rows):
    out = ["| problem | route | variant | rtol | gradient rel. error | CPU ms | wall ms | steps | F evals | F_z evals | "
           "stored | backward rhs | VJPs | nonlinear iters | setups |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(
            f"| {r['problem']} | {r['route']} | {r['variant']} | {r['rtol']:.0e} | {r['error']:.2e} | "
            f"{r['cpu_ms']:.3f} | {r['real_ms']:.3f} | {r['steps']} | {r['rhs']} | {r['jac']} | {r['stored']} | "
            f"{count(r['bwd_rhs'])} | {count(r['vjps'])} | {count(r['nl_iters'])} | {count(r['setups'])} |"
        )
    return "\n".join(out)


def plot(rows, path):
    problems = sorted({r["problem"] for r in rows}, reverse=False)
    fig, axes = plt.subplots(1, len(problems), figsize=(7 * len(problems), 5.5))
    if len(problems) == 1:
        axes = [axes]
    for ax, problem in zip(axes, problems):
        lines = collections.OrderedDict()
        for r in rows:
            if r["problem"] == problem:
                lines.setdefault(f"{r['route']} {r['variant']}", []).append(r)
        for i, (label, points) in enumerate(lines.items()):
            points.sort(key=lambda r: -r["rtol"])
            style = "-o" if "cvodes" not in label else ("--s" if "adams" in label else ":^")
            ax.loglog([p["cpu_ms"] for p in points], [p["error"] for p in points], style, label=label, ms=4,
                      color=plt.cm.tab20(i % 20))
        ax.set_xlabel("CPU time per gradient [ms] (median of 3)")
        ax.set_ylabel("gradient relative error vs tight reference")
        ax.set_title(f"{problem}: accuracy against cost (points: rtol from loose to tight)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if not args:
        print(__doc__)
        return 2
    context, rows = load(args[0])
    plot(rows, args[1] if len(args) > 1 else "bench/adjoint_routes.png")
    if "--table" in sys.argv:
        print(f"machine: {context.get('num_cpus')} CPUs at {context.get('mhz_per_cpu')} MHz, "
              f"load average {context.get('load_avg')}")
        print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
