#!/usr/bin/python3
"""Runs the hindsight benchmark suite and collects every figure into one JSON file, markdown tables
and PNG plots.

    /usr/bin/python3 bench/run_suite.py quick|full [--out DIR] [--build DIR] [--only REGEX] [--repetitions N]
    /usr/bin/python3 bench/run_suite.py report --out DIR   (tables and plots again from DIR/suite.json)

quick: the full-order rod at 100x6 (7 strategies, 100 TR-BDF2 steps); rod_bench: meshes 100x6 and
       200x12 (paper route at 200x12: 1 repetition), six storage strategies on the 20-mode rod with
       T = 3 s, the peers at rtol 1e-6 (CVODES Nd = 100 only); 3 repetitions. Under 5 min on 2 cores
       (bench/RESULTS.md gives the measured duration).
full:  rod_bench: meshes 100x6 ... 1600x96 (the paper's route up to 400x24, minutes per gradient, 1
       repetition); 14 strategies on m20/T3, m20/T10 (10^5 steps) and m20/T30 (3e5 steps), one per
       family on m20/T100 (10^6 steps) and m40/T10 (h = 5e-5); the peers at rtol 1e-4, 1e-6, 1e-8 with
       Nd 10/100/1000. full_order_bench: 7 strategies on the full-order rod 100x6 ... 800x48.
       optimize_bench: the 50-iteration optimisation, both routes. Then the colleagues' benches
       (storage_bench, disk_bench, adjoint_routes_bench, engine_bench). About 145 min of CPU; 80 min
       on 2 cores when run as parts side by side (bench/RESULTS.md gives the commands and durations):
         run_suite.py full --out A --only '^rod_bench (?!.*(400x24/gradient-nelson|1600x96|T100|m40))'
         run_suite.py full --out B --only '400x24/gradient-nelson|^(?!rod_bench)'
         ... then the rest (1600x96, m20/T100, m40/T10) the same way, and
         run_suite.py merge --out DIR A B ...

Outputs in DIR (default bench/results-MODE): suite.json (median, min, max per benchmark and counter;
machine info, nproc, load average at start and end, git commit; the exact commands), the raw Google
Benchmark JSON per run (raw-*.json), RESULTS.generated.md (summary table of headline ratios first,
then details) and the plots storage_tradeoff.png, routes_error_vs_time.png, design_scaling.png.
Needs numpy-free Python 3 and matplotlib (Debian's /usr/bin/python3 has it).
"""
import argparse
import datetime
import json
import math
import os
import platform
import re
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (binary, filter, repetitions). Filters are Google Benchmark regular expressions.
QUICK = [
    ("full_order_bench", r"^full_order/100x6/", 3),
    ("rod_bench", r"^rod_design/100x6/", 3),
    ("rod_bench", r"^rod_design/200x12/(forward|gradient-adjoint-nelson)/", 3),
    ("rod_bench", r"^rod_design/200x12/gradient-nelson/", 1),
    ("rod_bench", r"^rod_storage/m20/T3/(forward|full|binomial:checkpoints=100|online:checkpoints=100|disk:.*"
                  r"|hermite:every=4|lossy:codec=round,tolerance=1e-6)/", 3),
    ("rod_bench", r"^rod_routes/(forward/(rk4|trbdf2|dopri5/rtol:1e-06)|discrete-(rk4|trbdf2)/"
                  r"|(discrete|continuous)-dopri5/full/rtol:1e-06|cvodes-(adams|bdf)/hermite-Nd100/rtol:1e-06)", 3),
]
FULL = [
    ("rod_bench", r"^rod_design/(100x6|200x12)/(forward|gradient-adjoint-nelson)/", 5),
    ("rod_bench", r"^rod_design/(400x24|800x48)/(forward|gradient-adjoint-nelson)/", 3),
    ("rod_bench", r"^rod_design/(100x6|200x12)/gradient-nelson/", 3),
    ("rod_bench", r"^rod_design/400x24/gradient-nelson/", 1),
    ("rod_bench", r"^rod_design/1600x96/(forward|gradient-adjoint-nelson)/", 1),
    ("rod_bench", r"^rod_storage/m20/T3/", 3),
    ("rod_bench", r"^rod_storage/m20/T10/", 1),
    ("rod_bench", r"^rod_storage/m20/T30/", 1),
    ("rod_bench", r"^rod_storage/m20/T100/", 3),
    ("rod_bench", r"^rod_storage/m40/T10/", 3),
    ("rod_bench", r"^rod_routes/(forward/(rk4|trbdf2)|discrete-(rk4|trbdf2)/|.*/rtol:1e-06/)", 3),
    ("rod_bench", r"^rod_routes/.*/rtol:1e-0[48]/", 1),
    ("full_order_bench", r"^full_order/(100x6|200x12)/", 3),
    ("full_order_bench", r"^full_order/(400x24|800x48)/", 1),
    ("optimize_bench", r".", 3),
    ("storage_bench", r".", 3),
    ("disk_bench", r".", 3),
    ("adjoint_routes_bench", r".", 3),
    ("engine_bench", r".", 3),
]

