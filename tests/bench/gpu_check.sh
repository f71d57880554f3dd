#!/usr/bin/env bash
# Issue 16 target 6 on a machine with a GPU: the 1440^2 wall-eye frame of the
# 571K-triangle cabin on the hardware EGL device, proof that the device was
# used, the same images as llvmpipe's, and the bake's time (the bake is
# Embree on the CPU: it cannot use the GPU).  Read docs/benchmarks.md
# ("GPU: the wall-eye frame on a hardware EGL device").
#
# Usage: gpu_check.sh BUILD_DIR OUT_DIR [LOOP_FRAMES (300)]
#   BUILD_DIR holds cave, tests/bench/bench_render and tests/bench/img_diff
#   (or the three side by side); OUT_DIR gets log.txt, GPU images
#   (front_L.exr of the default scene at 720^2, front_L_1440.png of the
#   cabin, run1440_front_L.png: cave run's compensated frame), default.prt's
#   md5 in the log, nvidia-smi's utilisation during the back-to-back frames
#   (dmon.txt) and cave run's metrics (run<SIZE>_<share>_<drive>_metrics.jsonl).
#   Compare the EXR with llvmpipe's render of the same command elsewhere
#   with img_diff.  Env: GPU (0; software: a dry run on llvmpipe),
#   TABLE_FRAMES (10), RUNS ("720:auto 1440:auto 1440:auto:none 1440:host:none"; auto: on
#   a GPU the frame ends on it, --post auto, and each wall-eye relights on it, issue 29),
#   RUN_FRAMES (24), ONLY_RUN (1: skip the renders and benchmarks),
#   OMP_NUM_THREADS (1 for cave run, as cluster/main-job.sh),
#   CABIN (a cached cave_bench_render_t8.prt instead of baking it).
# Steps, each bounded by `timeout`: the GPU and driver; wrong --gpu values
# (errors, no fall-back); the default scene's bake (CPU) and its md5; cave
# render at 720^2 (--gpu auto) and 1440^2 x 5 frames (--gpu 0);
# bench_render's per-pass table (720^2 and 1440^2, glFinish between passes);
# bench_render --loop (back-to-back frames at 1440^2 and 720^2, float and
# half transfer); cave run under mpirun (11 ranks on this host and GPU) when
# mpirun is there (tests/bench/gpu_env.sh carries Open MPI to a GPU machine
# that lacks it).
set -uo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set -uo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;; esac
BUILD="${1:?usage: gpu_check.sh BUILD_DIR OUT_DIR [LOOP_FRAMES]}"
OUT="${2:?usage: gpu_check.sh BUILD_DIR OUT_DIR [LOOP_FRAMES]}"
LOOP="${3:-300}"
GPU="${GPU:-0}"            # the device index asked for (software: a dry run on llvmpipe)
TABLE_FRAMES="${TABLE_FRAMES:-10}"
RUNS="${RUNS:-720:auto 1440:auto 1440:auto:none 1440:host:none}"   # cave run: SIZE:--share-lighting[:drive (sky; none: no drive, a fixed light)]
ONLY_RUN="${ONLY_RUN:-0}"  # 1: the machine, the bakes and cave run only
RUN_FRAMES="${RUN_FRAMES:-24}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
pick() { if [ -x "$BUILD/$1" ]; then echo "$BUILD/$1"; else echo "$BUILD/$(basename "$1")"; fi; }
CAVE="$(pick cave)"; BR="$(pick tests/bench/bench_render)"; ED="$(pick tests/bench/img_diff)"
W="${TMPDIR:-/tmp}/gpu_check"
rm -rf "$W"; mkdir -p "$W" "$OUT"
# CABIN=FILE: a cached bench cabin (cave_bench_render_t8.prt) instead of baking it
export TMPDIR="$W"   # bench_render's cabin cache: baked once, by the first bench_render
[ -n "${CABIN:-}" ] && ln -s "$(realpath "$CABIN")" "$W/cave_bench_render_t8.prt"
exec > >(tee "$OUT/log.txt") 2>&1
step() { echo; echo "=== $* ($(date +%T))"; }
CFG="$ROOT/configs/caves/cave5.json"

step "machine"
nvidia-smi --query-gpu=name,driver_version,memory.total,pcie.link.gen.max --format=csv 2>&1 || echo "nvidia-smi: not found"
echo "CPU: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
grep -m1 PRETTY_NAME /etc/os-release
for b in "$CAVE" "$BR" "$ED"; do ldd "$b" | grep "not found" && echo "MISSING libraries for $b"; done

step "bake of the default scene (Embree, CPU threads; no GPU use)"
TIMEFORMAT="bake: %R s wall, %U s user CPU"
time "$CAVE" bake "$ROOT/configs/scenes/default.json" -o "$W/default.prt" --quiet
md5sum "$W/default.prt"

if [ "$ONLY_RUN" = 1 ]; then
  step "ONLY_RUN=1: the cabin's bake only (bench_render --loop 1 at 64^2)"
  timeout 120 "$BR" --loop 1 --only 64 --gpu "$GPU" --cave "$CFG" | tail -1
