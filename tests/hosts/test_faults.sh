#!/usr/bin/env bash
# Faults across hosts (issue 35, deliverable 4; ctest hosts_faults;
# docs/dead-rank.md "Several hosts"): three simulated hosts, cave1 (master,
# wall-eyes 1-6, gather rank 12), cave2 (wall-eyes 7-10) and farm1 (gather
# rank 11), the 2-host CAVE variant without windows, cluster/launch.sh with
# mpirun --enable-recovery, --gather-timeout 5.  A link down is farm1's,
# cave2's or cave1's port on the switch set down (a pulled cable).
#  1. reference: nothing down (--no-idle-lcd: the two gather ranks render every
#     LCD round), the LCD image;
#  2. farm1's link down after 8 frames: rank 11 declared dead within
#     --gather-timeout (+1 s), named with its host; the walls go on; the LCD
#     reaches its budget and is the reference's bytes; the job ends and
#     farm1's rank leaves by itself (the master's silence);
#  3. farm1's link down, back 1 s after the death: the stated policy (not taken
#     back: it reads its death notice and leaves), the LCD the reference's;
#  4. cave2's link down (wall-eyes): the run stops naming rank, host and
#     output; the job ends; cave2's ranks leave by themselves;
#  5. cave1's link down (the master's host): every rank on cave2 exits within
#     2 x --gather-timeout + 5 s; the master stops; nothing hangs.
# (4 and 5 without farm1's gather ranks: 11 ranks.)  A start that shows no
# frame within 60 s, and a reference run that lost a live rank, are run once
# more, said with a NOTE line: on a loaded 2-core machine Open MPI 4.1.4's TCP
# traffic between the simulated hosts can stick (docs/dead-rank.md).
# Prints the measured times.  Skips (exit 77, one line) without root or ip.
# Usage: test_faults.sh CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
WORK="$2"; MPIEXEC="${4:-mpirun}"
source "$(dirname "${BASH_SOURCE[0]}")/hosts_common.sh"
S=48; TMO=5; BOUND=$((2 * TMO + 5))
variant two.json $S
hosts_start "$((10 * S))x$S" cave1 cave2 farm1
printf 'farm1 slots=1\ncave1 slots=1\n' > farm.txt
cat > still.json <<'JSON'
{"description": "standing still", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 30, "weights": [1]}, {"t": 10, "yaw": 30}]}
JSON
export CAVE_FARM="$WORK/farm.txt" CAVE_MPI_EXTRA="--enable-recovery" CAVE_PREFLIGHT=0
BUDGET=1200
COMMON=(--scene "$WORK/scene.prt" --size $S --lcd-size 40x30 --lcd-spp 4 --lcd-budget $BUDGET --patches 8 --quiet
        --drive still.json --max-fps 10 --timeout-ms 1500 --gather-timeout $TMO --present files --no-idle-lcd)
