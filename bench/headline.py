#!/usr/bin/python3
"""Reproduces every headline figure of the README on this machine and says which machine it was.

    /usr/bin/python3 bench/headline.py [--build DIR] [--out DIR] [--ensemble N] [--skip-esl]

Runs the built `hindsight` (default ./build/hindsight) with the default configuration:
  1. hindsight evaluate --json                    psi1(x0), psi2(x0), f1(x0)
  2. hindsight optimize                           the psi1 route (exact adjoint gradients): final and
                                                  best feasible psi1, V/V0, iterations, stop reason
  3. hindsight optimize --objective psi2          the paper's ESL route, and psi1 of its final design
  4. with --ensemble N: N more psi1 runs started from rod.initialDesign = 0.5 moved by
     -N/2 ... N/2 ulps (0 excluded): the spread of the final psi1 over starts that differ in the
     last bits, i.e. how much the answer depends on rounding.
CPU seconds (user + system of the child) and wall seconds of every run; the machine (CPU model and
the features glibc could dispatch on, glibc version, cores, load average before and after).

Which figures are bitwise: psi1(x0), psi2(x0), every final psi and V/V0 are the same bits on every
x86-64 machine (docs/guides/reproducibility.md); the seconds are this machine's. Before it runs, the script
reads the record kept in the repository (bench/results-headline/headline.json, made on the machine it
names) and every row of the table says whether this machine's run gave the record's bits: "yes", "no"
(with the record's value) or "not in the record"; nothing is claimed that was not compared. The first
line names this machine, its caches (the kernel's view, sysfs) and the record's machine. Writes
OUT/headline.json and prints a Markdown table.
"""
import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time

import h5py
import numpy as np

# The machine's caches as the reproducibility record describes them (one description for both records).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "tests", "reproducibility"))
from record import cache_sizes  # noqa: E402  (tests/reproducibility/record.py)


RECORD = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results-headline", "headline.json")


def same(recorded, *path_and_value):
    """'yes' when the record holds the value at path with the same bits, 'no (record: ...)' when it holds
    another, 'not in the record' when it holds none."""
    *path, value = path_and_value
    node = recorded
    for key in path:
        if not isinstance(node, dict) or key not in node:
            return "not in the record"
        node = node[key]
    return "yes" if json.dumps(node) == json.dumps(value) else f"no (record: {node!r})"


def machine():
    info = {"platform": platform.platform(), "cores": os.cpu_count(), "glibc": " ".join(platform.libc_ver()),
            "caches": cache_sizes()}
    try:
        with open("/proc/cpuinfo") as f:
            text = f.read()
        for line in text.splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
        flags = next((l.split(":", 1)[1].split() for l in text.splitlines() if l.startswith("flags")), [])
        info["features"] = " ".join(f for f in ("sse4_2", "avx", "fma", "avx2", "avx512f") if f in flags)
    except OSError:
        pass
    info["load_average_start"] = os.getloadavg()
    return info


