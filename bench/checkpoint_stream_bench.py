#!/usr/bin/python3
"""Time to the first action, time to drain and peak memory of hindsight.checkpoint_schedule's streams
(docs/guides/checkpoint_schedule.md): each case runs in a fresh interpreter, which reports its resident
memory before opening the stream (the module loaded), after the first action and at the end (peak,
getrusage's ru_maxrss). The results go to bench/RESULTS.md ("Checkpoint action streams").

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
spec, steps, drain = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"
def rss_mb():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024
before = rss_mb()
t0 = time.perf_counter()
schedule = hindsight.checkpoint_schedule(spec, steps=steps, state_bytes=8)
first = next(schedule)
t1 = time.perf_counter()
after_first = rss_mb()
actions = 1
if drain:
    for _ in schedule:
        actions += 1
t2 = time.perf_counter()
print(json.dumps({"first_ms": 1e3 * (t1 - t0), "drain_s": t2 - t0, "actions": actions,
                  "rss_before_mb": before, "rss_first_mb": after_first,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000)
    args = parser.parse_args()
    multilevel = "multilevel:ram=160,disk=1MiB,costs=1:1:0.5:0.5"  # 20 RAM states of 8 bytes, a large disk
    cases = [("binomial:checkpoints=100", args.steps, True), ("binomial:checkpoints=10", args.steps, True),
             ("full", args.steps, True), ("disk:dir=unused", args.steps, True), (multilevel, args.steps, True),
             ("binomial:checkpoints=100", 1 << 40, False), (multilevel, 100_000_000, False),
             ("cams:checkpoints=100", 10_000, True)]
    print(f"# {platform.node()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; python {platform.python_version()}")
    print("| spec | N | first action | whole stream | actions | RSS before / after first / peak |")
    print("|---|---|---|---|---|---|")
    for spec, steps, drain in cases:
        out = subprocess.run([sys.executable, "-c", CASE, spec, str(steps), "1" if drain else "0"],
                             check=True, capture_output=True, text=True).stdout
        r = json.loads(out)
        whole = f"{r['drain_s']:.2f} s" if drain else "(not drained)"
        print(f"| `{spec}` | {steps:,} | {r['first_ms']:.2f} ms | {whole} | {r['actions']:,} | "
              f"{r['rss_before_mb']:.0f} / {r['rss_first_mb']:.0f} / {r['peak_rss_mb']:.0f} MB |")


if __name__ == "__main__":
    main()