STANDARD_KEYS = {
    "name", "run_name", "run_type", "family_index", "per_family_instance_index", "repetitions",
    "repetition_index", "threads", "iterations", "real_time", "cpu_time", "time_unit",
    "aggregate_name", "aggregate_unit", "error_occurred", "error_message", "label",
}
UNIT_MS = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}


def sh(cmd):
    try:
        return subprocess.run(cmd, shell=True, capture_output=True, text=True, cwd=ROOT).stdout.strip()
    except OSError:
        return ""


def machine_info():
    cpu = ""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem = ""
    try:
        with open("/proc/meminfo") as f:
            mem = f.readline().split(":", 1)[1].strip()
    except OSError:
        pass
    return {"nproc": int(sh("nproc") or os.cpu_count() or 0), "cpu": cpu, "memory": mem,
            "uname": " ".join(platform.uname()), "compiler": sh("c++ --version | head -1"),
            "benchmark_library": sh("dpkg-query -W -f '${Version}' libbenchmark-dev 2>/dev/null")}


def load_average():
    return list(os.getloadavg())


def stats(values):
    values = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    if not values:
        return None
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "n": len(values)}


def run_binary(build, binary, bench_filter, repetitions, out_dir, index):
    exe = os.path.join(build, "bench", binary)
    raw = os.path.join(out_dir, "raw-%02d-%s.json" % (index, binary))
    cmd = [exe, "--benchmark_filter=" + bench_filter, "--benchmark_repetitions=%d" % repetitions,
           "--benchmark_out=" + raw, "--benchmark_out_format=json"]
    printable = " ".join(cmd[:1] + ["'%s'" % cmd[1]] + cmd[2:])
    print("+ " + printable, flush=True)
    start = time.time()
    load_start = load_average()
    proc = subprocess.run(cmd, cwd=ROOT)
    seconds = time.time() - start
    entry = {"binary": binary, "filter": bench_filter, "repetitions": repetitions, "command": printable,
             "seconds": seconds, "returncode": proc.returncode, "load_start": load_start,
             "load_end": load_average(), "raw": os.path.basename(raw)}
    runs = []
    if os.path.exists(raw):
        with open(raw) as f:
            data = json.load(f)
        runs = data.get("benchmarks", [])
        entry["context"] = data.get("context", {})
    return entry, runs


def collect(runs, binary, results):
    grouped = {}
    for r in runs:
        if r.get("run_type", "iteration") != "iteration":
            continue
        name = re.sub(r"/iterations:\d+$", "", r.get("run_name", r["name"]))
        grouped.setdefault(name, []).append(r)
    for name, reps in grouped.items():
        scale = UNIT_MS.get(reps[0].get("time_unit", "ns"), 1e-6)
        errors = [r.get("error_message", "") for r in reps if r.get("error_occurred")]
        ok = [r for r in reps if not r.get("error_occurred")]
        counters = {}
        for key in ok[0].keys() if ok else []:
            if key in STANDARD_KEYS or not isinstance(ok[0][key], (int, float)):
                continue
            counters[key] = stats([r.get(key) for r in ok])
        results[name] = {
            "binary": binary,
            "repetitions": len(ok),
            "real_time_ms": stats([r["real_time"] * scale for r in ok]),
            "cpu_time_ms": stats([r["cpu_time"] * scale for r in ok]),
            "counters": counters,
            "errors": errors,
        }


# ----------------------------------------------------------------------------------------------------
# Tables and plots


def med(results, name, key="cpu_time_ms"):
    b = results.get(name)
    if not b:
        return None
    if key in ("cpu_time_ms", "real_time_ms"):
        s = b.get(key)
    else:
        s = b["counters"].get(key)
    return s["median"] if s else None


def ratio(a, b):
    return a / b if a is not None and b not in (None, 0) else None


def fmt(v, digits=3):
    if v is None:
        return "—"
    if isinstance(v, str):
        return v
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 1e5 or a < 1e-3:
        return "%.2e" % v
    if a >= 100:
        return "%.0f" % v
    return ("%%.%dg" % digits) % v


def mb(v):
    return None if v is None else v / 1e6


def design_rows(results):
    rows = []
    for mesh in ["100x6", "200x12", "400x24", "800x48", "1600x96"]:
        f = "rod_design/%s/forward" % mesh
        a = "rod_design/%s/gradient-adjoint-nelson" % mesh
        n = "rod_design/%s/gradient-nelson" % mesh
        if f not in results:
            continue
        rows.append({
            "mesh": mesh,
            "designs": med(results, f, "designs"),
            "fwd_cpu": med(results, f), "fwd_wall": med(results, f, "real_time_ms"),
            "an_cpu": med(results, a), "an_wall": med(results, a, "real_time_ms"),
            "n_cpu": med(results, n), "n_wall": med(results, n, "real_time_ms"),
            "n_reps": results[n]["repetitions"] if n in results else 0,
            "an_chain": med(results, a, "chain_s"), "n_chain": med(results, n, "chain_s"),
            "model": med(results, f, "model_s"), "sim_f": med(results, f, "simulation_s"),
            "sim_a": med(results, a, "simulation_s"),
            "diff": med(results, n, "grad_rel_diff"),
        })
    return rows


