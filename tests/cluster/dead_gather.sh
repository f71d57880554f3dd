#!/usr/bin/env bash
# A dead gather rank must not kill the CAVE (issue 15, deliverable 6;
# docs/dead-rank.md).  Runs under `mpirun --enable-recovery` (without it Open
# MPI ends the whole job: test_cluster.sh checks that), --lcd-budget 2400,
# --lcd-wait (the run holds after --frames until the LCD has its budget):
#  1. reference: 13 ranks (master, 10 wall-eyes of cave5.json, gather-only
#     ranks 11 and 12, --no-idle-lcd: the two gather ranks render every LCD
#     round), nothing killed;
#  2. the same with rank 12 SIGKILLed once 10 frames are written (early: it
#     must still owe rounds; the gather ranks are fast): the walls go
#     on, rank 12 is named dead on stderr and in the metrics, its rounds are
#     shared (rank 11 renders them), the LCD reaches its budget and lcd.exr is
#     the same bytes as the reference's, the job ends by itself;
#  3. 12 ranks (one gather rank, the wall-eyes' idle LCD threads on): rank 11
#     SIGSTOPped after 4 frames until it is declared dead, then SIGCONTed: its
#     rounds left go to the wall-eyes, it leaves by itself when it runs again,
#     the LCD is again the reference's bytes (another rank count), the job ends
#     by itself;
#  4. a SIGKILLed wall-eye (rank 3), without the swap lock, with it
#     (--barrier) and scheduled swaps, and with --swap-sync barrier: the run
#     stops by itself, naming it on stderr and in the summary's stop_reason
#     and dead_ranks, and the job ends.
# Prints the measured figures.
# Usage: dead_gather.sh CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
CAVE=$(realpath "$1"); WORK="$2"; SRC="$(realpath "$3")"; MPIEXEC="${4:-mpirun}"
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK"
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
[ -n "${ASAN_OPTIONS:-}" ] && export ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0"
XS=(); for v in ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS; do [ -n "${!v:-}" ] && XS+=(-x "$v"); done
CFG="$SRC/configs/caves/cave5.json"
"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null \
  || { echo "FAIL: bake"; exit 1; }
cat > still.json <<'JSON'
{"description": "standing still", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 30, "weights": [1]}, {"t": 10, "yaw": 30}]}
JSON
BUDGET=2400
COMMON=(--scene scene.prt --size 48 --lcd-size 40x30 --lcd-spp 4 --lcd-budget $BUDGET --patches 8 --quiet
        --drive still.json --max-fps 10 --timeout-ms 1500 --gather-timeout 3)
