#!/usr/bin/env bash
# ctest label mpi: the same scenario optimization with 1 rank, 2 MPI ranks and 2 threads
# writes bitwise-equal histories and designs; a run whose rank is killed resumes (with 2 ranks) to
# the same bits; a failing scenario stops every rank with a non-zero exit, the scenario named; the
# frequency guard and GCMMA give the same bits on 1 and 2 ranks; ranks started with different
# configurations (a scenario weight, --iterations) stop with exit 2 naming the field and the ranks
# before anything is written, and results.h5 carries the fingerprint they agreed on.
# Usage: ranks_test.sh HINDSIGHT MPIEXEC PYTHON WORKDIR. Runs as root too (CI): OpenMPI's
# allow-run-as-root variables are set here; --oversubscribe because the machine may have 2 cores.
set -euo pipefail
hindsight=$1 mpiexec=$2 python=$3 work=$4
here=$(cd "$(dirname "$0")" && pwd)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
rm -rf "$work" && mkdir -p "$work" && cd "$work"
config=$here/scenarios3.json
same() { "$python" "$here/same_results.py" "$1/results.h5" "$2/results.h5"; }

"$hindsight" optimize --config "$config" --iterations 3 --out D1 --threads 1 > D1.log
"$mpiexec" -np 2 --oversubscribe "$hindsight" optimize --config "$config" --iterations 3 --out D2 --threads 1 > D2.log
"$hindsight" optimize --config "$config" --iterations 3 --out T2 --threads 2 > T2.log
"$mpiexec" -np 3 --oversubscribe "$hindsight" optimize --config "$config" --iterations 3 --out D3 --threads 1 > D3.log
same D1 D2
same D1 T2
same D1 D3
grep -q "2 rank(s)" D2.log
grep -q "worst: fast" D2.log

# Kill rank 1 (SIGKILL) once the first iteration is on disk; resume with 2 ranks: the same bits.
"$mpiexec" -np 2 --oversubscribe "$hindsight" optimize --config "$config" --iterations 3 --out K --threads 1 \
  > K.log 2>&1 &
launcher=$!
for _ in $(seq 1 600); do
  if [ -f K/results.h5 ]; then break; fi
  sleep 0.1
done
ranks=$(ps -o pid= --ppid "$launcher" || true)
victim=$(for pid in $ranks; do
  if tr '\0' '\n' < "/proc/$pid/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=1"; then echo "$pid"; fi
done)
if [ -n "$victim" ]; then kill -9 $victim; fi
wait "$launcher" && status=0 || status=$?
echo "killed rank 1 (pid ${victim:-none, the run had ended}), mpirun exit $status"
"$mpiexec" -np 2 --oversubscribe "$hindsight" optimize --config "$config" --iterations 3 --out K --resume --threads 1 > K2.log
same D1 K

# A failing scenario (its simulation overflows at once) stops both ranks, named, exit code non-zero.
sed 's/"crankSpeed": 47.12388980384690/"crankSpeed": 1e9/' "$config" > bad.json
if "$mpiexec" -np 2 --oversubscribe "$hindsight" optimize --config bad.json --iterations 2 --out B > B.log 2>&1; then
  echo "a failing scenario did not fail the run"; exit 1
fi
grep -q "numerical failure: scenario 'fast'" B.log
# The frequency guard (70 Hz, violated at x0: 36.6 Hz) with scenarios: each rank computes it from a scenario
# it owns (the eigenpairs are the design's); 2 ranks give the bits of 1. More ranks than scenarios: refused.
guard=(--set optimization.minFirstFrequency=70)
"$hindsight" optimize --config "$config" --iterations 3 --out G1 --threads 1 "${guard[@]}" > G1.log
"$mpiexec" -np 2 --oversubscribe "$hindsight" optimize --config "$config" --iterations 3 --out G2 --threads 1 \
  "${guard[@]}" > G2.log
same G1 G2
if "$mpiexec" -np 4 --oversubscribe "$hindsight" optimize --config "$config" --iterations 1 --out G4 "${guard[@]}" \
  > G4.log 2>&1; then
  echo "4 ranks for 3 scenarios with the frequency guard were accepted"; exit 1
fi
grep -q "minFirstFrequency > 0 needs every MPI rank to own a scenario" G4.log

# GCMMA with scenarios: its trials are evaluated collectively; 2 ranks give the bits of 1.
gcmma=(--set optimization.method=gcmma)
"$hindsight" optimize --config "$config" --iterations 3 --out C1 --threads 1 "${gcmma[@]}" > C1.log
"$mpiexec" -np 2 --oversubscribe "$hindsight" optimize --config "$config" --iterations 3 --out C2 --threads 1 \
  "${gcmma[@]}" > C2.log
same C1 C2
# Ranks with different configurations: refused by every rank (exit 2) naming the field and the ranks,
# nothing written; different --iterations must not hang (timeout), the same refusal.
sed 's/"weight": 1.04/"weight": 1.05/' "$config" > other.json
status=0
timeout 300 "$mpiexec" --oversubscribe -np 1 "$hindsight" optimize --config "$config" --iterations 2 --out M --threads 1 \
  : -np 1 "$hindsight" optimize --config other.json --iterations 2 --out M --threads 1 > M.log 2>&1 || status=$?
cat M.log
[ "$status" = 2 ] || { echo "ranks with different scenario weights: exit $status, expected 2"; exit 1; }
grep -q "rank 1 differs from rank 0 in scenarios" M.log
[ ! -e M/results.h5 ] || { echo "ranks with different configurations wrote M/results.h5"; exit 1; }
status=0
timeout 300 "$mpiexec" --oversubscribe -np 1 "$hindsight" optimize --config "$config" --iterations 2 --out I --threads 1 \
  : -np 1 "$hindsight" optimize --config "$config" --iterations 3 --out I --threads 1 > I.log 2>&1 || status=$?
cat I.log
[ "$status" = 2 ] || { echo "ranks with different --iterations: exit $status, expected 2 (124: hung)"; exit 1; }
grep -q "optimization.iterations (rank 0: 2, rank 1: 3)" I.log
# The agreed fingerprint is in the results file; verify recomputes it from the stored configuration.
"$hindsight" verify D2 > V.log
grep -q "configuration fingerprint fnv1a64:[0-9a-f]*, agreed by 2 rank(s)" V.log
"$hindsight" verify D1 | grep -q "agreed by 1 rank(s)"
echo "mpi ranks test: passed"
