#!/usr/bin/python3
"""PETSc's own trajectory types against hindsight's strategies inside PETSc (docs/guides/petsc.md).

Runs the reaction-diffusion TSAdjoint program of the tests (tests/petsc/reaction_diffusion.c, a plain
PETSc program) once per trajectory configuration and reports, per run: CPU seconds (user + system of
the process, or of all ranks), the process's peak resident memory (largest rank), the trajectory's own
peak bytes where it reports them, PETSc's recomputation counter, and whether lambda(0) has the bits of
PETSc's memory trajectory. Writes a Markdown table (stdout, or --markdown FILE).

usage: petsc_trajectories.py --build BUILD [--grid 96] [--steps 300] [--ranks 1] [--scheme rk4|cn]
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time


def run(build, options, ranks, work):
    exe = os.path.abspath(os.path.join(build, "tests", "petsc_reaction_diffusion"))
    out = os.path.join(work, "lambda.bin")
    if os.path.exists(out):
        os.remove(out)
    command = [exe] + options + ["-out", out, "-ts_trajectory_view"]
    if ranks > 1:
        command = ["mpirun", "--oversubscribe", "--allow-run-as-root", "-n", str(ranks)] + command
    env = dict(os.environ, OMPI_MCA_ess_singleton_isolated="1")
    log = os.path.join(work, "log.txt")
    start = time.perf_counter()
    with open(log, "w") as f:
        process = subprocess.Popen(command, stdout=f, stderr=subprocess.STDOUT, cwd=work, env=env)
        # wait4: this run's own CPU time and peak resident memory (the largest of its processes).
        _, status, usage = os.wait4(process.pid, 0)
        process.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - start
    cpu = usage.ru_utime + usage.ru_stime
    output = open(log).read()
    result = {"ok": process.returncode == 0, "cpu": cpu, "wall": wall, "rss": usage.ru_maxrss / 1024.0,
              "output": output, "bits": open(out, "rb").read() if os.path.exists(out) else None}
    match = re.search(r"total number of recomputations for adjoint calculation = (\d+)", output)
    result["recomputations"] = int(match.group(1)) if match else None
    match = re.search(r"peak bytes in memory: (\d+)", output)
    result["peak"] = int(match.group(1)) if match else None
    if not result["ok"]:
        error = re.search(r"PETSC ERROR: (?!-|#|See|Petsc|Configure|.*named|-----)(.*)", output)
        result["error"] = error.group(1).strip() if error else output.strip().splitlines()[-1]
    return result


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--build", required=True)
    parser.add_argument("--grid", type=int, default=96)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--ranks", type=int, default=1)
    parser.add_argument("--scheme", default="rk4", choices=["rk4", "cn"])
    parser.add_argument("--markdown")
    args = parser.parse_args()
    lib = os.path.abspath(os.path.join(args.build, "libhindsight_petsc.so"))
    base = ["-grid", str(args.grid), "-ts_max_steps", str(args.steps)]
    base += ["-ts_rk_type", "4"] if args.scheme == "rk4" else ["-ts_type", "cn"]
    hs = ["-dll_append", lib, "-ts_trajectory_type", "hindsight", "-ts_trajectory_hindsight_storage"]
    state_bytes = 2 * args.grid * args.grid * 8 // args.ranks
    # C checkpoints: binomial/online/cams hold C + 1 states. PETSc's two-level stride S without revolve
    # holds one state per stride on disk and S states of the current stride in memory.
    configs = [
        ("PETSc basic (every step to disk, with stages)", ["-ts_trajectory_type", "basic"]),
        ("PETSc memory (every step's stages)", ["-ts_trajectory_type", "memory"]),
        ("PETSc memory, solution only", ["-ts_trajectory_type", "memory", "-ts_trajectory_solution_only"]),
        ("PETSc memory, two-level stride 20", ["-ts_trajectory_type", "memory", "-ts_trajectory_stride", "20",
                                               "-ts_trajectory_solution_only"]),
        ("PETSc memory, -ts_trajectory_max_cps_ram 20", ["-ts_trajectory_type", "memory",
                                                        "-ts_trajectory_max_cps_ram", "20"]),
        ("hindsight full", hs + ["full"]),
        ("hindsight full:stages=1", hs + ["full:stages=1"]),
        ("hindsight packed", hs + ["packed"]),
        ("hindsight binomial:checkpoints=20", hs + ["binomial:checkpoints=20"]),
        ("hindsight online:checkpoints=20", hs + ["online:checkpoints=20"]),
        ("hindsight cams:checkpoints=20", hs + ["cams:checkpoints=20"]),
        ("hindsight binomial:checkpoints=5", hs + ["binomial:checkpoints=5"]),
    ]
    work = tempfile.mkdtemp(prefix="hindsight-petsc-bench-")
    rows = []
    reference = None
    try:
        for name, options in configs:
            result = run(args.build, base + options, args.ranks, work)
            if name.startswith("PETSc memory (every"):
                reference = result["bits"]
            rows.append((name, result))
            print(name, "ok" if result["ok"] else "failed", "%.2f s" % result["cpu"], file=sys.stderr)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    lines = ["| trajectory | CPU s | peak RSS MiB | trajectory peak MiB | recomputed steps | lambda(0) bits |",
             "|---|---:|---:|---:|---:|---|"]
    for name, r in rows:
        if not r["ok"]:
            lines.append("| %s | fails: %s | | | | |" % (name, r["error"].replace("|", "/")[:120]))
            continue
        peak = "%.1f" % (r["peak"] / 2**20) if r["peak"] is not None else "-"
        same = "same as memory" if r["bits"] == reference else "differ"
        lines.append("| %s | %.2f | %.0f | %s | %s | %s |" % (name, r["cpu"], r["rss"], peak,
                                                             r["recomputations"], same))
    header = ("reaction-diffusion %dx%d grid (2 fields), %d %s steps, %d rank(s); one state = %.0f KiB per rank"
              % (args.grid, args.grid, args.steps, args.scheme.upper(), args.ranks, state_bytes / 1024))
    text = header + "\n\n" + "\n".join(lines) + "\n"
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(text)
    print(text)


if __name__ == "__main__":
    main()