now() { date +%s.%N; }
since() { python3 -c "print('%.1f' % ($(now) - $1))"; }
# start NP DIR ARGS...: a run in the background (mpid)
start() {
  local np=$1 dir=$2; shift 2
  rm -rf "$dir"
  timeout 900 "$MPIEXEC" --oversubscribe --enable-recovery -x OMP_NUM_THREADS -x LP_NUM_THREADS "${XS[@]}" \
    -np "$np" "$CAVE" run --http off "$CFG" "${COMMON[@]}" "$@" -o "$dir" >"$dir.out" 2>"$dir.err" &
  mpid=$!
}
nframes() { local n; n=$(grep -c '"type":"frame"' "$1/metrics.jsonl" 2>/dev/null); echo "${n:-0}"; }
nrounds() { tail -1 "$1/metrics.jsonl" 2>/dev/null | python3 -c 'import json, sys
try: print(json.loads(sys.stdin.read())["lcd"]["rounds"])
except Exception: print(0)'; }
# wait_frames DIR RANK N: until RANK's pid file is there and N frames are written
wait_frames() {
  for i in $(seq 1 1200); do
    [ -s "$1/pids/rank$2.pid" ] && [ "$(nframes "$1")" -ge "$3" ] && return 0
    kill -0 $mpid 2>/dev/null || return 1
    sleep 0.25
  done
  return 1
}
# finish S: waits for the job at most S s; ended=1 if it ended by itself
# (rc its status), else the ranks still running are listed and it is ended
finish() {
  local dir=$1 lim=$2 n=0
  while kill -0 $mpid 2>/dev/null && [ $n -lt $((lim * 10)) ]; do sleep 0.1; n=$((n + 1)); done
  ended=1
  if kill -0 $mpid 2>/dev/null; then
    ended=0
    echo "NOTE: $dir: ranks still running after ${lim} s: $(for r in $(seq 0 12); do
      q=$(cat "$dir/pids/rank$r.pid" 2>/dev/null); [ -n "$q" ] && kill -0 "$q" 2>/dev/null && echo -n "$r "; done)"
    kill -TERM $mpid; sleep 5; kill -KILL $mpid 2>/dev/null
  fi
  wait $mpid; rc=$?
}
# summary DIR KEY: a field of the summary line
summary() { python3 -c 'import json, sys
s = [json.loads(l) for l in open(sys.argv[1])]
s = [l for l in s if l.get("type") == "summary"]
v = s[-1] if s else {}
for k in sys.argv[2].split("."): v = v.get(k, {}) if isinstance(v, dict) else {}
print(json.dumps(v))' "$1/metrics.jsonl" "$2" 2>/dev/null; }

# A live wall-eye declared dead stops a run (a host loaded by other jobs can
# hold one past --gather-timeout): parts 1-3 are run once more then.
false_death() {
  grep -q 'stopping: rank [0-9]* (wall-eye' "$1.err" || return 1
  echo "NOTE: $1: a live wall-eye declared dead (loaded host): $(grep -o 'stopping: rank [^:]*: declared dead' "$1.err" | head -1); once more"
}

# --- 1. the reference: nothing killed ------------------------------------------
for attempt in 1 2; do
  start 13 ref --no-idle-lcd --frames 20 --lcd-wait
  finish ref 300
  false_death ref || break
done
r=$(summary ref lcd_rounds)
[ "$ended" = 1 ] && [ "$r" = "$BUDGET" ] && [ -s ref/lcd.exr ] \
  && ok "reference: $r rounds, $(summary ref frames) frames" \
  || { bad "reference run: ended $ended, status $rc, lcd_rounds $r; $(tail -2 ref.err)"; echo "$pass passed, $fail failed"; exit 1; }

# --- 2. a SIGKILLed gather rank ------------------------------------------------
for attempt in 1 2; do
  start 13 run --no-idle-lcd --frames 150 --lcd-wait
  wait_frames run 12 10 || echo "NOTE: the run did not reach 10 frames"
  before=$(nframes run); r_kill=$(nrounds run)
  t0=$(now)
  kill -9 "$(cat run/pids/rank12.pid)" 2>/dev/null || echo "NOTE: no rank 12 to kill"
  td=""
  while kill -0 $mpid 2>/dev/null; do
    [ -z "$td" ] && grep -q 'rank 12 (gather-only).*declared dead' run.err && td=$(since "$t0") && nd=$(nframes run)
    [ "$(since "$t0" | cut -d. -f1)" -ge 300 ] && break
    sleep 0.1
  done
  finish run 1
  false_death run || break
done
echo "rank 12 killed at frame $before with $r_kill of $BUDGET LCD rounds summed"
[ -n "$td" ] && echo "declared dead $td s after the kill, $((nd - before)) frames meanwhile"
echo "mpirun status $rc, $(since "$t0") s after the kill"
[ "$ended" = 1 ] && [ $rc -eq 0 ] && ok "the job ended by itself, status 0" || bad "mpirun status $rc, ended $ended"
grep -q 'rank 12 (gather-only)[^:]*: declared dead' run.err \
  && ok "stderr names the dead rank: $(grep -o 'rank 12 (gather-only)[^;]*' run.err | head -1)" \
  || bad "stderr does not name rank 12: $(tail -3 run.err)"
[ "$r_kill" -lt "$BUDGET" ] || bad "the budget was summed before the kill: nothing to share"
python3 - run/metrics.jsonl "$before" "$BUDGET" <<'PY' && ok "$(cat figures.txt)" || bad "$(cat figures.txt)"
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1])]
fr = [l for l in lines if l.get("type") == "frame"]
su = [l for l in lines if l.get("type") == "summary"]
k, budget = int(sys.argv[2]), int(sys.argv[3])
msg, ok = [], True
if not su:
    msg.append("no summary"); ok = False
else:
    s = su[-1]
    msg.append("summary: %d frames, dead_ranks %s, lcd_rounds %d of %d" % (s["frames"], s.get("dead_ranks"), s.get("lcd_rounds", -1), budget))
    ok &= s.get("dead_ranks") == [12] and s.get("lcd_rounds") == budget
after = fr[k:]
msg.append("%d frames after the kill" % len(after))
ok &= len(after) >= 20
first_dead = next((f for f in after if f.get("dead_ranks") == [12]), None)
if first_dead is None:
    msg.append("no frame line lists rank 12 dead"); ok = False
else:
    msg.append("first frame line naming it: %d" % first_dead["frame"])
    r0 = fr[k - 1]["lcd"]["rounds"] if k else 0
    rd = first_dead["lcd"]["rounds"]
    full = next((f["frame"] for f in fr if f["lcd"]["rounds"] == budget), None)
    msg.append("LCD rounds: %d at the kill, %d when declared dead, %d at the end (budget at frame %s)" % (r0, rd, fr[-1]["lcd"]["rounds"], full))
    late = sum(1 for f in after if f["late_walleyes"] > 0)
    msg.append("%d frames with late wall-eyes after the kill" % late)
    a = su[-1].get("lcd_allreduce", {}) if su else {}
    msg.append("allreduce abandoned: %s; point-to-point %d, of them rank 12's shared %d; rendered again %d" % (
        a.get("abandoned"), a.get("p2p_rounds", 0), a.get("shared_rounds", 0), a.get("duplicate_rounds", 0)))
    ok &= a.get("abandoned") is True and a.get("p2p_rounds", 0) > 0 and a.get("shared_rounds", 0) > 0