def storage_groups(results):
    """{"m20/T3": [specs...], ...} in the order of modes, then horizon (dicts keep insertion order)."""
    groups = {}
    for name in results:
        m = re.match(r"^rod_storage/(m\d+/T\d+)/(.*)$", name)
        if m:
            groups.setdefault(m.group(1), []).append(m.group(2))
    order = lambda key: tuple(int(x) for x in re.findall(r"\d+", key))
    return {key: groups[key] for key in sorted(groups, key=order)}


def rss_growth(results, name):
    """Peak resident set over a benchmark minus the resident set at its start [MB] (None if unknown)."""
    base, peak = med(results, name, "rss_base"), med(results, name, "rss_peak")
    if base is None or peak is None or base < 0 or peak < 0:
        return None
    return (peak - base) / 1e6


def strategy_table(results, prefix, specs, directory):
    """Markdown rows of one storage trade-off group: PREFIXforward is the baseline, PREFIXspec per strategy;
    the scratch directory in the specs is printed as D."""
    fwd = prefix + "forward"
    base = med(results, fwd)
    rows = ["| strategy | CPU ms | wall ms | grad/fwd CPU | recomputed | ratio to revolve | peak MB | "
            "RSS growth MB | disk MB | compression | I/O s | rel. gradient error |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
            "| forward only (baseline) | %s | %s | 1 | — | — | — | %s | — | — | — | — |" % (
                fmt(base), fmt(med(results, fwd, "real_time_ms")), fmt(rss_growth(results, fwd)))]
    for spec in specs:
        name = prefix + spec
        if results[name]["errors"] and not results[name]["repetitions"]:
            rows.append("| %s | error: %s |" % (spec, results[name]["errors"][0]))
            continue
        rows.append("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            spec.replace(directory, "D"), fmt(med(results, name)), fmt(med(results, name, "real_time_ms")),
            fmt(ratio(med(results, name), base)), fmt(med(results, name, "recomputed")),
            fmt(med(results, name, "ratio_to_revolve"), 4), fmt(mb(med(results, name, "peak_bytes"))),
            fmt(rss_growth(results, name)), fmt(mb(med(results, name, "disk_bytes"))),
            fmt(med(results, name, "compression")), fmt(med(results, name, "io_s")),
            fmt(med(results, name, "grad_rel_err"))))
    return rows


def full_order_groups(results):
    groups = {}
    for name in results:
        m = re.match(r"^full_order/(\d+x\d+)/(.*)$", name)
        if m and m.group(2) != "forward":
            groups.setdefault(m.group(1), []).append(m.group(2))
    return sorted(groups.items(), key=lambda kv: int(kv[0].split("x")[0]))


def route_rows(results):
    rows = []
    for name in results:
        m = re.match(r"^rod_routes/([^/]+)/([^/]+)/(.*)$", name)
        if not m or m.group(1) == "forward":
            continue
        route, variant, tol = m.groups()
        if "dopri5" in route or "cvodes" in route:
            base = "rod_routes/forward/dopri5/" + tol
        else:
            base = "rod_routes/forward/%s/%s" % (route.split("-")[1], tol)
        rows.append({"name": name, "route": route, "variant": variant, "tol": tol,
                     "cpu": med(results, name), "wall": med(results, name, "real_time_ms"),
                     "base": med(results, base), "err": med(results, name, "grad_rel_err"),
                     "steps": med(results, name, "steps"), "rhs": med(results, name, "rhs_evals"),
                     "jac": med(results, name, "jac_evals"), "stored": med(results, name, "stored"),
                     "recomputed": med(results, name, "recomputed")})
    rows.sort(key=lambda r: (r["tol"], r["route"], r["variant"]))
    return rows


