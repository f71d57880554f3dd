#!/usr/bin/env bash
# Faults of issue 35 (docs/dead-rank.md, "Issue 35"), 11 ranks under mpirun:
#  (2) a full disk: the run stops naming it, metrics.jsonl stays JSON lines,
#      no temporary left, exit status not 0 (root: a 2 MB tmpfs; else skipped);
#  (4) SIGTERM to one wall-eye: it says so, the master stops the run
#      (summary interrupted, stop_reason naming the rank), exit status not 0;
#  (5) the .prt replaced while ranks 4 and 8 start (test hook
#      CAVE_TEST_LOAD_DELAY): the run refuses naming the ranks and the file;
#  (6) a second run into the same -o refuses naming the first's pid; the
#      first ends with one summary and JSON lines only;
#  (9) --metrics elsewhere: the last line names it; the out folder deleted:
#      the run stops saying so; the master SIGSTOPped 4 s: no frame with
#      every wall-eye late, the stall said and counted.
# Usage: test_faults.sh CAVE WORKDIR SRC [MPIEXEC]
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"; MPIEXEC="${4:-mpirun}"
source "$(dirname "${BASH_SOURCE[0]}")/mpi_common.sh"
COMMON=(--scene scene.prt --size 48 --no-lcd --present files)
start() { # start NAME ARGS...: mpirun 11 ranks in the background, pid in $job
  local name="$1"; shift
  timeout 300 "${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" "$@" >"$name.out" 2>"$name.err" &
  job=$!
}
wait_frame() { # wait_frame NAME N: until frame N is printed (60 s at most)
  for _ in $(seq 600); do grep -q "^frame $2:" "$1.out" 2>/dev/null && return 0; sleep 0.1; done; return 1
}
jsonl_ok() { # jsonl_ok FILE: every line JSON; prints the number of summaries
  python3 - "$1" <<'PY'
import json, sys
n = 0
for l in open(sys.argv[1]):
    n += json.loads(l).get("type") == "summary"
print(n)
PY
}
summary() { python3 -c "import json,sys; print(json.loads(open(sys.argv[1]).readlines()[-1]).get(sys.argv[2]))" "$@"; }

# (6) two runs into one folder; (9) the first with --metrics elsewhere names it
start one -o same --frames 40 --max-fps 8; one=$job
wait_frame one 2 || bad "run one did not start: $(tail -3 one.err)"
"${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" -o same --frames 3 >two.out 2>two.err; rc=$?
holder=$(cat same/pids/rank0.pid 2>/dev/null)
[ $rc -ne 0 ] && grep -q "same: another cave run (pid $holder on host" two.err && ! grep -q "^frame" two.out \
  && ok "a second run into the same -o refuses: '$(grep 'another cave run' two.err)'" \
  || bad "second run into the same -o: rc $rc, holder $holder: $(grep -v '^ \|^--' two.err | head -3)"
wait $one; rc=$?
n=$(jsonl_ok same/metrics.jsonl)
[ $rc -eq 0 ] && [ "$n" = 1 ] && [ ! -e same/.cave.lock ] && grep -q "metrics in same/metrics.jsonl" one.out \
  && ok "the first run ends alone: one summary, JSON lines only, the lock removed" \
  || bad "first run: rc $rc, summaries '$n', $(ls -a same | grep lock) $(tail -1 one.out)"

# (4) SIGTERM to wall-eye rank 3 alone
start term -o term --frames 0 --max-fps 8; j=$job
wait_frame term 3 && kill -TERM "$(cat term/pids/rank3.pid)"
t0=$(date +%s.%N); wait $j; rc=$?; t1=$(date +%s.%N)
[ $rc -ne 0 ] && grep -q "rank 3: SIGTERM alone" term.err && [ "$(summary term/metrics.jsonl interrupted)" = True ] \
  && summary term/metrics.jsonl stop_reason | grep -q "rank 3 (wall-eye of wall .*) got SIGTERM" \
  && ok "SIGTERM to wall-eye 3: said, the run stopped $(printf %.1f "$(echo "$t1 - $t0" | bc)") s later, stop_reason '$(summary term/metrics.jsonl stop_reason)'" \
  || bad "SIGTERM to one wall-eye: rc $rc, $(grep -v '^ \|^--' term.err | head -3)"

