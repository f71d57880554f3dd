#!/usr/bin/env bash
# Benchmark of presentation on real windows (issue 11), 11 ranks on this
# machine under Xvfb (started here with xvfb-run):
#   - frame rate with windows against files only, at 240^2 and 360^2 per
#     wall-eye (same frames, --clock sim; files: --write-every 0);
#   - swap skew p50/p99/max (us) of the 10 render ranks for each swap lock:
#     scheduled (default), barrier (MPI_Ibarrier), and none (files, no lock);
#   - motion-to-photon estimate and head prediction error on the wall clock
#     with the recorded head path (the path is the truth at scan-out).
# Usage: bench_present.sh BUILD_DIR [FRAMES]
set -euo pipefail
BUILD="${1:?usage: bench_present.sh BUILD_DIR [FRAMES]}"
FRAMES="${2:-40}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
if [ -z "${CAVE_IN_XVFB:-}" ]; then
  export CAVE_IN_XVFB=1
  exec xvfb-run -n 141 -a -s "-screen 0 1920x1080x24" bash "$0" "$@"
fi
CAVE="$BUILD/cave"
WORK="${BENCH_WORK:-/tmp/bench_present}"
mkdir -p "$WORK"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1 LP_NUM_THREADS=1
MPI=(mpirun --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS -x DISPLAY -x XAUTHORITY)
SCENE="$WORK/default.prt"
[ -s "$SCENE" ] || "$CAVE" bake default -o "$SCENE" --bands 5 --rays 64 --bounces 1 --quiet
CFG="$ROOT/configs/caves/cave5.json"
DRIVE="$ROOT/configs/drives/default.json"
HEAD="$ROOT/configs/heads/default.txt"
get() { python3 -c "
import json,sys
s=[json.loads(l) for l in open(sys.argv[1]) if '\"summary\"' in l][-1]
print(' | '.join(('%.3g' % s[k]) if k in s else '-' for k in sys.argv[2:]))" "$@"; }
run() { local out="$1"; shift; "${MPI[@]}" -np 11 "$CAVE" run "$CFG" --scene "$SCENE" --drive "$DRIVE" --head-path "$HEAD" \
          --frames "$FRAMES" --no-idle-lcd --quiet -o "$WORK/$out" "$@" >/dev/null; }

echo "machine: $(nproc --all) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs); load $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| pixels per wall-eye | present | swap lock | fps (p50) | frame ms p50 | frame ms p99 | swap skew us p50 | p99 | max |"
echo "|---|---|---|---|---|---|---|---|---|"
for size in 240 360; do
  run files$size --size $size --present files --write-every 0 --clock sim
  echo "| $size | files | none | $(get "$WORK/files$size/metrics.jsonl" fps frame_ms_p50 frame_ms_p99 swap_skew_us_p50 swap_skew_us_p99 swap_skew_us_max) |"
  run win$size --size $size --present window --clock sim
  echo "| $size | window | scheduled | $(get "$WORK/win$size/metrics.jsonl" fps frame_ms_p50 frame_ms_p99 swap_skew_us_p50 swap_skew_us_p99 swap_skew_us_max) |"
done
run winbar240 --size 240 --present window --clock sim --swap-sync barrier
echo "| 240 | window | barrier | $(get "$WORK/winbar240/metrics.jsonl" fps frame_ms_p50 frame_ms_p99 swap_skew_us_p50 swap_skew_us_p99 swap_skew_us_max) |"
echo
echo "Wall clock, 240 per wall-eye, windows, recorded head path:"
echo
echo "| prediction | motion-to-photon ms p50 | p99 | tracker age at swap ms p50 | head error at scan-out mm p50 | p99 | held pose error mm p50 | p99 |"
echo "|---|---|---|---|---|---|---|---|"
run wall240 --size 240 --present window --clock wall
echo "| constant velocity | $(get "$WORK/wall240/metrics.jsonl" motion_to_photon_ms_p50 motion_to_photon_ms_p99 tracker_age_at_swap_ms_p50 prediction_error_mm_p50 prediction_error_mm_p99 held_pose_error_mm_p50 held_pose_error_mm_p99) |"
run wallnp240 --size 240 --present window --clock wall --no-predict
echo "| none | $(get "$WORK/wallnp240/metrics.jsonl" motion_to_photon_ms_p50 motion_to_photon_ms_p99 tracker_age_at_swap_ms_p50 prediction_error_mm_p50 prediction_error_mm_p99 held_pose_error_mm_p50 held_pose_error_mm_p99) |"

# The swap lock's own skew, without more render ranks than cores: the front
# wall alone (master + 2 render ranks on this 2-core machine).
python3 - "$CFG" > "$WORK/front.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
c["walls"] = c["walls"][:1]
print(json.dumps(c))
PY
run1() { local out="$1"; shift; "${MPI[@]}" -np 3 "$CAVE" run "$WORK/front.json" --scene "$SCENE" --drive "$DRIVE" --head-path "$HEAD" \
          --frames "$FRAMES" --no-idle-lcd --quiet -o "$WORK/$out" "$@" >/dev/null; }
echo
echo "Front wall only (3 ranks: render ranks do not outnumber the cores):"
echo
echo "| pixels per wall-eye | present | swap lock | fps (p50) | frame ms p50 | frame ms p99 | swap skew us p50 | p99 | max |"
echo "|---|---|---|---|---|---|---|---|---|"
for lock in scheduled barrier; do
  run1 front_$lock --size 240 --present window --clock sim --swap-sync $lock
  echo "| 240 | window | $lock | $(get "$WORK/front_$lock/metrics.jsonl" fps frame_ms_p50 frame_ms_p99 swap_skew_us_p50 swap_skew_us_p99 swap_skew_us_max) |"
done
