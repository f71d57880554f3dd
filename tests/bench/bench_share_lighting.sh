#!/usr/bin/env bash
# Shared lighting in the full CAVE (issue 16, targets 2 and 3): 11 ranks
# (master + the 10 wall-eyes of configs/caves/cave5.json) on this machine,
# the 571K-triangle cabin at 360^2 per wall-eye, the sky drive at --dt 0.2
# (the sun moves every frame: every frame is a lighting change with a new
# shadow map), --share-lighting host, host-now and off alternated (RUNS
# rounds; MODES overrides the list), LCD
# off, nothing written.  Per run, from the metrics (frame 0 left out):
#   CAVE frames/s (p50) and frame ms;
#   CPU ms per CAVE frame: every wall-eye's process CPU (all its threads,
#     the `cpu_s` the ranks report with each lighting step) from frame 1 to
#     the last, plus the master's thread CPU, over the frames between;
#   per lighting change: the wall-eyes' lighting step (renderer products +
#     background image) in process CPU ms, median per kind (computed, led,
#     imported; a prefetched change counts the prefetch's CPU), and summed
#     over the host's 10 wall-eyes;
#   the importers' median wait for the leader (wall ms), prefetches that
#     came true / did not.
# Usage: bench_share_lighting.sh BUILD_DIR SCENE.prt [FRAMES (10)] [RUNS (2)] [SIZE (360)]
#   SCENE: e.g. the bench_render cache $TMPDIR/cave_bench_render_t8.prt
#   (build/tests/bench/bench_shadow --share makes it when missing).
set -euo pipefail
BUILD="${1:?usage: bench_share_lighting.sh BUILD_DIR SCENE.prt [FRAMES] [RUNS] [SIZE]}"
SCENE="${2:?usage: bench_share_lighting.sh BUILD_DIR SCENE.prt [FRAMES] [RUNS] [SIZE]}"
FRAMES="${3:-10}"; RUNS="${4:-2}"; SIZE="${5:-360}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
WORK="${BENCH_WORK:-/tmp/bench_share_lighting}"
mkdir -p "$WORK"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1 LP_NUM_THREADS=1
MPI=(mpirun --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS)
echo "| run | --share-lighting | CAVE frames/s (p50) | frame ms p50 | CPU ms per CAVE frame | lighting step CPU ms per wall-eye: computed / led / imported (medians) | per change, 10 wall-eyes (CPU ms) | importers' wait ms (median) | prefetched / missed | late / dead / torn |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for run in $(seq 1 "$RUNS"); do
  for mode in ${MODES:-host host-now off}; do
    out="$WORK/$mode$run"
    rm -rf "$out"
    "${MPI[@]}" -np 11 "$BUILD/cave" run "$ROOT/configs/caves/cave5.json" --scene "$SCENE" \
      --drive "$ROOT/configs/drives/sky.json" --dt 0.2 --frames "$FRAMES" --size "$SIZE" \
      --write-every 0 --no-lcd --quiet --timeout-ms 30000 --gather-timeout 300 \
      --share-lighting "$mode" -o "$out" >/dev/null 2>"$out.err" || { echo "run failed: $(tail -3 "$out.err")"; exit 1; }
    python3 - "$out/metrics.jsonl" "$run" "$mode" <<'PY'
import json, statistics as st, sys
lines = [json.loads(l) for l in open(sys.argv[1])]
frames = [l for l in lines if l["type"] == "frame"]
s = lines[-1]
per = {"computed": [], "led": [], "imported": []}
host, waits = [], []
cpu = {}
for f in frames[1:]:
    tot = 0
    for r, v in f["ranks"].items():
        if "light" not in v: continue
        if v["light"] in per: per[v["light"]].append(v["light_cpu_ms"])
        if v["light"] == "imported": waits.append(v["light_wait_ms"])
        tot += v["light_cpu_ms"]
        cpu.setdefault(r, []).append((f["frame"], v["cpu_s"]))
    host.append(tot)
n = len(frames) - 2
walleye = sum(c[-1][1] - c[0][1] for c in cpu.values()) * 1e3
master = s.get("master_thread_cpu_s", 0) * 1e3 / max(1, len(frames))
med = lambda a: f"{st.median(a):.1f}" if a else "-"
sl = s["shared_lighting"]
print(f"| {sys.argv[2]} | {sys.argv[3]} | {s['fps']:.2f} | {s['frame_ms_p50']:.0f} | {walleye / max(1, n) + master:.0f} | "
      f"{med(per['computed'])} / {med(per['led'])} / {med(per['imported'])} | {med(host)} | {med(waits)} | "
      f"{sl['prefetched']} / {sl['prefetch_missed']} | {sl['late_leader']} / {sl['dead_leader']} / {sl['torn']} |")
PY
  done
done