now() { date +%s.%N; }
since() { python3 -c "print('%.1f' % ($(now) - $1))"; }
nframes() { local n; n=$(grep -c '"type":"frame"' "$1/metrics.jsonl" 2>/dev/null); echo "${n:-0}"; }
summary() { python3 -c 'import json, sys
s = [json.loads(l) for l in open(sys.argv[1])]
s = [l for l in s if l.get("type") == "summary"]
v = s[-1] if s else {}
for k in sys.argv[2].split("."): v = v.get(k, {}) if isinstance(v, dict) else {}
print(json.dumps(v))' "$1/metrics.jsonl" "$2" 2>/dev/null; }
# ranks_on HOST: the cave processes running on HOST
ranks_on() { for p in $(ip netns pids "$TAG-$1" 2>/dev/null); do [ "$(cat /proc/$p/comm 2>/dev/null)" = cave ] && echo "$p"; done; }
# start NAME ARGS...: the launch in the background (job), on cave1
start() {
  local name=$1; shift
  rm -rf "$name"
  timeout 300 "$HOSTS_SH" launch "$H" two.json "${COMMON[@]}" "$@" -o "$WORK/$name" >"$name.out" 2>"$name.err" &
  job=$!
}
# wait_frames NAME N: until N frames are written (60 s at most)
wait_frames() {
  for _ in $(seq 300); do [ "$(nframes "$1")" -ge "$2" ] && return 0; kill -0 $job 2>/dev/null || return 1; sleep 0.2; done
  return 1
}
# start_frames NAME N ARGS...: start, until N frames; once more when the first
# start never reached them: Open MPI 4.1.4's TCP connections between the
# simulated hosts can stick in their handshake on a loaded machine (the
# frame-0 reports never arrive; docs/dead-rank.md, "Several hosts")
start_frames() {
  local name=$1 n=$2; shift 2
  start "$name" "$@"
  wait_frames "$name" "$n" && return 0
  echo "NOTE: $name: no frame $n after 60 s (a stuck start, $(nframes "$name") frames): once more"
  kill -TERM $job 2>/dev/null; sleep 2; kill -KILL $job 2>/dev/null; wait $job
  start "$name" "$@"
  wait_frames "$name" "$n"
}
# finish S: waits S s at most for the launch; ended=1 if it ended (rc its status)
finish() {
  local n=0
  while kill -0 $job 2>/dev/null && [ $n -lt $(($1 * 10)) ]; do sleep 0.1; n=$((n + 1)); done
  ended=1; kill -0 $job 2>/dev/null && { ended=0; kill -TERM $job; sleep 2; kill -KILL $job 2>/dev/null; }
  wait $job; rc=$?
}
# gone_within HOST S: 0 when no cave process runs on HOST within S s (t_gone: when)
gone_within() {
  local t=$(now)
  while [ -n "$(ranks_on "$1")" ]; do [ "$(since "$t" | cut -d. -f1)" -ge "$2" ] && return 1; sleep 0.1; done
  return 0
}

# --- 1. reference ---------------------------------------------------------------
for attempt in 1 2; do
  start_frames ref 1 --frames 10 --lcd-wait
  finish 200
  r=$(summary ref lcd_rounds)
  [ "$ended" = 1 ] && [ "$r" = "$BUDGET" ] && break
  echo "NOTE: reference run $attempt: ended $ended, $r rounds ($(grep -o 'rank [0-9]* [^:]*: declared dead\|nothing from the master' ref.err | head -2 | tr '\n' ' ')): once more"
done
[ "$ended" = 1 ] && [ "$r" = "$BUDGET" ] && [ -s ref/lcd.exr ] && ok "reference: 13 ranks on 3 hosts, $r LCD rounds" \
  || { bad "reference: ended $ended rc $rc, lcd_rounds $r: $(grep -v '^ \|PMIX' ref.err | tail -3)"; hosts_stop; exit 1; }

# --- 2. the gather host's link down ------------------------------------------------
start_frames gl 8 --frames 100 --lcd-wait || bad "the gather run did not reach 8 frames"
f0=$(nframes gl); t0=$(now)
hosts_link "$H" farm1 down
td=""; tn=""
while kill -0 $job 2>/dev/null && [ "$(since "$t0" | cut -d. -f1)" -lt 200 ]; do
  if [ -z "$td" ] && grep -q 'rank 11 (gather-only) silent.*declared dead' gl.err; then td=$(since "$t0"); fd=$(nframes gl); fi
  [ -n "$td" ] && [ -z "$tn" ] && [ "$(nframes gl)" -gt "$fd" ] && tn=$(since "$t0")
  sleep 0.05
done
finish 1; tend=$(since "$t0")
gone_within farm1 $BOUND; g=$?; tgone=$(since "$t0")
hosts_link "$H" farm1 up
echo "farm1 down at frame $f0: named dead after ${td:-never} s, the walls' next frame after ${tn:-never} s, $(( $(nframes gl) - f0 )) frames after the link down; job ended after $tend s; farm1's rank gone after $tgone s"
grep -q 'rank 11 (gather-only) silent for [0-9.]* s (host farm1): declared dead' gl.err && [ -n "$td" ] \
  && python3 -c "import sys; sys.exit(0 if $td <= $TMO + 1.5 else 1)" \
  && ok "gather host down: named within --gather-timeout $TMO s (+ the poll): '$(grep -o 'rank 11 (gather-only)[^;]*' gl.err | head -1)' after $td s" \
  || bad "gather host down: named after ${td:-never} s: $(grep -v '^ \|PMIX' gl.err | head -3)"
d=$(summary gl dead_ranks); r=$(summary gl lcd_rounds)
[ "$ended" = 1 ] && [ "$d" = "[11]" ] && [ "$r" = "$BUDGET" ] && [ $g -eq 0 ] && [ -n "$tn" ] \
  && ok "gather host down: the walls went on ($(( $(nframes gl) - f0 )) frames), the job ended, farm1's rank left; dead_ranks $d, $r rounds" \
  || bad "gather host down: ended $ended, dead $d, rounds $r, farm1 ranks left: $(ranks_on farm1)"
cmp -s gl/lcd.exr ref/lcd.exr && ok "gather host down: lcd.exr the reference's bytes" || bad "gather host down: lcd.exr differs"
grep -q "nothing from the master for" gl.err || echo "(farm1's rank said it leaves on its host only: its stderr went with the link)"

# --- 3. the gather host's link back after its death ---------------------------------
start_frames gb 8 --frames 100 --lcd-wait || bad "the link-back run did not reach 8 frames"
t0=$(now); hosts_link "$H" farm1 down
for _ in $(seq 200); do grep -q 'rank 11 (gather-only) silent.*declared dead' gb.err && break; sleep 0.05; done
sleep 1; hosts_link "$H" farm1 up; tb=$(now)
finish 200
echo "farm1 down, named after $(grep -o 'rank 11 (gather-only) silent for [0-9.]* s' gb.err | head -1 | grep -o '[0-9.]* s'), back 1 s later; the job ended $(since "$tb") s after"
d=$(summary gb dead_ranks); r=$(summary gb lcd_rounds)
[ "$ended" = 1 ] && [ "$d" = "[11]" ] && [ "$r" = "$BUDGET" ] && gone_within farm1 $BOUND \
  && grep -q "rank 11: the master declared this rank dead" gb.err \
  && ok "link back: rank 11 not taken back, it read its death notice and left ('$(grep -o 'rank 11: the master declared[^:]*' gb.err | head -1)'); $r rounds" \
  || bad "link back: ended $ended, dead $d, rounds $r: $(grep -v '^ \|PMIX' gb.err | grep 'rank 11' | head -3)"
cmp -s gb/lcd.exr ref/lcd.exr && ok "link back: lcd.exr the reference's bytes" || bad "link back: lcd.exr differs"

# --- 4. a wall-eye host's link down (11 ranks: no gather rank) ---------------------------
unset CAVE_FARM
start_frames wl 8 --frames 0 --no-lcd || bad "the wall run did not reach 8 frames"
t0=$(now); hosts_link "$H" cave2 down
finish 120; tend=$(since "$t0")
gone_within cave2 $BOUND; g=$?; tgone=$(since "$t0")
hosts_link "$H" cave2 up
reason=$(summary wl stop_reason)
echo "cave2 down: stop '$reason'; job ended after $tend s, cave2's ranks gone after $tgone s"
[ "$ended" = 1 ] && [ $g -eq 0 ] && echo "$reason" | grep -q 'rank [789]\|rank 10' \
  && grep -q 'stopping: rank [0-9]* (wall-eye of wall [0-9]) silent for [0-9.]* s (host cave2, output [6-9]: \(floor\|ceiling\), \(left\|right\) eye): declared dead' wl.err \
  && [ "$(summary wl interrupted)" = true ] \
  && ok "wall-eye host down: the run stops (the policy), $reason; job ended after $tend s, cave2's ranks left" \
  || bad "wall-eye host down: ended $ended, cave2 ranks left: $(ranks_on cave2), reason $reason"

# --- 5. the master's host's link down ------------------------------------------------------
start_frames ml 8 --frames 0 --no-lcd || bad "the master run did not reach 8 frames"
t0=$(now); hosts_link "$H" cave1 down
gone_within cave2 $BOUND; g2=$?; t2=$(since "$t0")
gf=0; tf="-"
finish 60; tend=$(since "$t0")
hosts_link "$H" cave1 up
echo "cave1 down: cave2's ranks gone after $t2 s, the job (mpirun, master) ended after $tend s"
[ $g2 -eq 0 ] && [ $gf -eq 0 ] && [ "$ended" = 1 ] && grep -q "stopping: rank" ml.err \
  && ok "master host down: every rank on cave2 exited within $BOUND s (2 x --gather-timeout + 5), the master stopped, mpirun ended after $tend s" \
  || bad "master host down: cave2 left $(ranks_on cave2), farm1 left $(ranks_on farm1), ended $ended: $(grep -v '^ \|PMIX' ml.err | head -3)"

hosts_stop
hosts_clean
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