# (5) the .prt replaced while ranks 4 and 8 start
cp scene.prt first.prt
"$CAVE" bake default -o other.prt --tess 1 --bands 3 --rays 16 --bounces 1 --quiet >/dev/null
CAVE_TEST_LOAD_DELAY=6000:4,8 timeout 300 "${MPI[@]}" -x CAVE_TEST_LOAD_DELAY -np 11 "$CAVE" run "$CFG" \
  "${COMMON[@]}" -o swap --frames 3 >swap.out 2>swap.err & j=$!
for _ in $(seq 300); do [ -e swap/pids/rank0.pid ] && break; sleep 0.1; done
sleep 2.5; cp other.prt scene.tmp && mv scene.tmp scene.prt
wait $j; rc=$?
cp first.prt scene.prt
[ $rc -ne 0 ] && grep -q "scene.prt changed while the ranks started: ranks 4, 8 loaded another file" swap.err \
  && ! grep -q "^frame" swap.out && ok "a .prt replaced during the start: refused, '$(grep -o 'ranks 4, 8 loaded[^(]*' swap.err)'" \
  || bad "prt replaced: rc $rc, $(grep -v '^ \|^--' swap.err | head -3)"

# (9) the out folder deleted during the run
mkdir -p del
start del -o del/run --frames 0 --max-fps 8; j=$job
wait_frame del 3 && rm -rf del/run
wait $j; rc=$?
[ $rc -ne 0 ] && grep -q "del/run/metrics.jsonl was deleted during the run" del.err \
  && grep -q "metrics INCOMPLETE" del.out && ok "out folder deleted: the run stops, '$(grep -m1 'was deleted' del.err)'" \
  || bad "out folder deleted: rc $rc, $(grep -v '^ \|^--' del.err | head -3)"

# (9) the master stopped 4 s (--timeout-ms 2000): no frame with every wall-eye late
start stall -o stall --frames 150 --metrics stall.jsonl; j=$job
wait_frame stall 5 && { m=$(cat stall/pids/rank0.pid); kill -STOP "$m"; sleep 4; kill -CONT "$m"; }
wait $j; rc=$?
worst=$(python3 -c "import json; print(max(d.get('late_walleyes',0) for d in map(json.loads, open('stall.jsonl')) if d.get('type')=='frame'))")
# (the stall is said and counted when the stop lands in the master's waits, where it made every wall-eye late)
[ $rc -eq 0 ] && [ "$worst" -lt 10 ] && grep -q "metrics in stall.jsonl" stall.out \
  && ok "master stopped 4 s: most late wall-eyes in a frame $worst (not 10); master_stalls $(summary stall.jsonl master_stalls): '$(grep -m1 'did not run' stall.err)'" \
  || bad "master stopped: rc $rc, worst late $worst, $(grep -v '^ \|^--' stall.err | head -3)"

# (2) a full disk (root only)
if [ "$(id -u)" -eq 0 ]; then
  mkdir -p full && mount -t tmpfs -o size=2m tmpfs full && trap 'umount -l "$WORK/full" 2>/dev/null' EXIT
  fallocate -l 1850k full/fill
  timeout 120 "${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" --size 64 -o full/run --frames 10 \
    --write-every 1 >full.out 2>full.err; rc=$?
  n=$(jsonl_ok full/run/metrics.jsonl 2>&1); tmp=$(find full -name '*.tmp*' | wc -l)
  # the stop names the disk: in the master's line, or (when a wall-eye's failure stops the run
  # first) as "N KB free on its disk" after the rank's own "No space left on device" line
  if [ $rc -ne 0 ] && [ $rc -ne 124 ] && grep -q "No space left on device" full.err \
     && grep -Eq "stopping: (.*No space left on device|.*KB free on its disk)" full.err \
     && [[ "$n" =~ ^[01]$ ]] && [ "$tmp" -eq 0 ] \
     && { [ "$n" = 1 ] && [ "$(summary full/run/metrics.jsonl interrupted)" = True ] || grep -q "metrics INCOMPLETE" full.out; }; then
    ok "full disk: the run stops, '$(grep -m1 'stopping:' full.err)', metrics JSON lines ($n summary)"
  else
    bad "full disk: rc $rc (124: hung), summaries '$n', $tmp temporaries, $(grep -v '^ \|^--' full.err | head -4)"
  fi
else
  echo "SKIP: full disk part (needs root for mount -t tmpfs)"
fi
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
