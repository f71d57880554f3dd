#!/usr/bin/env bash
# The main job: installs what is missing, builds, bakes the built-in car cabin
# (configs/scenes/default.json) and runs the CAVE render service with 12 MPI
# ranks on this machine (master, 10 render ranks, 1 LCD gather rank): the 5-wall CAVE (configs/caves/cave5.json), the car
# driving through blender-data's HDR maps (configs/drives/default.json), a
# recorded head path (configs/heads/default.txt), a bounded number of frames
# at a modest resolution.  Leaves montage PNGs, per wall-eye EXR/PNG frames,
# the LCD panel image and the JSON-lines metrics (with the summary as the
# last line), the plots of the run (OUT/plots) and OUT/index.html showing
# them in OUT (default out/main-job).
#   bash cluster/main-job.sh [OUT]
# Environment: FRAMES (default 48), SIZE (pixels per wall-eye, default 240),
# RANKS (default 12: 11 is the minimum, each rank above it is an LCD gather
# rank; with 11 the LCD has only the render ranks' idle threads, which get no
# core while ten renderers share this machine's two, so the drive would have
# no readability figures until the held frames after it).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cave_install_packages
cave_build "$CAVE_ROOT/build"
CAVE="$CAVE_ROOT/build/cave"
OUT="${1:-$CAVE_ROOT/out/main-job}"
FRAMES="${FRAMES:-48}"
SIZE="${SIZE:-240}"
RANKS="${RANKS:-12}"
mkdir -p "$OUT"

"$CAVE" bake "$CAVE_ROOT/configs/scenes/default.json" -o "$OUT/default.prt"

# 12 ranks on one machine: one thread each (OpenMP, llvmpipe), oversubscribed.
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
# Ctrl-C / SIGTERM: mpirun forwards SIGTERM and sends SIGKILL after this many
# seconds (default 1); 10 lets the ranks finish their frame and the master
# write the LCD image and the summary (it also delays the end of a job whose
# rank died by that much).
export OMPI_MCA_odls_base_sigkill_timeout=10
MPI=(mpirun --oversubscribe -np "$RANKS" -x OMP_NUM_THREADS -x LP_NUM_THREADS)
if [ "$(id -u)" -eq 0 ]; then MPI+=(--allow-run-as-root); fi
# dt 0.3 s: 48 frames cover 14 s of the 20 s drive (the car turns through
# sunrise, forest and city light); during the drive every LCD round is a
# snapshot of the head and lighting it started with, so readability figures
# appear in metrics.jsonl with their key and age; the LCD image of the last
# pose is then summed to its budget of 64 rounds of 10 samples (640 samples
# per texel).  Rounds of 10 rather than the default 40 samples: the first
# figure comes 4x sooner on a slow machine (2-core VM, 2026-11-28: figures in
# 41 of the 48 drive frames from frame 7, against 30 from frame 18 with 16
# rounds of 40; same final image error, 11 s longer in all).
"${MPI[@]}" "$CAVE" run "$CAVE_ROOT/configs/caves/cave5.json" \
  --scene "$OUT/default.prt" --scene-config "$CAVE_ROOT/configs/scenes/default.json" \
  --drive "$CAVE_ROOT/configs/drives/default.json" \
  --head-path "$CAVE_ROOT/configs/heads/default.txt" \
  --frames "$FRAMES" --dt 0.3 --size "$SIZE" --write-every 12 \
  --lcd-spp 10 --lcd-budget 64 --lcd-wait -o "$OUT"

echo
echo "main job done; results in $OUT:"
ls "$OUT" | grep -E "montage|lcd|metrics" || true
nf=$(grep -c '"type":"frame"' "$OUT/metrics.jsonl" 2>/dev/null || echo 0)
echo "frames: $nf rendered: $FRAMES of the drive, $((nf > FRAMES ? nf - FRAMES : 0)) more at the last pose while the LCD image was summed to its budget"
echo "images (every 12th frame and the last, one per wall-eye and frame): $(ls "$OUT"/frame*.exr 2>/dev/null | wc -l) EXR," \
  "$(ls "$OUT"/frame*.png 2>/dev/null | grep -vc uncompensated) PNG, $(ls "$OUT"/frame*_uncompensated.png 2>/dev/null | wc -l) uncompensated PNG"
echo "summary: $(tail -1 "$OUT/metrics.jsonl")"
# the readability over the drive (the summary's lcd_drive, docs/metrics.md)
python3 - "$OUT/metrics.jsonl" <<'PY' || true
import json, sys
d = [json.loads(l) for l in open(sys.argv[1])][-1].get("lcd_drive")
if d:
    print("LCD over the drive (%s): figures in %d of %d drive frames, %d of them at most 2 frames old" % (
        "absolute light" if d["calibrated"] else "UNCALIBRATED light: no verdict", d["frames_with_figures"],
        d["frames"], d["frames_with_figures_at_most_2_old"]))
    for n, p in d.get("panels", {}).items():
        print("  %s: lowest CR %.3g at frame %d (t %.1f s); below %g:1 in %d frames, %.0f%% of the drive time" % (
            n, p["contrast_ratio_min"], p["contrast_ratio_min_frame"], p["contrast_ratio_min_t"], d["cr_min"],
            p["frames_below_cr_min"], 100 * p["time_share_below_cr_min"]))
PY
# plots of the whole run (docs/metrics.md "Plots") and the folder's index.html with them
"$CAVE" plot "$OUT/metrics.jsonl" -o "$OUT/plots" --index "$OUT"
echo "open $OUT/index.html: the newest montages, lcd.png and the plots"