open("figures.txt", "w").write("; ".join(msg))
sys.exit(0 if ok else 1)
PY
cmp -s run/lcd.exr ref/lcd.exr && ok "lcd.exr after the kill is the reference's bytes" \
  || bad "lcd.exr after the kill differs from the reference's"
echo "stderr: $(grep -v -e '^\s*$' -e PMIX run.err | head -8 | cut -c1-200 | tr '\n' '|')"

# --- 3. a stalled gather rank (SIGSTOP, then SIGCONT) ----------------------------
for attempt in 1 2; do
  start 12 stall --frames 150 --lcd-wait
  wait_frames stall 11 4 || echo "NOTE: the stall run did not reach 4 frames"
  r_stop=$(nrounds stall)
  t0=$(now)
  kill -STOP "$(cat stall/pids/rank11.pid)" 2>/dev/null || echo "NOTE: no rank 11 to stop"
  for i in $(seq 1 600); do grep -q 'rank 11 (gather-only).*declared dead' stall.err && break; sleep 0.1; done
  td=$(since "$t0")
  sleep 1
  kill -CONT "$(cat stall/pids/rank11.pid)" 2>/dev/null
  tc=$(now)
  finish stall 300
  false_death stall || break
done
echo "rank 11 stopped with $r_stop of $BUDGET rounds, declared dead after $td s, continued 1 s later; job ended $(since "$tc") s after the SIGCONT (ended $ended, status $rc)"
grep -q 'rank 11: the master declared this rank dead' stall.err \
  && ok "the stalled rank, running again, leaves: $(grep -o 'rank 11: the master declared[^:]*' stall.err | head -1)" \
  || bad "rank 11 did not say it leaves: $(grep -v PMIX stall.err | tail -3)"
r=$(summary stall lcd_rounds); d=$(summary stall dead_ranks); sh=$(summary stall lcd_allreduce.shared_rounds)
# (its share, 1/11 of the budget, may be all in before the stop: gather ranks
# are faster than the wall-eyes' idle threads; the kill above requires sharing)
[ "$ended" = 1 ] && [ "$r" = "$BUDGET" ] && [ "$d" = "[11]" ] \
  && ok "stall: job ended by itself; lcd_rounds $r, dead_ranks $d, rank 11's rounds rendered by the wall-eyes: $sh" \
  || bad "stall: ended $ended, lcd_rounds $r, dead_ranks $d, shared $sh"
cmp -s stall/lcd.exr ref/lcd.exr && ok "lcd.exr (12 ranks, stalled gather rank) is the reference's bytes (13 ranks)" \
  || bad "lcd.exr after the stall differs from the reference's"

# --- 4. a dead wall-eye: the run stops by itself, naming it -----------------------
# (no swap lock, the headless default; the swap lock (--barrier) with
# scheduled swaps; with --swap-sync barrier, where the others wait in an MPI
# barrier with the dead one: given up once it is known dead)
for mode in none scheduled barrier; do
  case $mode in none) SW=() ;; *) SW=(--barrier --swap-sync $mode) ;; esac
  start 12 wall --frames 0 "${SW[@]}"
  wait_frames wall 3 10 || bad "the wall run did not reach 10 frames"
  t0=$(now)
  kill -9 "$(cat wall/pids/rank3.pid)" 2>/dev/null || bad "no rank 3 to kill"
  finish wall 60
  dt=$(since "$t0")
  reason=$(tail -1 wall/metrics.jsonl | python3 -c "import json,sys; l=json.loads(sys.stdin.read()); print(l.get('type'), l.get('stop_reason'), l.get('dead_ranks'))")
  # (the master exits with status 1, but mpirun --enable-recovery reports 0
  # whatever its ranks' status, even after MPI_Abort: measured, docs/dead-rank.md)
  grep -q 'stopping: rank 3 (wall-eye of wall [0-9]*) silent' wall.err \
    && [ "${reason#summary rank 3 }" != "$reason" ] && [ "$ended" = 1 ] \
    && ok "swap lock $mode: a dead wall-eye stops the run; the job ended ${dt} s after the kill (mpirun status $rc): $reason" \
    || bad "swap lock $mode: dead wall-eye: ended $ended, status $rc after ${dt} s; last line: $reason; $(grep -i 'rank 3' wall.err | head -2)"
done
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
