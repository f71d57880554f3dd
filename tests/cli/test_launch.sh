#!/usr/bin/env bash
# A real launch through cluster/launch.sh on this one machine (label mpi):
# `cave cluster rankfile` for cave5.json (every output on localhost), then
# mpirun --rankfile ... -np 11 cave run ... --frames 2 --size 32 --no-lcd
# --present files.  Checks exit 0, the rankfile's 11 ranks, a summary line
# in metrics.jsonl, one log folder per rank (Open MPI 4.1's
# --output-filename: DIR/1/rank.K/stdout|stderr, K zero-padded), rank 0's log
# with every rank's ready line, and that a bad option stops before mpirun.
# Usage: test_launch.sh CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"; MPIEXEC="${4:-mpirun}"
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK" || exit 1
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_mca_base_component_disable_dlclose=1
# As tests/cluster/test_cluster.sh: no LeakSanitizer inside the MPI ranks
# (Open MPI and Mesa free nothing at exit); set even when ASAN_OPTIONS is not,
# since a sanitized build would otherwise report their leaks (harmless without ASan).
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
export CAVE MPIRUN="$MPIEXEC"
CFG="$SRC/configs/caves/cave5.json"

"$CAVE" bake default -o s.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null || { echo "FAIL: bake"; exit 1; }
bash "$SRC/cluster/launch.sh" --help | grep -q "CAVE_CORES" && ok "launch.sh --help" || bad "launch.sh --help"

t0=$(date +%s)
timeout 110 bash "$SRC/cluster/launch.sh" "$CFG" --scene s.prt --frames 2 --size 32 --no-lcd --present files --http off \
  -o run >launch.out 2>launch.err; rc=$?
t1=$(date +%s)
[ $rc -eq 0 ] && ok "launch exit 0 in $((t1 - t0)) s" || bad "launch rc $rc: $(tail -15 launch.err launch.out)"
n=$(grep -c '^rank [0-9]*=localhost slot=' run/rankfile 2>/dev/null)
[ "$n" = 11 ] && ok "rankfile: 11 ranks on localhost" || bad "rankfile: $(cat run/rankfile)"
grep -q -- "--rankfile run/rankfile -np 11 --output-filename run/logs" launch.out \
  && ok "mpirun line: $(grep '^launch: .*--rankfile' launch.out | cut -c1-150)..." || bad "mpirun line: $(cat launch.out)"
grep -q '"type":"summary"' run/metrics.jsonl 2>/dev/null && ok "metrics.jsonl has the summary" || bad "no summary"
nlog=0
for r in $(seq 0 10); do
  d="run/logs/1/rank.$(printf %02d "$r")"
  [ -f "$d/stdout" ] && [ -f "$d/stderr" ] && nlog=$((nlog + 1))
done
[ $nlog -eq 11 ] && ok "11 per-rank log folders (stdout, stderr)" || bad "per-rank logs: $nlog of 11: $(find run/logs | head)"
# The master prints every rank's ready line (host and GL renderer) and the frames.
nready=$(grep -c "^cave run: ready: " run/logs/1/rank.00/stdout 2>/dev/null)
[ "$nready" = 11 ] && grep -q "^frame 1:" run/logs/1/rank.00/stdout && ok "rank 0's log: 11 ready lines, the frames" \
  || bad "rank 0 log: $nready ready lines: $(head -3 run/logs/1/rank.00/stdout)"

# A problem is found by cave run --check before mpirun starts.
timeout 60 bash "$SRC/cluster/launch.sh" "$CFG" --scene missing.prt -o bad >b.out 2>b.err; rc=$?
[ $rc -eq 2 ] && grep -q "missing.prt" b.err && [ ! -d bad/logs ] && ok "bad option: rc 2 before mpirun" \
  || bad "bad option: rc $rc $(cat b.err)"

echo "launch: $pass passed, $fail failed"
[ $fail -eq 0 ]
