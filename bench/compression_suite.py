#!/usr/bin/python3
"""Compression along time: old and new codecs side by side in one run, through the CLI.

    /usr/bin/python3 bench/compression_suite.py [--build DIR] [--out FILE.md] [--only REGEX] [--dir TMPDIR]

For every configuration (reduced rod 200x12 with 10, 20, 40 modes at T = 3, 10, 100 s; full-order rod
200x12, 0.1 s with trbdf2 at h = 1e-3) it runs `hindsight evaluate --json --gradient g.h5` once per strategy:
full (the reference), disk:codec=zstd (shuffle + zstd, the older format), disk (time codec),
lossy:codec=zfp,tolerance=1e-10, lossy:codec=round,tolerance=1e-6 and lossy:target=1e-6, and prints
one markdown table: compression ratio, relative 2-norm error of every gradient in g.h5 against full's
(the largest over dpsi1_dx, dpsi2_dx), "bitwise" when every bit agrees, the strategy's
gradient_error_estimate, and the simulation's wall seconds relative to full's. One run each (not a
median): on a loaded machine the time column carries +-20 %.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

CONFIGS = [
    # label, --set assignments
    ("m10 T3 (default)", ["rod.endTime=3"]),
    ("m10 T10", ["rod.endTime=10"]),
    ("m20 T3", ["rod.modeCount=20", "rod.endTime=3"]),
    ("m20 T10", ["rod.modeCount=20", "rod.endTime=10"]),
    ("m20 T100", ["rod.modeCount=20", "rod.endTime=100"]),
    ("m40 T3", ["rod.modeCount=40", "rod.endTime=3", "simulation.step=5e-5"]),
    ("m40 T10", ["rod.modeCount=40", "rod.endTime=10", "simulation.step=5e-5"]),
    # The full-order model as full_order_bench runs it: crank at full speed after 50 ms, 100 trbdf2 steps
    # (T = 3 s would be 3000 steps of 10^4 doubles: minutes per gradient on 2 cores).
    ("full-order 200x12 100 steps", ["simulation.model=full", "rod.rampTime=0.05", "rod.endTime=0.1",
                                     "simulation.integrator=trbdf2", "simulation.step=1e-3"]),
]
STRATEGIES = ["full", "disk:dir={dir},codec=zstd", "disk:dir={dir}", "lossy:codec=zfp,tolerance=1e-10",
              "lossy:codec=round,tolerance=1e-6", "lossy:target=1e-6"]


def run(binary, assignments, storage, gradient):
    command = [binary, "evaluate", "--json", "--force", "--gradient", gradient, "--storage", storage]
    for a in assignments:
        command += ["--set", a]
    start = time.time()
    out = subprocess.run(command, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(" ".join(command) + ": " + out.stderr.strip())
    result = json.loads(out.stdout)
    result["wall"] = time.time() - start
    result["command"] = " ".join(command)
    return result


def gradients(path):
    with h5py.File(path, "r") as f:
        return {k: f[k][()] for k in ("dpsi1_dx", "dpsi2_dx") if k in f}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--build", default="build")
    parser.add_argument("--out", default=None)
    parser.add_argument("--only", default=".")
    parser.add_argument("--dir", default=None)
    args = parser.parse_args()
    binary = os.path.join(args.build, "hindsight")
    work = args.dir or tempfile.mkdtemp(prefix="hindsight-compression-")
    rows = ["| configuration | strategy | ratio | rel. gradient error vs full | estimate | simulation time / full |",
            "|---|---|---:|---:|---:|---:|"]
    for label, assignments in CONFIGS:
        if not re.search(args.only, label):
            continue
        reference = None
        for template in STRATEGIES:
            storage = template.format(dir=work)
            path = os.path.join(work, "g.h5")
            try:
                r = run(binary, assignments, storage, path)
            except RuntimeError as e:
                print("skipped:", e, file=sys.stderr)
                continue
            g = gradients(path)
            seconds = r["seconds"]["simulation"]
            if template == "full":
                reference = (g, seconds)
            errors = [np.linalg.norm(g[k] - reference[0][k]) / np.linalg.norm(reference[0][k]) for k in g]
            bitwise = all(np.array_equal(g[k].view(np.uint64), reference[0][k].view(np.uint64)) for k in g)
            error = "bitwise" if bitwise else f"{max(errors):.3g}"
            estimate = r["summary"].get("gradient_error_estimate")
            rows.append(f"| {label} | `{template.replace('{dir}', 'D')}` | {r['summary']['compression_ratio']:.3g} | "
                        f"{error} | {'' if estimate is None else f'{estimate:.3g}'} | {seconds / reference[1]:.2f} |")
            print(rows[-1], flush=True)
    text = "\n".join(rows) + "\n"
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