def markdown(suite):
    results = suite["benchmarks"]
    out = []
    m = suite["machine"]
    out.append("# Benchmark suite results (`bench/run_suite.py %s`)\n" % suite["mode"])
    out.append("Machine: %d cores (%s), %s; load average at start %s, at end %s. git %s%s. Started %s UTC, "
               "duration %.0f s. Times are medians over the repetitions (min–max in suite.json); CPU time is "
               "the benchmark thread's (the disk strategy's I/O thread is in `io_s`).\n" % (
                   m["nproc"], m["cpu"], m["memory"],
                   "/".join("%.2f" % x for x in suite["load_start"]),
                   "/".join("%.2f" % x for x in suite["load_end"]), ", ".join(sorted(set(c[:10] for c in suite["git"]["commit"].split(" + ")))),
                   " (dirty)" if suite["git"]["dirty"] else "", suite["started"], suite["duration_s"]))
    out.append("Commands:\n")
    out.append("```")
    for r in suite["runs"]:
        out.append("%s   # %.0f s" % (r["command"], r["seconds"]))
    out.append("```\n")
    if suite.get("replaced"):
        by = sorted({r["by"] for r in suite["replaced"]})
        out.append("%d benchmarks of earlier parts were replaced by the later part(s) %s (merge --replace).\n" % (
            len(suite["replaced"]), ", ".join(by)))

    # ------------------------------------------------------------------ summary
    out.append("## Summary: headline ratios (CPU-time medians)\n")
    out.append("| headline | configuration | value |")
    out.append("|---|---|---:|")
    for key, names in storage_groups(results).items():
        base = med(results, "rod_storage/%s/forward" % key)
        for spec in ["full", "binomial:checkpoints=100", "online:checkpoints=100", "disk:dir=/tmp/hindsight-rod-bench",
                     "hermite:every=4", "lossy:codec=round,tolerance=1e-6"]:
            name = "rod_storage/%s/%s" % (key, spec)
            if name in results:
                out.append("| gradient / forward, rk4, %s | rod %s, 200x12 | %s |" % (
                    spec.split(":dir=")[0], key, fmt(ratio(med(results, name), base))))
    for fwd, grad, label in [("rod_routes/forward/rk4/h:1e-4", "rod_routes/discrete-rk4/full/h:1e-4", "rk4 h=1e-4"),
                             ("rod_routes/forward/trbdf2/h:1e-4", "rod_routes/discrete-trbdf2/full/h:1e-4", "trbdf2 h=1e-4"),
                             ("rod_routes/forward/dopri5/rtol:1e-06", "rod_routes/discrete-dopri5/full/rtol:1e-06", "dopri5 rtol=1e-6")]:
        if grad in results:
            out.append("| gradient / forward, discrete adjoint, %s, full | rod m10/T3 | %s |" % (
                label, fmt(ratio(med(results, grad), med(results, fwd)))))
    for route in ["continuous-dopri5/full", "cvodes-adams/hermite-Nd100", "cvodes-bdf/hermite-Nd100"]:
        name = "rod_routes/%s/rtol:1e-06" % route
        if name in results:
            out.append("| gradient / forward dopri5 rtol=1e-6, %s (error %s) | rod m10/T3 | %s |" % (
                route, fmt(med(results, name, "grad_rel_err")),
                fmt(ratio(med(results, name), med(results, "rod_routes/forward/dopri5/rtol:1e-06")))))
    for key in storage_groups(results):
        for spec in ["binomial:checkpoints=10", "binomial:checkpoints=100", "online:checkpoints=100",
                     "online:checkpoints=1000"]:
            name = "rod_storage/%s/%s" % (key, spec)
            if name in results:
                out.append("| forward steps / revolve optimum, %s | rod %s | %s |" % (
                    spec, key, fmt(med(results, name, "ratio_to_revolve"), 4)))
        d = "rod_storage/%s/disk:dir=/tmp/hindsight-rod-bench" % key
        f = "rod_storage/%s/full" % key
        if d in results:
            out.append("| disk / full, CPU (wall) | rod %s | %s (%s) |" % (
                key, fmt(ratio(med(results, d), med(results, f))),
                fmt(ratio(med(results, d, "real_time_ms"), med(results, f, "real_time_ms")))))
            out.append("| disk compression ratio (shuffle + zstd) | rod %s | %s |" % (
                key, fmt(med(results, d, "compression"))))
    for r in design_rows(results):
        if r["n_cpu"] is not None:
            out.append("| paper route / hindsight, gradient CPU (chain only) | %s, %d designs%s | %s (%s) |" % (
                r["mesh"], r["designs"], ", 1 rep." if r["n_reps"] == 1 else "",
                fmt(ratio(r["n_cpu"], r["an_cpu"])), fmt(ratio(r["n_chain"], r["an_chain"]))))
    for mesh, specs in full_order_groups(results):
        f, b = "full_order/%s/full" % mesh, "full_order/%s/binomial:checkpoints=10" % mesh
        if f in results and b in results:
            out.append("| full-order rod: binomial c=10 / full, CPU; storage peak MB (binomial vs full) | %s, %s "
                       "steps | %s; %s vs %s |" % (
                           mesh, fmt(med(results, f, "steps")), fmt(ratio(med(results, b), med(results, f))),
                           fmt(mb(med(results, b, "peak_bytes"))), fmt(mb(med(results, f, "peak_bytes")))))
    if "rod_optimize/psi1" in results and "rod_optimize/psi2" in results:
        p1, p2 = "rod_optimize/psi1", "rod_optimize/psi2"
        out.append("| 50-iteration optimisation, wall s: ψ1 route / ESL route | 200x12 defaults | %s / %s |" % (
            fmt(med(results, p1, "real_time_ms") / 1e3), fmt(med(results, p2, "real_time_ms") / 1e3)))
        out.append("| ψ1 of the final design: ESL route / ψ1 route (paper 3.3) | 200x12 defaults | %s (%s vs %s) |" % (
            fmt(ratio(med(results, p2, "psi1_final"), med(results, p1, "psi1_final"))),
            fmt(med(results, p2, "psi1_final"), 4), fmt(med(results, p1, "psi1_final"), 4)))
    for r in design_rows(results):
        out.append("| gradient / forward, adjoint Nelson | %s, %d designs | %s%s |" % (
            r["mesh"], r["designs"], fmt(ratio(r["an_cpu"], r["fwd_cpu"])),
            "" if r["n_cpu"] is None else " (paper route: %s)" % fmt(ratio(r["n_cpu"], r["fwd_cpu"]))))
    out.append("")

    # ------------------------------------------------------------------ design
    rows = design_rows(results)
    if rows:
        out.append("## Gradient cost against the mesh (`rod_design`)\n")
        out.append("PistonRod::evaluate at the uniform design x0 = 0.5, 10 modes, rk4 h = 1e-4, T = 3 s, full "
                   "storage; forward = FE model + modes + invariants + simulation; gradient adds the discrete "
                   "adjoint and the chain to dψ1/dx (adjoint Nelson: one solve per mode; paper: Nelson, one "
                   "solve per mode and design variable). ms are medians.\n")
        out.append("| mesh | designs | forward CPU ms (wall) | gradient adj.-Nelson CPU ms (wall) | grad/fwd | "
                   "gradient paper CPU ms (wall) | paper grad/fwd | paper / hindsight | model s | chain s adj.-Nelson | "
                   "chain s paper | ‖Δ‖/‖g‖ paper vs hindsight |")
        out.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            out.append("| %s | %d | %s (%s) | %s (%s) | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                r["mesh"], r["designs"], fmt(r["fwd_cpu"]), fmt(r["fwd_wall"]), fmt(r["an_cpu"]), fmt(r["an_wall"]),
                fmt(ratio(r["an_cpu"], r["fwd_cpu"])),
                "—" if r["n_cpu"] is None else "%s (%s)%s" % (fmt(r["n_cpu"]), fmt(r["n_wall"]),
                                                            " 1 rep." if r["n_reps"] == 1 else ""),
                fmt(ratio(r["n_cpu"], r["fwd_cpu"])), fmt(ratio(r["n_cpu"], r["an_cpu"])), fmt(r["model"]),
                fmt(r["an_chain"]), fmt(r["n_chain"]), fmt(r["diff"])))
        out.append("")

    # ------------------------------------------------------------------ storage
    for key, specs in storage_groups(results).items():
        fwd = "rod_storage/%s/forward" % key
        out.append("## Storage trade-offs, rod %s (`rod_storage`)\n" % key)
        out.append("Slider-crank with the invariants of the 200x12 initial design, %s modes, T = %s s, rk4 "
                   "h = 1e-4 (%s steps, %s bytes per state). One gradient dψ1/dp per repetition; error "
                   "against full storage of the same run. ratio = (N − 1 + recomputed) / T(N, c) (revolve "
                   "optimum; N − 1 for strategies without a schedule).\n" % (
                       key.split("/")[0][1:], key.split("/")[1][1:], fmt(med(results, fwd, "steps")),
                       fmt(med(results, fwd, "state_bytes"))))
        out.extend(strategy_table(results, "rod_storage/%s/" % key, [x for x in specs if x != "forward"],
                                  "/tmp/hindsight-rod-bench"))
        out.append("")

    # ------------------------------------------------------------------ full-order rod
    for mesh, specs in full_order_groups(results):
        fwd = "full_order/%s/forward" % mesh
        out.append("## Storage trade-offs, full-order rod %s (`full_order_bench`)\n" % mesh)
        out.append("Unreduced FE model of x0 = 0.5 (docs/design.md §9), state %s doubles (%s kB), TR-BDF2 h = 1e-3, "
                   "%s steps (crank at full speed after 50 ms); full storage for the paper's T = 3 s would hold "
                   "%s MB. One gradient dψ1,full/dx per repetition (%s); error against `full`. RSS growth = "
                   "peak resident set over the benchmark minus the resident set at its start.\n" % (
                       fmt(med(results, fwd, "state_bytes") / 8), fmt(med(results, fwd, "state_bytes") / 1e3),
                       fmt(med(results, fwd, "steps")), fmt(mb(med(results, fwd, "full_bytes_T3"))),
                       "%d repetitions" % results[fwd]["repetitions"] if results[fwd]["repetitions"] > 1
                       else "1 repetition"))
        out.extend(strategy_table(results, "full_order/%s/" % mesh, specs, "/tmp/hindsight-full-order-bench"))
        out.append("")

    # ------------------------------------------------------------------ optimisation
    opt = [n for n in ("rod_optimize/psi1", "rod_optimize/psi2") if n in results]
    if opt:
        out.append("## The 50-iteration optimisation end to end (`optimize_bench`)\n")
        out.append("`hindsight optimize` on the default configuration (200x12, 10 modes, rk4 h = 1e-4, T = 3 s, "
                   "MMA move limit 0.5, V/V0 ≤ 0.5), results.h5 rewritten after every iteration. psi1: exact "
                   "gradients (discrete adjoint + adjoint Nelson); psi2: equivalent static loads. Seconds are "
                   "medians (min–max) over the repetitions; ψ1 of the final design is the paper's comparison.\n")
        out.append("| route | reps | wall s | CPU s | evaluations | ψ1 initial | ψ1 final | ψ2 final | V/V0 | "
                   "backtracks | evaluation s | MMA s |")
        out.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for name in opt:
            b = results[name]
            w = b["real_time_ms"]
            out.append("| %s | %d | %s (%s–%s) | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                name.split("/")[1], b["repetitions"], fmt(w["median"] / 1e3), fmt(w["min"] / 1e3),
                fmt(w["max"] / 1e3), fmt(med(results, name) / 1e3), fmt(med(results, name, "evaluations")),
                fmt(med(results, name, "psi1_initial"), 5), fmt(med(results, name, "psi1_final"), 4),
                fmt(med(results, name, "psi2_final"), 4), fmt(med(results, name, "volume_final"), 3),
                fmt(med(results, name, "backtracks")), fmt(med(results, name, "evaluation_s")),
                fmt(med(results, name, "mma_s"))))
        if len(opt) == 2:
            out.append("\nψ1 of the ESL design / ψ1 of the ψ1 design: %s (paper: 3.3); wall time ψ1 route / ESL "
                       "route: %s (paper: two days / 1.5 h = 32).\n" % (
                           fmt(ratio(med(results, opt[1], "psi1_final"), med(results, opt[0], "psi1_final"))),
                           fmt(ratio(med(results, opt[0], "real_time_ms"), med(results, opt[1], "real_time_ms")))))
        out.append("")

    # ------------------------------------------------------------------ routes
    rows = route_rows(results)
    if rows:
        out.append("## Peers on the same rod problem (`rod_routes`)\n")
        out.append("200x12, 10 modes, T = 3 s. Error: ‖g − g_ref‖/‖g_ref‖ of dψ1/dp against the discrete adjoint "
                   "of rk4 at h = 2e-5 (computed once, untimed). dopri5/CVODES: atol = rtol·1e-4. grad/fwd: "
                   "CPU over the forward sweep of the same integrator and tolerance (CVODES and continuous: over "
                   "forward dopri5).\n")
        out.append("| route | variant | tol | rel. gradient error | CPU ms | wall ms | grad/fwd CPU | steps | F evals | "
                   "F_z evals | stored | recomputed |")
        out.append("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            out.append("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                r["route"], r["variant"], r["tol"], fmt(r["err"]), fmt(r["cpu"]), fmt(r["wall"]),
                fmt(ratio(r["cpu"], r["base"])), fmt(r["steps"]), fmt(r["rhs"]), fmt(r["jac"]), fmt(r["stored"]),
                fmt(r["recomputed"])))
        out.append("")
        out.append("Forward baselines:\n")
        out.append("| forward | CPU ms | wall ms | steps |")
        out.append("|---|---:|---:|---:|")
        for name in sorted(results):
            if name.startswith("rod_routes/forward/"):
                out.append("| %s | %s | %s | %s |" % (name[len("rod_routes/forward/"):], fmt(med(results, name)),
                                                     fmt(med(results, name, "real_time_ms")),
                                                     fmt(med(results, name, "steps"))))
        out.append("")

    # ------------------------------------------------------------------ other binaries
    others = sorted(n for n in results
                    if results[n]["binary"] not in ("rod_bench", "full_order_bench", "optimize_bench"))
    if others:
        out.append("## Other benchmarks (medians)\n")
        out.append("| benchmark | CPU ms | wall ms | counters (median) |")
        out.append("|---|---:|---:|---|")
        for name in others:
            c = ", ".join("%s=%s" % (k, fmt(v["median"])) for k, v in results[name]["counters"].items() if v)
            out.append("| %s | %s | %s | %s |" % (name, fmt(med(results, name)), fmt(med(results, name, "real_time_ms")), c))
        out.append("")

    errors = [(n, b["errors"]) for n, b in results.items() if b["errors"]]
    if errors:
        out.append("## Errors\n")
        for n, e in errors:
            out.append("- %s: %s" % (n, e[0]))
        out.append("")
    return "\n".join(out)


