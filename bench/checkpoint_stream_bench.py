#!/usr/bin/python3
"""Time to the first action, time to drain and peak memory of hindsight.checkpoint_schedule's streams
(docs/guides/checkpoint_schedule.md), every family at N = 10^6 where it streams that N: each case runs in a
fresh interpreter, which reports its resident memory before opening the stream (the module loaded), after
the first action and at the end (peak, getrusage's ru_maxrss), and the CPU seconds of the whole stream. A
family that refuses the N says why (the first line of its error). Streams opened with steps=None (full,
online, cams) are finalized where a Forward reaches N, as a host stops there; for them the longest Forward before
finalize is reported too (how far the host runs on one action). The results go to bench/RESULTS.md
("Checkpoint action streams").

    PYTHONPATH=build/python /usr/bin/python3 bench/checkpoint_stream_bench.py [--steps 1000000]
"""
import argparse
import json
import os
import platform
import subprocess
import sys

CASE = r"""
import json, resource, sys, time
import hindsight
spec, drain = sys.argv[1], sys.argv[3] == "1"
unknown = sys.argv[2].startswith("none:")  # steps=None, finalized at N
steps = int(sys.argv[2].split(":")[-1])
def rss_mb():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024
before = rss_mb()
t0, c0 = time.perf_counter(), time.process_time()
try:
    schedule = hindsight.checkpoint_schedule(spec, steps=None if unknown else steps, state_bytes=8)
except ValueError as error:
    print(json.dumps({"refused": str(error).splitlines()[0], "seconds": time.perf_counter() - t0}))
    sys.exit(0)
longest = 0
def host(action):  # a host that stops its forward run at N
    global longest
    if unknown and type(action) is hindsight.Forward and schedule.max_n is None:
        longest = max(longest, min(action.n1, steps) - action.n0)
        if action.n1 >= steps:
            schedule.finalize(steps)
host(next(schedule))
t1 = time.perf_counter()
after_first = rss_mb()
actions = 1
if drain:
    for action in schedule:
        host(action)
        actions += 1
t2 = time.perf_counter()
print(json.dumps({"first_ms": 1e3 * (t1 - t0), "drain_s": t2 - t0, "cpu_s": time.process_time() - c0,
                  "actions": actions, "rss_before_mb": before, "rss_first_mb": after_first,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "longest_forward": longest}))
"""

# cams' exact plan has tables of N (M + 1) entries, at most cams::Plan::kMaxTableEntries
# (engine/cams_checkpointing.h): checkpoints=100 holds M = 101 units, so its largest N is this.
CAMS_MAX_TABLE_ENTRIES = 12_500_000
CAMS_LARGEST_N = CAMS_MAX_TABLE_ENTRIES // 102 - 1


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000)
    parser.add_argument("--only", help="run the cases whose spec contains this text")
    args = parser.parse_args()
    multilevel = "multilevel:ram=160,disk=1MiB,costs=1:1:0.5:0.5"  # 20 RAM states of 8 bytes, a large disk
    n = args.steps
    cases = [("binomial:checkpoints=100", n, True), ("binomial:checkpoints=10", n, True),
             ("full", n, True), ("disk:dir=unused", n, True), (multilevel, n, True),
             ("cams:checkpoints=100,online=1", n, True), ("online:checkpoints=100", n, True),
             ("full", f"none:{n}", True), ("online:checkpoints=100", f"none:{n}", True),
             ("online:checkpoints=10", f"none:{n}", True), ("cams:checkpoints=100,online=1", f"none:{n}", True),
             ("cams:checkpoints=100", n, True), ("cams:checkpoints=100", 10_000, True),
             ("cams:checkpoints=100", CAMS_LARGEST_N, True),
             ("binomial:checkpoints=100", 1 << 40, False), (multilevel, 100_000_000, False)]
    print(f"# {platform.node()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; python {platform.python_version()}")
    print("| spec | N | first action | whole stream (CPU) | actions | RSS before / after first / peak |")
    print("|---|---|---|---|---|---|")
    for spec, steps, drain in cases:
        if args.only and args.only not in spec:
            continue
        out = subprocess.run([sys.executable, "-c", CASE, spec, str(steps), "1" if drain else "0"],
                             check=True, capture_output=True, text=True).stdout
        r = json.loads(out)
        unknown = isinstance(steps, str)
        label = f"`{spec}`" + (" steps=None, finalize(N)" if unknown else "")
        if unknown:
            steps = int(steps.split(":")[1])
        if "refused" in r:
            print(f"| {label} | {steps:,} | refused in {1e3 * r['seconds']:.1f} ms: {r['refused']} | | | |")
            continue
        whole = f"{r['drain_s']:.2f} s ({r['cpu_s']:.2f} s)" if drain else "(not drained)"
        longest = f", longest Forward {r['longest_forward']:,}" if unknown else ""
        print(f"| {label} | {steps:,} | {r['first_ms']:.2f} ms | {whole} | {r['actions']:,}{longest} | "
              f"{r['rss_before_mb']:.0f} / {r['rss_first_mb']:.0f} / {r['peak_rss_mb']:.0f} MB |", flush=True)


if __name__ == "__main__":
    main()
