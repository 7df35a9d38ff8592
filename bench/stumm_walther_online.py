#!/usr/bin/python3
"""online against Stumm & Walther's own online checkpointing, N by N.

Stumm & Walther ("New algorithms for optimal online checkpointing", SIAM J. Sci. Comput. 32(2), 2010)
published their algorithms in their revolve code (class Revolve in online mode: Online_r2 up to
beta(c, 2), Online_r3 up to beta(c, 3) -- "quasi optimal" there --, then Moin). This script compiles
bench/stumm_walther_driver.cpp against that code, which the user supplies (it is not part of hindsight
and is not downloaded; e.g. the copy in devitocodes/pyrevolve: include/revolve.h, src/revolve.cpp), runs
it for every N up to beta(c, 3) (sampled beyond 3000) and for N beyond, and compares its forward steps
with `online:checkpoints=c` (`hindsight.schedule`, whose counts equal a run's, tested). Both hold c
checkpoints beside the current (working) state; forward steps count the first sweep's N - 1 as revolve's
numforw does, so the offline optimum is T(N, c).

Usage: bench/stumm_walther_online.py --revolve DIR [--build build] [--checkpoints 2,3,...] [--limit N]
"""
import argparse
import os
import subprocess
import sys
import tempfile
from math import comb


def beta(c, r):
    return comb(c + r, c) if r >= 0 else 0


def optimum(steps, c):
    r = 0
    while beta(c, r) < steps:
        r += 1
    return r * steps - beta(c + 1, r - 1)


def stumm_walther(driver, c, steps_list):
    out = subprocess.run([driver, str(c)] + [str(n) for n in steps_list], capture_output=True, text=True,
                         check=True).stdout
    counts = {}
    for line in out.splitlines():
        fields = line.split()
        if len(fields) == 5 and fields[0] == "RESULT":
            counts[int(fields[2])] = int(fields[3])
    return counts


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--revolve", required=True, help="directory with include/revolve.h and src/revolve.cpp")
    parser.add_argument("--build", default="build")
    parser.add_argument("--checkpoints", default="2,3,4,5,6,8,10,20,50")
    parser.add_argument("--limit", type=int, default=100000, help="largest N beyond beta(c, 3)")
    args = parser.parse_args()
    sys.path.insert(0, os.path.join(os.path.abspath(args.build), "python"))
    import hindsight

    here = os.path.dirname(os.path.abspath(__file__))
    with tempfile.TemporaryDirectory() as work:
        driver = os.path.join(work, "driver")
        subprocess.run(["g++", "-O2", "-w", "-I", os.path.join(args.revolve, "include"),
                        os.path.join(here, "stumm_walther_driver.cpp"), os.path.join(args.revolve, "src", "revolve.cpp"),
                        "-o", driver], check=True)
        print("| c | N | cases | online > S&W | online < S&W | worst S&W / T(N,c) | worst online / T(N,c) |")
        print("|---:|---|---:|---:|---:|---:|---:|")
        for c in [int(x) for x in args.checkpoints.split(",")]:
            b3 = beta(c, 3)
            inside = list(range(2, b3 + 1)) if b3 <= 3000 else sorted(
                set(list(range(2, 1000)) + list(range(1000, b3 + 1, b3 // 1000)) + [b3]))
            beyond = sorted(n for n in set([b3 + k for k in range(1, 200)] + [int(b3 * f) for f in (1.5, 2, 3, 5)])
                            if n <= args.limit)
            counts = stumm_walther(driver, c, inside + beyond)
            for label, group in ((f"2 … β(c,3) = {b3}", inside), (f"{beyond[0]} … {beyond[-1]}" if beyond else "", beyond)):
                if not group:
                    continue
                above = below = 0
                worst_sw = worst_online = 1.0
                for steps in group:
                    online = steps - 1 + hindsight.schedule(f"online:checkpoints={c}", steps,
                                                           state_bytes=8)["recomputed_steps"]
                    t = optimum(steps, c)
                    above += online > counts[steps]
                    below += online < counts[steps]
                    worst_sw = max(worst_sw, counts[steps] / t)
                    worst_online = max(worst_online, online / t)
                print(f"| {c} | {label} | {len(group)} | {above} | {below} | {worst_sw:.4f} | {worst_online:.4f} |",
                      flush=True)


if __name__ == "__main__":
    main()
