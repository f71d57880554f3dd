#!/usr/bin/env bash
# End-to-end error of the PRT picture in image space (issue 13): `cave shade
# --view` against `cave reference` (the unbiased path tracer, until roulette)
# on the default cabin, the issue's two views, maps forest, sunset, city and a
# constant one, for a sweep of SH bands.  Per row: mean luminance ratio
# shade/reference, median and 90th percentile of the per-pixel relative
# luminance error over pixels that hit geometry, the LCD region's mean ratio,
# the reference's own noise floor (median relative standard error) and the
# bake time.  BENCH_SPLIT="0 64" adds rows for `cave shade --split K` (window
# light split out as K directional lights); BENCH_PIXEL="none sun all" rows
# for `--pixel-lights M` (default sun); BENCH_MAPS picks the maps; BENCH_SPLIT_SAMPLES (default 4) is
# passed as --split-samples.  The shade column is the wall time of one
# `cave shade` (relight + view; a ratio between rows of one run only).  Bakes and references are kept in
# BENCH_WORK and reused by a later run.  Prints a markdown table
# (docs/benchmarks.md).
# Usage: bench_reference.sh BUILD_DIR [SPP] [WxH] [BANDS...]
set -euo pipefail
BUILD="${1:?usage: bench_reference.sh BUILD_DIR [SPP] [WxH] [BANDS...]}"
SPP="${2:-2048}"
SIZE="${3:-160x120}"
shift $(( $# < 3 ? $# : 3 ))
BANDS=("$@")
[ ${#BANDS[@]} -gt 0 ] || BANDS=(3 5 8)
CAVE="$BUILD/cave"
CMP="$BUILD/tests/bench/ref_compare"
WORK="${BENCH_WORK:-/tmp/bench_reference}"
RAYS="${BENCH_RAYS:-1024}"
read -r -a SPLITS <<<"${BENCH_SPLIT:-0}"
read -r -a PIXELS <<<"${BENCH_PIXEL:-sun}"
SSAMP="${BENCH_SPLIT_SAMPLES:-4}"
mkdir -p "$WORK"
VIEWS=("driver|--view -0.37,1.02,0 --look -0.15,0.65,-1.0 --fov 60"
       "seats|--view 0.3,0.95,-0.8 --look -0.1,0.75,1.2 --fov 80")
read -r -a MAPS <<<"${BENCH_MAPS:-forest.exr sunset.exr city.exr constant}"
light() { if [ "$1" = constant ]; then echo "--env-constant 1,1,1"; else echo "--env $1"; fi; }

declare -A BAKE_S
for b in "${BANDS[@]}"; do
  p="$WORK/b$b.prt"
  if [ ! -s "$p" ] || [ ! -s "$p.seconds" ]; then
    "$CAVE" bake default -o "$p" --bands "$b" --rays "$RAYS" --bounces 2 --force --quiet |
      sed -n 's/^bake: \([0-9.]*\) s,.*/\1/p' >"$p.seconds"
  fi
  BAKE_S[$b]=$(cat "$p.seconds")
done
LCD_ID=$("$CAVE" reference "$WORK/b${BANDS[0]}.prt" --env-constant 1,1,1 --view 0,1,0 --look 0,1,-1 \
         --size 2x2 --spp 1 --quiet --ids "$WORK/tmp_ids.exr" -o "$WORK/tmp.exr" |
         sed -n 's/^material \([0-9]*\): lcd_panel.*/\1/p')

echo "| view | map | bands | split | pixel lights | bake s | shade s | mean ratio | median err | p90 err | LCD mean ratio | noise floor |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for v in "${VIEWS[@]}"; do
  vn=${v%%|*} vo=${v#*|}
  for m in "${MAPS[@]}"; do
    r="$WORK/ref_${vn}_${m%.exr}"
    if [ ! -s "$r.exr" ]; then
      # shellcheck disable=SC2046,SC2086
      "$CAVE" reference "$WORK/b${BANDS[0]}.prt" $(light "$m") $vo --size "$SIZE" --spp "$SPP" \
        --pass "$SPP" --quiet -o "$r.exr" --error "$r.se.exr" --ids "$r.ids.exr" >"$r.log"
    fi
    for b in "${BANDS[@]}"; do
     for k in "${SPLITS[@]}"; do
      for px in "${PIXELS[@]}"; do
      s="$WORK/shade_${vn}_${m%.exr}_b${b}_s${k}_$px.exr"
      t0=$(date +%s.%N)
      # shellcheck disable=SC2046,SC2086
      "$CAVE" shade "$WORK/b$b.prt" $(light "$m") $vo --size "$SIZE" --split "$k" \
        --split-samples "$SSAMP" --pixel-lights "$px" -o "$s" >/dev/null
      ts=$(echo "$(date +%s.%N) - $t0" | bc)
      res=$("$CMP" "$s" "$r.exr" "$r.se.exr" "$r.ids.exr" "$LCD_ID")
      all=$(echo "$res" | awk '$1 == "all" {printf "%.3f | %.1f%% | %.1f%% |", $3, 100 * $4, 100 * $5}')
      lcd=$(echo "$res" | awk '$1 ~ /^ids:/ {print ($2 > 0 ? sprintf("%.3f", $3) : "-")}')
      noise=$(echo "$res" | awk '$1 == "all" {printf "%.1f%%", 100 * $6}')
      printf '| %s | %s | %s | %s | %s | %s | %.2f | %s %s | %s |\n' "$vn" "${m%.exr}" "$b" "$k" "$px" \
        "${BAKE_S[$b]}" "$ts" "$all" "$lcd" "$noise"
      done
     done
    done
  done
done