def timed(command, log):
    """Runs command; returns (stdout, wall seconds, CPU seconds of the child)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    with open(log, "w") as out:
        result = subprocess.run(command, stdout=subprocess.PIPE, stderr=out, text=True)
    wall = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(log, "a") as out:
        out.write(result.stdout)
    if result.returncode != 0:
        sys.exit(f"{' '.join(command)} failed with exit {result.returncode}; see {log}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return result.stdout, wall, cpu


def history(results):
    with h5py.File(results, "r") as f:
        h = {name: np.asarray(f["history"][name][()]) for name in f["history"]}
        h["finished"] = int(f.attrs["finished"])
        h["designs"] = np.asarray(f["designs"][()])
        h["configuration"] = json.loads(f.attrs["configuration"])
    return h


def summarize(h):
    """Final and best feasible psi of a run (the best as hindsight defines it: optimization.volumeFraction
    with 1e-6 relative slack, problems/topopt/optimization_run.h)."""
    bound = h["configuration"]["optimization"]["volumeFraction"]
    objective = h["configuration"]["optimization"]["objective"]
    values = h["psi1"] if objective == "psi1" else h["psi2"]
    feasible = [k for k in range(len(values)) if h["volume_fraction"][k] <= bound * (1 + 1e-6)]
    best = min(feasible, key=lambda k: values[k]) if feasible else None
    kkt = h.get("kkt_residual")
    converged = bool(h["finished"]) and kkt is not None and not math.isnan(kkt[-1])
    last5 = values[-5:]
    return {
        "iterations": int(h["iteration"][-1]),
        "final_psi1": float(h["psi1"][-1]),
        "final_psi2": float(h["psi2"][-1]),
        "final_volume_fraction": float(h["volume_fraction"][-1]),
        "stop": "convergence rule" if converged else "iteration limit",
        "final_kkt_residual": float(kkt[-1]) if kkt is not None else None,
        "best_feasible_iteration": int(h["iteration"][best]) if best is not None else None,
        "best_feasible_psi": float(values[best]) if best is not None else None,
        "last_five_relative_change": float((last5.max() - last5.min()) / last5.min()),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default="build")
    parser.add_argument("--out", default=os.path.join("bench", "results-headline"))
    parser.add_argument("--ensemble", type=int, default=0, help="extra psi1 runs from perturbed starts")
    parser.add_argument("--skip-esl", action="store_true", help="leave out the psi2 (ESL) route")
    args = parser.parse_args()
    # The record is read before anything runs: the default --out writes over that very file.
    recorded = {}
    if os.path.isfile(RECORD):
        with open(RECORD) as f:
            recorded = json.load(f)
    hindsight = os.path.abspath(os.path.join(args.build, "hindsight"))
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    report = {"machine": machine()}
    version, _, _ = timed([hindsight, "--version"], os.path.join(out, "version.log"))
    report["version"] = version.strip()

    text, wall, cpu = timed([hindsight, "evaluate", "--json"], os.path.join(out, "evaluate.log"))
    x0 = json.loads(text)
    report["x0"] = {"psi1": x0["psi1"], "psi2": x0["psi2"], "first_frequency_hz": x0["frequencies_hz"][0],
                    "wall_seconds": wall, "cpu_seconds": cpu}

    _, wall, cpu = timed([hindsight, "optimize", "--force", "--out", os.path.join(out, "psi1")],
                         os.path.join(out, "psi1.log"))
    report["psi1_route"] = summarize(history(os.path.join(out, "psi1", "results.h5")))
    report["psi1_route"].update(wall_seconds=wall, cpu_seconds=cpu)

    if not args.skip_esl:
        _, wall, cpu = timed([hindsight, "optimize", "--objective", "psi2", "--force", "--out",
                              os.path.join(out, "psi2")], os.path.join(out, "psi2.log"))
        report["esl_route"] = summarize(history(os.path.join(out, "psi2", "results.h5")))
        report["esl_route"].update(wall_seconds=wall, cpu_seconds=cpu)
        report["esl_over_exact"] = report["esl_route"]["final_psi1"] / report["psi1_route"]["final_psi1"]

    if args.ensemble > 0:
        finals = [report["psi1_route"]["final_psi1"]]
        stops = [report["psi1_route"]["stop"]]
        iterations = [report["psi1_route"]["iterations"]]
        starts = []
        for k in range(-(args.ensemble // 2), args.ensemble - args.ensemble // 2 + 1):
            if k == 0:
                continue
            x = 0.5
            for _ in range(abs(k)):
                x = float(np.nextafter(x, 1.0 if k > 0 else 0.0))
            starts.append(x)
            if len(starts) == args.ensemble:
                break
        for i, x in enumerate(starts):
            directory = os.path.join(out, f"ensemble{i}")
            timed([hindsight, "optimize", "--force", "--out", directory, "--set", f"rod.initialDesign={x!r}"],
                  directory + ".log")
            member = summarize(history(os.path.join(directory, "results.h5")))
            finals.append(member["final_psi1"])
            stops.append(member["stop"])
            iterations.append(member["iterations"])
        report["ensemble"] = {"starts": [0.5] + starts, "final_psi1": finals, "stops": stops,
                              "iterations": iterations,
                              "relative_spread": (max(finals) - min(finals)) / min(finals)}

    report["machine"]["load_average_end"] = os.getloadavg()
    with open(os.path.join(out, "headline.json"), "w") as f:
        json.dump(report, f, indent=2)

    m = report["machine"]
    rm = recorded.get("machine", {})
    print(f"machine: {m.get('cpu', '?')} ({m.get('features', '')}), caches {m.get('caches')}, {m['cores']} cores, "
          f"{m['glibc']}, load {m['load_average_start'][0]:.1f} -> {m['load_average_end'][0]:.1f}; {report['version']}")
    print(f"record: {RECORD} made on {rm.get('cpu', '?')} ({rm.get('features', '')}), caches {rm.get('caches', '?')}"
          if recorded else f"record: none at {RECORD}; nothing compared")
    print("| figure | value | same bits as the record |")
    print("|---|---|---|")
    x0r = report["x0"]
    print(f"| psi1(x0), psi2(x0), f1(x0) | {x0r['psi1']!r}, {x0r['psi2']!r}, {x0r['first_frequency_hz']!r} Hz | "
          f"{same(recorded, 'x0', 'psi1', x0r['psi1'])}, {same(recorded, 'x0', 'psi2', x0r['psi2'])}, "
          f"{same(recorded, 'x0', 'first_frequency_hz', x0r['first_frequency_hz'])} |")
    r = report["psi1_route"]
    print(f"| psi1 route: final psi1, V/V0 | {r['final_psi1']!r}, {r['final_volume_fraction']!r} "
          f"({r['stop']} after {r['iterations']} iterations; best feasible psi1 {r['best_feasible_psi']:.6g} "
          f"at {r['best_feasible_iteration']}) | {same(recorded, 'psi1_route', 'final_psi1', r['final_psi1'])}, "
          f"{same(recorded, 'psi1_route', 'final_volume_fraction', r['final_volume_fraction'])}, iterations "
          f"{same(recorded, 'psi1_route', 'iterations', r['iterations'])} |")
    print(f"| psi1 route: change over the last five iterations | {r['last_five_relative_change']:.2e} (relative) | "
          f"{same(recorded, 'psi1_route', 'last_five_relative_change', r['last_five_relative_change'])} |")
    print(f"| psi1 route: time | {r['cpu_seconds']:.1f} s CPU, {r['wall_seconds']:.1f} s wall | "
          f"not compared (this machine's) |")
    if "esl_route" in report:
        e = report["esl_route"]
        print(f"| ESL route: psi1 of its final design, V/V0 | {e['final_psi1']!r}, {e['final_volume_fraction']!r} "
              f"({e['stop']} after {e['iterations']} iterations) | "
              f"{same(recorded, 'esl_route', 'final_psi1', e['final_psi1'])}, "
              f"{same(recorded, 'esl_route', 'final_volume_fraction', e['final_volume_fraction'])} |")
        print(f"| ratio ESL / exact | {report['esl_over_exact']:.3g} | "
              f"{same(recorded, 'esl_over_exact', report['esl_over_exact'])} |")
        print(f"| ESL route: time | {e['cpu_seconds']:.1f} s CPU, {e['wall_seconds']:.1f} s wall | "
              f"not compared (this machine's) |")
    if "ensemble" in report:
        en = report["ensemble"]
        stops = en["stops"]
        print(f"| final psi1 over {len(en['final_psi1'])} starts 0.5 +- ulps | "
              f"{min(en['final_psi1']):.6g} ... {max(en['final_psi1']):.6g} "
              f"(spread {100 * en['relative_spread']:.3g} %; {stops.count('convergence rule')} of {len(stops)} "
              f"stopped by the rule) | {same(recorded, 'ensemble', 'final_psi1', en['final_psi1'])} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
