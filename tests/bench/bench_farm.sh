#!/usr/bin/env bash
# Gather farm scaling (issue 16, target 5): `cave run` with G = 0, 1, 2, 4,
# 8, 16, 32 gather-only ranks on this machine (oversubscribed), one wall with
# one packed-stereo render rank (1 + 1 + G ranks), a small scene, a static
# head and light (one LCD key, so every round sums), idle LCD threads off (the
# gather ranks are the only contributors).  Per G, from metrics.jsonl:
#   round_ms, round_cpu_ms   a gather rank's round: wall (its share of the
#                            cores) and thread CPU time (its cost)
#   Msamples/s/rank (CPU)    texels x spp per CPU second of a gather rank
#   rounds/s                 rounds summed into the master's image per second
#   epoch_ms                 an allreduce epoch, start to sum on the master
#   poll cpu ms/epoch, max   the master's CPU time in the allreduce's polls
#                            per epoch with rounds (MPI_Test and the sum into
#                            the image), and its largest single poll
#   gather MPI cpu / round cpu  the gather ranks' MPI threads' CPU time
#                            (pooling rounds, their share of the sum,
#                            polling) over their rounds' CPU time, and the
#                            busiest rank's MPI-thread CPU per epoch (ms)
#   master cpu s/s           the master thread's CPU seconds per second of
#                            the run (mostly its polling loops)
#   master_ms p50/p99        per-frame master work, wall (with preemption)
#   master_cpu_ms p50/p99    the same intervals in thread CPU time
# The gather ranks run under `nice -n GATHER_NICE` (default 19): on a farm
# they have nodes of their own, here they would otherwise take the master's
# core in turns and its wall times would be the scheduler's (GATHER_NICE=0
# shows that).  --gather-timeout 60: a niced gather rank starved by other
# jobs on the machine is not taken for dead.  A run whose mpirun failed but
# whose summary was written still counts (the rc is noted).  At the end,
# farm_model.py projects the farm from these runs.
# Usage: bench_farm.sh BUILD_DIR [REPS]
# Environment: GATHER ("0 1 2 4 8 16 32"), FRAMES (200), FPS (10),
# LCD_SIZE (400x300), LCD_SPP (4), GATHER_NICE (19), BENCH_WORK (/tmp/bench_farm).
set -euo pipefail
BUILD="${1:?usage: bench_farm.sh BUILD_DIR [REPS]}"
REPS="${2:-1}"
CAVE="$(cd "$BUILD" && pwd)/cave"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
WORK="${BENCH_WORK:-/tmp/bench_farm}"
FRAMES="${FRAMES:-200}"
FPS="${FPS:-10}"
LCD_SIZE="${LCD_SIZE:-400x300}"
LCD_SPP="${LCD_SPP:-4}"
NICE="${GATHER_NICE:-19}"
CORES=$(getconf _NPROCESSORS_ONLN)
mkdir -p "$WORK"
cd "$WORK"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1 LP_NUM_THREADS=1
MPI=(mpirun --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS)

[ -s scene.prt ] || "$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null
cat > wall1.json <<'JSON'
{"description": "the front wall of cave5.json, both eyes on one rank (side-by-side)",
 "walls": [{"name": "front", "pa": [-1.5, 0, -1.5], "pb": [1.5, 0, -1.5], "pc": [-1.5, 3, -1.5], "res": [720, 720]}],
 "outputs": [{"wall": "front", "eye": "both", "stereo": "side-by-side", "gpu": "software"}],
 "head": [0, 1.2, 0], "gaze": [0, 0, -1], "scene_offset": [-0.37, -0.18, 0]}
JSON
cat > still.json <<'JSON'
{"description": "standing still under forest", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 30, "weights": [1]}, {"t": 10, "yaw": 30}]}
JSON

echo "# bench_farm: $(date -u +%FT%TZ), $CORES cores, gather ranks at nice $NICE, LCD $LCD_SIZE x $LCD_SPP spp, $FRAMES frames at $FPS/s" | tee bench.txt
echo "| G | rep | round ms | round cpu ms | Msamples/s/rank (CPU) | rounds/s summed | epochs | epoch ms | poll cpu ms/epoch | poll cpu ms max | poll wall ms max | gather MPI cpu / round cpu | busiest gather MPI cpu ms/epoch | master cpu s/s | master_ms p50 | p99 | master_cpu_ms p50 | p99 |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for rep in $(seq 1 "$REPS"); do
  for g in ${GATHER:-0 1 2 4 8 16 32}; do
    out="g${g}r$rep"
    rm -rf "$out"
    ARGS=(run wall1.json --scene scene.prt --drive still.json --size 32 --frames "$FRAMES" --max-fps "$FPS"
      --no-compensation --no-idle-lcd --write-every 0 --lcd-size "$LCD_SIZE" --lcd-spp "$LCD_SPP"
      --lcd-budget 100000 --gather-timeout 60 --quiet -o "$out")
    APP=(-np 2 "$CAVE" "${ARGS[@]}")
    [ "$g" -gt 0 ] && APP+=(: -np "$g" nice -n "$NICE" "$CAVE" "${ARGS[@]}")
    rc=0
    timeout 900 "${MPI[@]}" "${APP[@]}" >"$out.log" 2>&1 || rc=$?
    if ! grep -q '"summary"' "$out/metrics.jsonl" 2>/dev/null; then
      echo "| $g | $rep | run failed (rc $rc): $(grep -m1 'cave run' "$out.log") |"
      continue
    fi
    [ $rc -ne 0 ] && echo "(G = $g, rep $rep: mpirun rc $rc after the summary: $(grep -m1 'cave run' "$out.log"))" >&2
    python3 - "$out/metrics.jsonl" "$g" "$rep" "$LCD_SIZE" "$LCD_SPP" <<'PY' || echo "| $g | $rep | metrics not read |"
import json, sys
path, g, rep, size, spp = sys.argv[1:6]
s = [json.loads(l) for l in open(path) if '"summary"' in l][-1]
w, h = (int(v) for v in size.split("x"))
texels_spp = w * h * int(spp)
rate = s["master_thread_cpu_s"] / s["seconds"]  # master CPU s per s
a = s.get("lcd_allreduce")
f = lambda v, d=3: f"{v:.{d}g}" if isinstance(v, float) else str(v)
cols = []
if a and a["gather_rounds"] > 0:
    de = max(a["data_epochs"], 1)
    cols = [f(a["gather_round_ms"]), f(a["gather_round_cpu_ms"]),
            f(texels_spp / (a["gather_round_cpu_ms"] * 1e-3) / 1e6),
            f(s["lcd_rounds"] / s["seconds"]), f"{a['data_epochs']}/{a['epochs']}", f(a["epoch_ms_mean"]),
            f(a["poll_cpu_ms"] / de), f(a["poll_cpu_ms_max"]), f(a["poll_ms_max"]),
            f(a["gather_comm_cpu_ms"] / a["gather_cpu_ms"]) if "gather_comm_cpu_ms" in a else "-",
            f(a["gather_comm_cpu_ms_max"] / max(a["epochs"], 1)) if "gather_comm_cpu_ms_max" in a else "-"]
else:
    cols = ["-"] * 11
cols += [f(rate), f(s["master_ms_p50"]), f(s["master_ms_p99"]), f(s["master_cpu_ms_p50"]), f(s["master_cpu_ms_p99"])]
print(f"| {g} | {rep} | " + " | ".join(cols) + " |")
PY
  done
done
echo
python3 "$HERE/farm_model.py" "$WORK"