else
step "wrong --gpu values must fail, naming what exists (the first bench_render bakes the 571K-triangle cabin, CPU)"
timeout 60 "$CAVE" render "$CFG" --scene "$W/default.prt" --sky 3,35,30 --gpu 7 -o "$W/x" ; echo "exit $?"
timeout 60 "$BR" --gpu 7 --loop 1 --cave "$CFG"; echo "exit $?"
timeout 60 "$BR" --gpu software --loop 1 --only 64 --cave "$CFG" 2>&1 | grep -E "GL:|EGL|device" ; echo "exit ${PIPESTATUS[0]}"

step "cave render, 720^2, --gpu auto (must pick the hardware device)"
timeout 120 "$CAVE" render "$CFG" --scene "$W/default.prt" --sky 3,35,30 --size 720 --gpu auto -o "$W/r720"
echo "exit $?"
[ "$GPU" = software ] && timeout 120 "$CAVE" render "$CFG" --scene "$W/default.prt" --sky 3,35,30 --size 720 --gpu software -o "$W/r720"
cp "$W/r720/front_L.exr" "$OUT/" 2>/dev/null

step "bench_render per-pass table"
timeout 300 "$BR" "$TABLE_FRAMES" --gpu "$GPU" --cave "$CFG"; echo "exit $?"

step "cave render, 571K-triangle cabin, 1440^2, 5 frames, --gpu 0"
timeout 120 "$CAVE" render "$CFG" --scene "$W/cave_bench_render_t8.prt" --sky 3,35,30 --size 1440 --frames 5 \
  --cull-back --gpu "$GPU" -o "$W/r1440"; echo "exit $?"
cp "$W/r1440/front_L.png" "$OUT/front_L_1440.png" 2>/dev/null

step "back-to-back frames (bench_render --loop $LOOP), nvidia-smi dmon alongside"
(nvidia-smi dmon -s u -d 1 > "$OUT/dmon.txt" 2>&1 &) ; sleep 1
for args in "--only 1440" "--only 1440 --half" "--only 720"; do
  timeout 240 "$BR" --loop "$LOOP" --gpu "$GPU" --cave "$CFG" $args; echo "exit $? ($args)"
done
pkill -f "nvidia-smi dmon" || true
echo; echo "dmon (GPU utilisation, %):"; cat "$OUT/dmon.txt" | head -60

fi  # ONLY_RUN

step "cave run under mpirun: 11 ranks (master + 10 wall-eyes) sharing this GPU, the 571K-triangle cabin, the sky drive at --dt 0.2 (a lighting change every frame), LCD off"
if command -v mpirun > /dev/null; then
  for run in $RUNS; do
    IFS=: read -r S share drive <<< "$run"; drive="${drive:-sky}"; out="$W/run${S}_${share}_$drive"
    dargs=(--drive "$ROOT/configs/drives/$drive.json"); [ "$drive" = none ] && dargs=()
    OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}" OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-passive}" \
    timeout 300 mpirun --oversubscribe $([ "$(id -u)" = 0 ] && echo --allow-run-as-root) -np 11 "$CAVE" run "$CFG" --scene "$W/cave_bench_render_t8.prt" \
      "${dargs[@]}" --dt 0.2 --frames "$RUN_FRAMES" --size "$S" --write-every 0 \
      --no-lcd --quiet --timeout-ms 60000 --gpu "$GPU" --share-lighting "$share" -o "$out" > "$out.log" 2>&1
    echo "size $S, --share-lighting $share, drive $drive (OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}): exit $?"
    grep -iE "error|fail" "$out.log" | head -5
    cp "$out/metrics.jsonl" "$OUT/run${S}_${share}_${drive}_metrics.jsonl" 2>/dev/null
    [ -f "$out/metrics.jsonl" ] && python3 - "$out/metrics.jsonl" <<'PY'
import json, statistics as st, sys
L = [json.loads(l) for l in open(sys.argv[1])]
fr = [l for l in L if l.get("type") == "frame"][1:]
s = L[-1]
rd = L[0].get("ranks", {}) if L and L[0].get("type") == "ready" else {}
for r in ("1", "10"):
    if r in rd: print("  ready:", rd[r])
print("  fps %.2f, frame_ms p50 %.1f p99 %.1f, master_ms p50 %.2f; frames %d" % (
    s.get("fps", 0), s.get("frame_ms_p50", 0), s.get("frame_ms_p99", 0), s.get("master_ms_p50", 0), len(fr)))
keys = {}
for f in fr:
    for r, v in f.get("ranks", {}).items():
        for k, x in v.items():
            if isinstance(x, (int, float)) and not isinstance(x, bool) and k.endswith("_ms"):
                keys.setdefault(k, {}).setdefault(r, []).append(x)
print("  wall-eyes, mean over ranks of each rank's median ms: " + ", ".join(
    "%s %.2f" % (k, st.mean(st.median(v) for v in d.values())) for k, d in sorted(keys.items())))
comp = [f["compensation"]["frame_ms"] for f in fr if isinstance(f.get("compensation"), dict) and "frame_ms" in f["compensation"]]
if comp: print("  master compensation.frame_ms median %.2f" % st.median(comp))
print("  master_ms p99 %.3f, frame path (issue 29): %s" % (s.get("master_ms_p99", 0), s.get("frame_path")))
PY
  done
  cp "$W/run1440_host_sky/frame"*"_front_L.png" "$OUT/run1440_front_L.png" 2>/dev/null
else
  echo "no mpirun here: skipped"
fi
step "done"
