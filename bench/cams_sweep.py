#!/usr/bin/python3
"""cams vs binomial at equal bytes: right-hand-side evaluations and planning time from
`hindsight schedule` (no model run; its counts equal a real run's, tests/storage/cams_checkpointing_test.cpp).

For every N and budget C (the bytes of binomial:checkpoints=C, i.e. C + 1 states):
  binomial        revolve with all C + 1 slots as snapshots, x_{N-1} the engine's working state,
                  T(N, C + 1) - (N - 1) recomputed steps: the optimum without step records (every adjoint
                  step recomputes its stages)
  cams            the exact stage-aware optimum (only where its N x (C + 2) table fits, <= 1.25e7 entries)
  cams online=1   online placement + the optimal plan per interval (any N)
Ratios: each count over binomial's, and cams online over the exact cams optimum where that exists.

Usage: bench/cams_sweep.py BUILD_DIR [--steps 3e4,1e5,...] [--slots 10,50,...] [--json OUT] [--timeout S]
                           [--exact-up-to N]   (exact cams only for N <= this; its plan takes minutes beyond 1e5)
"""
import argparse
import json
import subprocess
import sys
import time

TABLE_CAP = 12_500_000


def schedule(hindsight, spec, steps, timeout):
    start = time.perf_counter()
    try:
        out = subprocess.run([hindsight, "schedule", "--storage", spec, "--steps", str(steps), "--state-bytes", "800",
                              "--json"], capture_output=True, text=True, timeout=timeout, check=True).stdout
    except subprocess.TimeoutExpired:
        return None
    seconds = time.perf_counter() - start
    result = json.loads(out)
    result["seconds"] = seconds
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("build")
    parser.add_argument("--steps", default="30000,100000,300000,1000000")
    parser.add_argument("--slots", default="10,50,100,1000")
    parser.add_argument("--json")
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--exact-up-to", type=float, default=float("inf"))
    args = parser.parse_args()
    hindsight = args.build + "/hindsight"
    rows = []
    print("| N | C | binomial rhs | cams rhs (plan s) | cams online=1 rhs (plan s) | cams/binomial | online/binomial | online/cams |")
    print("|---|---|---|---|---|---|---|---|")
    for steps in [int(float(s)) for s in args.steps.split(",")]:
        for slots in [int(s) for s in args.slots.split(",")]:
            binomial = schedule(hindsight, f"binomial:checkpoints={slots}", steps, args.timeout)
            online = schedule(hindsight, f"cams:checkpoints={slots},online=1", steps, args.timeout)
            exact = None
            if steps <= args.exact_up_to and (steps + 1) * (min(slots + 1, 4 * (steps + 1)) + 1) <= TABLE_CAP:
                exact = schedule(hindsight, f"cams:checkpoints={slots}", steps, args.timeout)
            b = binomial["rhs_evaluations"]
            row = {"steps": steps, "slots": slots, "binomial": b,
                   "cams": exact["rhs_evaluations"] if exact else None,
                   "cams_seconds": exact["seconds"] if exact else None,
                   "online": online["rhs_evaluations"] if online else None,
                   "online_seconds": online["seconds"] if online else None}
            rows.append(row)

            def cell(count, seconds):
                return "-" if count is None else f"{count:,} ({seconds:.2f})"

            def ratio(a, c):
                return "-" if a is None or c is None else f"{a / c:.3f}"

            print(f"| {steps:,} | {slots} | {b:,} | {cell(row['cams'], row['cams_seconds'])} | "
                  f"{cell(row['online'], row['online_seconds'])} | {ratio(row['cams'], b)} | "
                  f"{ratio(row['online'], b)} | {ratio(row['online'], row['cams'])} |", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