def save(plt, fig, out_dir, name, dpi):
    """Lays out, writes DIR/name and closes one figure; returns its path."""
    fig.tight_layout()
    path = os.path.join(out_dir, name)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def plots(suite, out_dir):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib missing: no plots (use /usr/bin/python3)", file=sys.stderr)
        return []
    results = suite["benchmarks"]
    made = []
    # Time vs memory per strategy: one panel per reduced-rod horizon and per full-order mesh.
    panels = [("rod_storage/%s/" % key, [x for x in specs if x != "forward"], "reduced rod " + key)
              for key, specs in storage_groups(results).items()]
    panels += [("full_order/%s/" % mesh, specs, "full-order rod " + mesh) for mesh, specs in full_order_groups(results)]
    if panels:
        columns = min(3, len(panels))
        rows_ = (len(panels) + columns - 1) // columns
        fig, axes = plt.subplots(rows_, columns, figsize=(6.5 * columns, 5 * rows_), squeeze=False)
        markers = dict(full="s", binomial="o", online="^", disk="D", multilevel="P", hermite="v", lossy="*")
        for ax, (prefix, specs, title) in zip(axes.flat, panels):
            base = med(results, prefix + "forward")
            families = {}
            for spec in specs:
                t, peak = med(results, prefix + spec), med(results, prefix + spec, "peak_bytes")
                if t is None or peak is None:
                    continue
                families.setdefault(spec.split(":")[0], []).append((peak / 1e6, t / base if base else t, spec))
            for fam, pts in sorted(families.items()):
                ax.scatter([p[0] for p in pts], [p[1] for p in pts], marker=markers.get(fam, "x"), s=60, label=fam)
                for x, y, spec in pts:
                    label = spec.split(":", 1)[1] if ":" in spec else spec
                    label = re.sub(r"dir=/tmp/[^,]*", "", label).replace("checkpoints=", "c=").strip(",")
                    ax.annotate(label or fam, (x, y), fontsize=7, xytext=(4, 3), textcoords="offset points")
            ax.set_xscale("log")
            ax.set_xlabel("peak bytes held in memory by the storage [MB]")
            ax.set_ylabel("gradient CPU time / forward CPU time")
            ax.set_title("%s: time vs memory" % title)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        for ax in list(axes.flat)[len(panels):]:
            ax.set_visible(False)
        fig.suptitle("hindsight storage strategies, CPU-time medians (%d cores, load %.1f)" % (
            suite["machine"]["nproc"], suite["load_start"][0]))
        made.append(save(plt, fig, out_dir, "storage_tradeoff.png", 100))
    # Error vs time per route.
    rows = route_rows(results)
    if rows:
        fig, ax = plt.subplots(figsize=(8.5, 6))
        families = {}
        for r in rows:
            if r["err"] is None or r["cpu"] is None:
                continue
            fam = r["route"] + ("" if "cvodes" not in r["route"] else "/" + r["variant"].split("-")[0])
            families.setdefault(fam, []).append(r)
        for fam, rs in sorted(families.items()):
            ax.scatter([r["cpu"] for r in rs], [max(r["err"], 1e-16) for r in rs], label=fam, s=40,
                       marker="o" if "cvodes" in fam else ("s" if "discrete" in fam else "^"))
            for r in rs:
                if "cvodes" not in fam or r["variant"].endswith("Nd100"):
                    ax.annotate(r["tol"].replace("rtol:", "") + ("" if "cvodes" not in fam else " Nd100"),
                                (r["cpu"], max(r["err"], 1e-16)), fontsize=6, xytext=(3, 2), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU time per gradient [ms] (median)")
        ax.set_ylabel("relative gradient error vs rk4 h=2e-5 discrete reference")
        ax.set_title("rod 200x12, 10 modes, T = 3 s: error vs time per adjoint route")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        made.append(save(plt, fig, out_dir, "routes_error_vs_time.png", 110))
    # Gradient / forward vs design count.
    rows = design_rows(results)
    if rows:
        fig, ax = plt.subplots(figsize=(7.5, 5))
        xs = [r["designs"] for r in rows]
        ax.plot(xs, [ratio(r["an_cpu"], r["fwd_cpu"]) for r in rows], "o-", label="hindsight (adjoint Nelson)")
        pr = [(r["designs"], ratio(r["n_cpu"], r["fwd_cpu"])) for r in rows if r["n_cpu"] is not None]
        if pr:
            ax.plot([p[0] for p in pr], [p[1] for p in pr], "s--", label="paper route (Nelson per design variable)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        for r in rows:
            ax.annotate(r["mesh"], (r["designs"], ratio(r["an_cpu"], r["fwd_cpu"])), fontsize=8,
                        xytext=(4, -10), textcoords="offset points")
        ax.set_xlabel("number of design variables")
        ax.set_ylabel("gradient CPU time / forward CPU time")
        ax.set_title("piston rod, 10 modes, T = 3 s: gradient cost vs design count")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        made.append(save(plt, fig, out_dir, "design_scaling.png", 110))
    return made


def merge_parts(dirs, replace=False):
    """One suite from parts run at the same time (each on its own core) or one after the other: runs are
    concatenated with the part they came from, benchmarks united (a name in two parts is an error, or with
    `replace` the later part's entry wins and is listed under "replaced"), the
    load averages are the extremes over the parts and the duration is the span from first start to last end."""
    if not dirs:
        sys.exit("merge needs the part directories")
    parts = []
    for d in dirs:
        with open(os.path.join(d, "suite.json")) as f:
            parts.append(json.load(f))
    suite = {"mode": "merged: " + ", ".join(p["mode"] for p in parts), "parts": [], "machine": parts[0]["machine"],
             "git": parts[0]["git"], "runs": [], "benchmarks": {}}
    starts, ends = [], []
    for d, p in zip(dirs, parts):
        start = datetime.datetime.strptime(p["started"], "%Y-%m-%d %H:%M:%S")
        starts.append(start)
        ends.append(start + datetime.timedelta(seconds=p["duration_s"]))
        suite["parts"].append({"dir": os.path.relpath(d, ROOT), "mode": p["mode"], "started": p["started"],
                               "duration_s": p["duration_s"], "git": p["git"], "load_start": p["load_start"],
                               "load_end": p.get("load_end", p["load_start"])})
        for r in p["runs"]:
            suite["runs"].append(dict(r, part=os.path.relpath(d, ROOT)))
        for name, b in p["benchmarks"].items():
            if name in suite["benchmarks"]:
                if not replace:
                    sys.exit("merge: %s is in two parts (--replace lets the later part's figures win)" % name)
                suite.setdefault("replaced", []).append({"name": name, "by": os.path.relpath(d, ROOT)})
            suite["benchmarks"][name] = b
    commits = list(dict.fromkeys(x["git"]["commit"] for x in suite["parts"]))  # unique, in order
    if len(commits) > 1:
        suite["git"] = {"commit": " + ".join(c[:10] for c in commits), "branch": parts[-1]["git"]["branch"],
                        "dirty": any(x["git"]["dirty"] for x in suite["parts"])}
    suite["started"] = min(starts).strftime("%Y-%m-%d %H:%M:%S")
    suite["duration_s"] = (max(ends) - min(starts)).total_seconds()
    suite["load_start"] = [max(x["load_start"][i] for x in suite["parts"]) for i in range(3)]
    suite["load_end"] = [max(x["load_end"][i] for x in suite["parts"]) for i in range(3)]
    return suite


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mode", choices=["quick", "full", "report", "merge"],
                        help="report: rebuild tables and plots from an existing DIR/suite.json; "
                             "merge: combine the suite.json of parts run side by side (one per core)")
    parser.add_argument("--out", default=None)
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--only", default=None,
                        help="run only the plan entries whose 'binary filter' text matches this regular expression")
    parser.add_argument("--replace", action="store_true",
                        help="merge: a benchmark in a later part replaces the same one of an earlier part")
    parser.add_argument("parts", nargs="*", help="merge: the DIRs whose suite.json files to combine into --out")
    parser.add_argument("--repetitions", type=int, default=None, help="override every entry's repetitions")
    args = parser.parse_intermixed_args()
    out_dir = os.path.abspath(args.out or os.path.join(ROOT, "bench", "results-" + args.mode))
    os.makedirs(out_dir, exist_ok=True)
    suite_path = os.path.join(out_dir, "suite.json")

    if args.mode == "report":
        with open(suite_path) as f:
            suite = json.load(f)
    elif args.mode == "merge":
        suite = merge_parts(args.parts, args.replace)
        with open(suite_path, "w") as f:
            json.dump(suite, f, indent=1)
    else:
        plan = QUICK if args.mode == "quick" else FULL
        if args.only:
            plan = [entry for entry in plan if re.search(args.only, entry[0] + " " + entry[1])]
        if args.repetitions:
            plan = [(b, f, args.repetitions) for b, f, _ in plan]
        for stale in os.listdir(out_dir):  # raw files of an earlier run would mix with this one's
            if re.match(r"^raw-\d+-.*\.json$", stale):
                os.remove(os.path.join(out_dir, stale))
        started = time.time()
        suite = {
            "mode": args.mode + ("" if not args.only else " --only '%s'" % args.only)
                    + ("" if not args.repetitions else " --repetitions %d" % args.repetitions),
            "started": datetime.datetime.utcfromtimestamp(started).strftime("%Y-%m-%d %H:%M:%S"),
            "machine": machine_info(),
            "load_start": load_average(),
            "git": {"commit": sh("git rev-parse HEAD"), "branch": sh("git rev-parse --abbrev-ref HEAD"),
                    "dirty": bool(sh("git status --porcelain --untracked-files=no"))},
            "runs": [],
            "benchmarks": {},
        }
        for index, (binary, bench_filter, reps) in enumerate(plan):
            entry, runs = run_binary(args.build, binary, bench_filter, reps, out_dir, index)
            suite["runs"].append(entry)
            collect(runs, binary, suite["benchmarks"])
            suite["load_end"] = load_average()
            suite["duration_s"] = time.time() - started
            with open(suite_path, "w") as f:  # after every run, so a partial suite is usable
                json.dump(suite, f, indent=1)
        print("suite took %.0f s" % suite["duration_s"])
    text = markdown(suite)
    with open(os.path.join(out_dir, "RESULTS.generated.md"), "w") as f:
        f.write(text + "\n")
    for path in plots(suite, out_dir):
        print("wrote " + path)
    print("wrote " + os.path.join(out_dir, "RESULTS.generated.md"))


if __name__ == "__main__":
    main()
