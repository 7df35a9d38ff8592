#!/usr/bin/env bash
# Two load-independent measurements for the rank model (bench/RESULTS.md, "Scenarios, MPI, threads"):
#  1. CPU seconds per rank (user + system, /usr/bin/time inside mpirun) of the 4-scenario
#     optimization at 100 x 6, 3 iterations, on 1 and 2 ranks: the work of a rank, independent of
#     how much of a core the shared machine grants it (the wall time is not).
#  2. MMA seconds per update against the scenario count, for max (m = S + 1 constraints) and sum
#     (m = 1), at 200 x 12 with a 0.05 s horizon so that evaluations are cheap.
# Usage: bench/scaling/cpu_and_mma.sh BUILD_DIR OUT_DIR
set -euo pipefail
build=$(cd "$1" && pwd) out=$2
here=$(cd "$(dirname "$0")" && pwd)
hs=$build/hindsight
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mkdir -p "$out" && cd "$out"
mesh=(--set rod.elementsAlongLength=100 --set rod.elementsThroughHeight=6 --iterations 3 --force --threads 1)
/usr/bin/time -f "RESULT cpu 1 rank: %U s user %S s system, %e s wall" \
  "$hs" optimize --config "$here/four_scenarios.json" "${mesh[@]}" --out c1 > c1.log
mpirun -np 2 --oversubscribe /usr/bin/time -f "RESULT cpu 2 ranks, one rank: %U s user %S s system, %e s wall" \
  "$hs" optimize --config "$here/four_scenarios.json" "${mesh[@]}" --out c2 > c2.log
OMPI_MCA_mpi_yield_when_idle=1 mpirun -np 2 --oversubscribe \
  /usr/bin/time -f "RESULT cpu 2 ranks (yield when idle), one rank: %U s user %S s system, %e s wall" \
  "$hs" optimize --config "$here/four_scenarios.json" "${mesh[@]}" --out c3 > c3.log
/usr/bin/python3 "$here/../../tests/mpi/same_results.py" c1/results.h5 c2/results.h5
for count in 4 16 64 128; do
  for aggregate in max sum; do
    /usr/bin/python3 - "$count" "$aggregate" <<'PY'
import json, sys
count, aggregate = int(sys.argv[1]), sys.argv[2]
json.dump({"rod": {"endTime": 0.05, "rampTime": 0.05, "eslSamples": 10},
           "optimization": {"aggregate": aggregate, "moveLimit": 0.2},
           "scenarios": [{"name": f"s{i}", "crankSpeed": 10.0 + 0.25 * i} for i in range(count)]},
          open(f"mma_{aggregate}_{count}.json", "w"))
PY
    "$hs" optimize --config "mma_${aggregate}_$count.json" --iterations 2 --out "m_${aggregate}_$count" --force > /dev/null
    /usr/bin/python3 - "m_${aggregate}_$count/results.h5" "$count" "$aggregate" <<'PY'
import sys, h5py, numpy as np
h = h5py.File(sys.argv[1])["history"]
print(f"RESULT mma {sys.argv[3]} S={sys.argv[2]}: {1e3 * np.median(h['mma_seconds'][:-1]):.1f} ms per update, "
      f"evaluation {np.median(h['evaluation_seconds'][()]):.2f} s")
PY
  done
done
