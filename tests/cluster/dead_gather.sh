#!/usr/bin/env bash
# Measures what Open MPI 4 does when a gather rank is SIGKILLed in a 13-rank
# `cave run` (issue 15, deliverable 6; results in docs/service.md): once with
# plain mpirun, once with `mpirun --enable-recovery`.  Prints, per mode, the
# seconds from the kill to mpirun's exit (or "still running" after WAIT s),
# the frames written after the kill, mpirun's status and its first message.
# Not a ctest: a measurement.  Usage: dead_gather.sh CAVE WORKDIR SOURCE_DIR [WAIT]
set -uo pipefail
CAVE=$(realpath "$1"); WORK="$2"; SRC="$(realpath "$3")"; WAIT=${4:-60}
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK"
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
CFG="$SRC/configs/caves/cave5.json"
"$CAVE" bake default -o scene.prt --bands 3 --rays 32 --bounces 1 --quiet >/dev/null || exit 1
cat > still.json <<'JSON'
{"description": "standing still", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 30, "weights": [1]}, {"t": 10, "yaw": 30}]}
JSON
COMMON=(--scene scene.prt --size 48 --lcd-size 40x30 --lcd-spp 4 --patches 8 --quiet
        --drive still.json --frames 0 --timeout-ms 1500)
for mode in plain recovery; do
  extra=(); [ $mode = recovery ] && extra=(--enable-recovery)
  mpirun --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS "${extra[@]}" -np 13 \
    "$CAVE" run "$CFG" "${COMMON[@]}" -o $mode >$mode.out 2>$mode.err &
  mpid=$!
  for i in $(seq 1 600); do
    [ -s $mode/pids/rank12.pid ] && [ "$(cat $mode/metrics.jsonl 2>/dev/null | grep -c '"type":"frame"')" -ge 3 ] && break
    sleep 0.5
  done
  before=$(grep -c '"type":"frame"' $mode/metrics.jsonl)
  t0=$(date +%s.%N)
  kill -9 "$(cat $mode/pids/rank12.pid)"
  end=""
  for i in $(seq 1 $((WAIT * 10))); do
    if ! kill -0 $mpid 2>/dev/null; then end=$(date +%s.%N); break; fi
    sleep 0.1
  done
  after=$(grep -c '"type":"frame"' $mode/metrics.jsonl)
  sleep 2
  left=$(for r in $(seq 0 12); do p=$(cat $mode/pids/rank$r.pid 2>/dev/null); [ -n "$p" ] && kill -0 $p 2>/dev/null && echo $r; done | tr '\n' ' ')
  if [ -n "$end" ]; then
    wait $mpid; rc=$?
    printf '%s: mpirun exited %.1f s after the kill, status %d; frames %d before, %d after\n' \
      $mode "$(python3 -c "print($end - $t0)")" $rc $before $((after - before))
  else
    printf '%s: still running %d s after the kill; frames %d before, %d after\n' \
      $mode $WAIT $before $((after - before))
    kill -TERM $mpid; sleep 10; kill -KILL $mpid 2>/dev/null; wait $mpid
  fi
  echo "  ranks alive 2 s after mpirun's exit or after the wait: ${left:-none}"
  python3 - $mode/metrics.jsonl $before <<'PY'
import json, sys
fr = [json.loads(l) for l in open(sys.argv[1])]
fr = [f for f in fr if f.get("type") == "frame"]
k = int(sys.argv[2])
if fr:
    r = [f["lcd"]["rounds"] for f in fr]
    last = min(i for i in range(len(r)) if r[i] == r[-1])
    late = [f["frame"] for f in fr[k:] if f["late_walleyes"] > 0]
    print("  LCD rounds: %d at the kill, %d at the end (reached at frame %d of %d);"
          " frames with late wall-eyes after the kill: %d, first %s"
          % (r[min(k, len(r)) - 1], r[-1], fr[last]["frame"], len(fr), len(late), late[:1]))
PY
  echo "  stderr: $(grep -v '^\s*$' $mode.err | head -12 | cut -c1-160 | tr '\n' '|')"
done
