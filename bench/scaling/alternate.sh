#!/usr/bin/env bash
# Strong scaling on a loaded machine: 1 rank, 2 ranks and 1 rank x 2 threads run in turn, ROUNDS
# times, on the 4-scenario optimization at a coarser mesh (100 x 6, ITER iterations), so that a change
# of the background load hits every variant alike; prints every wall time and the medians.
# Usage: bench/scaling/alternate.sh BUILD_DIR OUT_DIR [ROUNDS=3] [ITER=5]
set -euo pipefail
build=$(cd "$1" && pwd) out=$2 rounds=${3:-3} iterations=${4:-5}
here=$(cd "$(dirname "$0")" && pwd)
hs=$build/hindsight
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mkdir -p "$out" && cd "$out"
mesh=(--set rod.elementsAlongLength=100 --set rod.elementsThroughHeight=6 --iterations "$iterations" --force)
run() {  # NAME COMMAND...
  local name=$1; shift
  local start end
  start=$(date +%s.%N)
  "$@" > "$name.log" 2>&1
  end=$(date +%s.%N)
  echo "$name $(echo "$end - $start" | bc)" | tee -a times.txt
}
rm -f times.txt
for round in $(seq 1 "$rounds"); do
  echo "round $round, load $(cut -d' ' -f1 /proc/loadavg)"
  run one_rank "$hs" optimize --config "$here/four_scenarios.json" "${mesh[@]}" --out a1 --threads 1
  run two_ranks mpirun -np 2 --oversubscribe "$hs" optimize --config "$here/four_scenarios.json" "${mesh[@]}" --out a2 --threads 1
  run two_threads "$hs" optimize --config "$here/four_scenarios.json" "${mesh[@]}" --out a3 --threads 2
done
/usr/bin/python3 - <<'PY'
import statistics
times = {}
for line in open("times.txt"):
    name, seconds = line.split()
    times.setdefault(name, []).append(float(seconds))
base = statistics.median(times["one_rank"])
for name, values in times.items():
    m = statistics.median(values)
    print(f"RESULT alternate {name}: median {m:.1f} s of {len(values)} ({', '.join(f'{v:.1f}' for v in values)}), "
          f"speed-up {base / m:.2f}")
PY
