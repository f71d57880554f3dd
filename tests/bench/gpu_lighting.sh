#!/usr/bin/env bash
# The renderer's tests and the lighting-change benchmark on a machine with a
# GPU (issue 16, targets 2 and 6): run from the repository root after
# `source tests/bench/gpu_env.sh PACK` (tests/bench/gpu_pack.sh's output).
#
# Usage: gpu_lighting.sh PACK_DIR OUT_DIR [LOOP_FRAMES (200)]
# Steps, each bounded by `timeout`, all output in OUT_DIR/log.txt:
#   - test_render, test_render_share, test_render_texture on the hardware EGL
#     device (their renderers take --gpu auto's choice: the hardware device
#     when there is one; each prints its GL line): the GPU's paths of the
#     relight (transform feedback), the fitted shadow map, the mapped split,
#     shared lighting, against the CPU references;
#   - bench_shadow --only "1 mm, facing away only" (a lighting change on the
#     GPU: CPU and wall ms; its cabin baked into TMPDIR, 2 rays a vertex);
#   - bench_render --loop at 1440^2 (cases a-e; (c) changes the lighting
#     every frame).
set -uo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set -uo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;; esac
P="${1:?usage: gpu_lighting.sh PACK_DIR OUT_DIR [LOOP_FRAMES]}"
OUT="${2:?usage: gpu_lighting.sh PACK_DIR OUT_DIR [LOOP_FRAMES]}"
LOOP="${3:-200}"
mkdir -p "$OUT"
export TMPDIR="${TMPDIR:-/tmp}"
exec > >(tee "$OUT/log.txt") 2>&1
step() { echo; echo "=== $* ($(date +%T))"; }

step "machine"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 || echo "nvidia-smi: not found"
echo "CPU: $(nproc) cores"
for t in test_render test_render_share test_render_texture; do
  step "$t"
  timeout 180 "$P/$t" > "$OUT/$t.txt" 2>&1
  echo "$t: exit $?"
  grep -E "^GL:|default transfer|PASSED|FAILED|other transfer" "$OUT/$t.txt" | head -8
done
step "bench_shadow (a lighting change on this GL)"
timeout 240 "$P/bench_shadow" --only "1 mm, facing away only" --reps 3 --suns 4 --no-error
step "bench_render --loop $LOOP --gpu 0 --only 1440"
timeout 240 "$P/bench_render" --loop "$LOOP" --gpu 0 --only 1440 --cave configs/caves/cave5.json
step "done"
