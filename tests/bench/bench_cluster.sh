#!/usr/bin/env bash
# Benchmark of the cluster service (issue 6): frames per second for 11 ranks
# on one machine at 360x360 and 720x720 per wall-eye, the master's per-frame
# overhead (p50/p99), and the LCD panel's time to 1% relative RMS (the
# gather's own error estimate) against the number of gather-only ranks.
# Usage: bench_cluster.sh BUILD_DIR [SCENE.prt] [FRAMES]
#   SCENE: a baked scene (default: bakes the 571K-triangle cabin, tess 8,
#   with few rays: raster speed does not depend on transfer accuracy).
set -euo pipefail
BUILD="${1:?usage: bench_cluster.sh BUILD_DIR [SCENE.prt] [FRAMES]}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
CAVE="$BUILD/cave"
WORK="${BENCH_WORK:-/tmp/bench_cluster}"
mkdir -p "$WORK"
SCENE="${2:-}"
FRAMES="${3:-12}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1 LP_NUM_THREADS=1
MPI=(mpirun --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS)
if [ -z "$SCENE" ]; then
  SCENE="$WORK/cabin8.prt"
  if [ ! -s "$SCENE" ]; then
    printf '{"mesh": {"source": "cabin", "tess": 8}, "prt": {"bands": 5, "rays": 16, "bounces": 1}}\n' > "$WORK/cabin8.json"
    "$CAVE" bake "$WORK/cabin8.json" -o "$SCENE" --quiet
  fi
fi
CFG="$ROOT/configs/caves/cave5.json"
DRIVE="$ROOT/configs/drives/default.json"
HEAD="$ROOT/configs/heads/default.txt"
summary() { python3 -c "
import json,sys
s=[json.loads(l) for l in open(sys.argv[1]) if '\"summary\"' in l][-1]
print(' | '.join(str(round(s.get(k,0),3)) for k in sys.argv[2:]))" "$@"; }

echo "| pixels per wall-eye | ranks | frames | fps (p50) | frame ms p50 | frame ms p99 | master ms p50 | master ms p99 |"
echo "|---|---|---|---|---|---|---|---|"
for size in 360 720; do
  out="$WORK/fps$size"
  "${MPI[@]}" -np 11 "$CAVE" run "$CFG" --scene "$SCENE" --drive "$DRIVE" --head-path "$HEAD" \
    --frames "$FRAMES" --size "$size" --write-every 0 --no-idle-lcd --quiet -o "$out" >/dev/null
  echo "| $size x $size | 11 | $FRAMES | $(summary "$out/metrics.jsonl" fps frame_ms_p50 frame_ms_p99 master_ms_p50 master_ms_p99) |"
done
echo
[ "${SKIP_LCD:-0}" = 1 ] && exit 0
echo "| gather-only ranks | LCD rounds summed | seconds to 1% rel. RMS | final rel. RMS |"
echo "|---|---|---|---|"
LCD_SIZE="${LCD_SIZE:-400x300}"
LCD_LIMIT="${LCD_LIMIT:-600}"
for g in ${GATHER:-0 2 4}; do
  out="$WORK/lcd$g"
  np=$((11 + g))
  "${MPI[@]}" -np "$np" "$CAVE" run "$CFG" --scene "$SCENE" --frames 0 --size 64 --write-every 0 \
    --no-compensation --lcd-budget 400 --lcd-size "$LCD_SIZE" --max-fps 2 --quiet -o "$out" >/dev/null 2>&1 &
  job=$!
  t0=$(date +%s.%N); t1=""
  for i in $(seq 1 "$LCD_LIMIT"); do
    sleep 1
    r=$(tail -1 "$out/metrics.jsonl" 2>/dev/null | python3 -c "import json,sys
try: print(json.loads(sys.stdin.read())['lcd'].get('rel_rms', 1))
except Exception: print(1)")
    if python3 -c "import sys; sys.exit(0 if float('$r') <= 0.01 else 1)"; then t1=$(date +%s.%N); break; fi
  done
  kill -TERM "$(cat "$out/pids/rank0.pid")"; wait $job || true
  rounds=$(grep -o '"lcd_rounds":[0-9]*' "$out/metrics.jsonl" | tail -1 | grep -o '[0-9]*$')
  fin=$(grep -o '"lcd_rel_rms":[0-9.e-]*' "$out/metrics.jsonl" | tail -1 | grep -o '[0-9.e-]*$')
  dt=$( [ -n "$t1" ] && python3 -c "print(round($t1 - $t0, 1))" || echo "> $LCD_LIMIT")
  echo "| $g | $rounds | $dt | $fin |"
done
