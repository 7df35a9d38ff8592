#!/usr/bin/env bash
# Scenario measurements (bench/RESULTS.md "Scenarios, MPI, threads"): strong and weak scaling
# of scenario optimizations over ranks and threads, one gradient at 800x48 (and 1600x96 with
# FINE=1) with 1 and 2 threads, the 50-iteration single-scenario run with 2 threads, and the robust
# design (0.5, 1, 1.5 Omega, worst case) against the single-speed design at every speed.
# Usage: bench/scaling/run.sh BUILD_DIR OUT_DIR [BASELINE_50_ITERATION_DIR]
# Every line "RESULT ..." is a figure; logs stay in OUT_DIR.
set -euo pipefail
build=$(cd "$1" && pwd) out=$2 single=${3:-}
here=$(cd "$(dirname "$0")" && pwd)
hs=$build/hindsight
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mkdir -p "$out" && cd "$out"
timed() {  # NAME COMMAND...: wall seconds of the command
  local name=$1; shift
  local start end
  start=$(date +%s.%N)
  "$@" > "$name.log" 2>&1
  end=$(date +%s.%N)
  echo "RESULT $name $(echo "$end - $start" | bc) s  ($*)"
}
echo "load before: $(cat /proc/loadavg)"
# Strong scaling: 4 scenarios, 20 iterations, 200 x 12.
timed strong_1rank_1thread "$hs" optimize --config "$here/four_scenarios.json" --iterations 20 --out s1 --force --threads 1
mpirun -np 2 --oversubscribe true  # warm the launcher once
timed strong_2ranks mpirun -np 2 --oversubscribe "$hs" optimize --config "$here/four_scenarios.json" --iterations 20 --out s2 --force --threads 1
timed strong_1rank_2threads "$hs" optimize --config "$here/four_scenarios.json" --iterations 20 --out t2 --force --threads 2
# Weak scaling: 2 scenarios per rank.
timed weak_1rank_2scenarios "$hs" optimize --config "$here/two_scenarios.json" --iterations 20 --out w1 --force --threads 1
grep "rank 0:" strong_*.log weak_*.log | sed 's/^/RESULT /'
/usr/bin/python3 "$here/../../tests/mpi/same_results.py" s1/results.h5 s2/results.h5
/usr/bin/python3 "$here/../../tests/mpi/same_results.py" s1/results.h5 t2/results.h5
# One gradient at 800 x 48 with 1 and 2 threads.
for k in 1 2; do
  timed gradient_800x48_threads$k "$hs" evaluate --set rod.elementsAlongLength=800 --set rod.elementsThroughHeight=48 \
    --gradient g800_$k.h5 --force --threads $k --json
  grep -A4 '"seconds"' gradient_800x48_threads$k.log | tr -d '\n ' | sed "s/^/RESULT gradient_800x48_threads$k phases /"; echo
done
/usr/bin/python3 - <<'PY'
import h5py
a, b = h5py.File("g800_1.h5"), h5py.File("g800_2.h5")
print("RESULT gradient_800x48 1 vs 2 threads bitwise equal:",
      all(a[k][()].tobytes() == b[k][()].tobytes() for k in a))
PY
# The 50-iteration single-scenario optimization with 2 threads.
timed single_50_threads2 "$hs" optimize --out single50 --force --threads 2
# Robust design (worst case over 0.5, 1, 1.5 Omega) on 2 ranks, 50 iterations.
timed robust_2ranks mpirun -np 2 --oversubscribe "$hs" optimize --config "$here/robust.json" --out robust --force --threads 1
# Both final designs at every speed.
/usr/bin/python3 - "$single" <<'PY'
import sys, h5py
for name, path in [("single", (sys.argv[1] or "single50") + "/results.h5"), ("robust", "robust/results.h5")]:
    with h5py.File(path) as f, h5py.File(f"design_{name}.h5", "w") as out:
        out["x"] = f["designs"][-1]
PY
for design in single robust; do
  for speed in 15.707963267948966 31.415926535897931 47.12388980384690; do
    "$hs" evaluate --design design_$design.h5 --set rod.crankSpeed=$speed --json > eval_${design}_$speed.json
    echo "RESULT design $design speed $speed psi1 $(grep '"psi1"' eval_${design}_$speed.json | tr -d ' ,')"
  done
done
if [ "${FINE:-0}" = 1 ]; then
  for k in 1 2; do
    timed gradient_1600x96_threads$k "$hs" evaluate --set rod.elementsAlongLength=1600 --set rod.elementsThroughHeight=96 \
      --gradient g1600_$k.h5 --force --threads $k --json
    grep -A4 '"seconds"' gradient_1600x96_threads$k.log | tr -d '\n ' | sed "s/^/RESULT gradient_1600x96_threads$k phases /"; echo
  done
fi
echo "load after: $(cat /proc/loadavg)"
