#!/usr/bin/env bash
# `cave render` and `cave shade --view` agree on a view with split window
# lights (issue 13): a one-wall CAVE whose wall is the 60-degree, 96 x 96
# pinhole view of `cave shade --view` from the driver's eye, forest.exr with
# its sun left in the map (--no-sun) and 16 split lights.  Over the pixels
# that see geometry (ids from `cave reference --ids`): mean luminance ratio
# within 0.2%, median per-pixel difference < 0.1%, 90th percentile < 1%
# (GL rasterisation vs Embree rays at triangle edges); the split must change
# the picture (median > 1% against the frame without it) so that agreement
# means something.
# Usage: test_render_split.sh CAVE REF_COMPARE WORKDIR
set -euo pipefail
CAVE=$1 CMP=$2 WORK=$3
rm -rf "$WORK" && mkdir -p "$WORK" && cd "$WORK"
cat >one.json <<'JSON'
{
  "walls": [
    {"name": "front", "pa": [-0.866025, 0.333975, -1.5], "pb": [0.866025, 0.333975, -1.5],
     "pc": [-0.866025, 2.066025, -1.5], "res": [96, 96]}
  ],
  "eye_separation": 0,
  "head": [0, 1.2, 0],
  "gaze": [0, 0, -1],
  "scene_offset": [-0.37, -0.18, 0]
}
JSON
V=(--view -0.37,1.02,0 --look -0.37,1.02,-1 --fov 60 --size 96x96)
L=(--env forest.exr --no-sun)
"$CAVE" bake default --tess 1 --rays 64 --bounces 1 -o a.prt --quiet >/dev/null
"$CAVE" render one.json --scene a.prt "${L[@]}" --split 16 -o r16 >render.txt
grep -q "^split: 16 window lights" render.txt || { echo "FAIL: render --split printed no split line"; cat render.txt; exit 1; }
"$CAVE" shade a.prt "${L[@]}" --split 16 "${V[@]}" -o s16.exr >/dev/null
"$CAVE" shade a.prt "${L[@]}" "${V[@]}" -o s0.exr >/dev/null
"$CAVE" reference a.prt --env forest.exr "${V[@]}" --spp 1 --quiet --ids ids.exr -o ref1.exr >/dev/null
fail=0
agree=$("$CMP" r16/front_L.exr s16.exr s16.exr ids.exr | awk '$1 == "all"')
echo "render --split 16 vs shade --split 16: pixels, mean ratio, median, p90: $(echo "$agree" | awk '{print $2, $3, $4, $5}')"
echo "$agree" | awk '{exit !($2 > 1000 && $3 > 0.998 && $3 < 1.002 && $4 < 0.001 && $5 < 0.01)}' ||
  { echo "FAIL: cave render and cave shade differ with the split on"; fail=1; }
effect=$("$CMP" s0.exr s16.exr s16.exr ids.exr | awk '$1 == "all"')
echo "shade without vs with the split: median difference $(echo "$effect" | awk '{print $4}')"
echo "$effect" | awk '{exit !($4 > 0.01)}' || { echo "FAIL: the split lights change nothing"; fail=1; }
exit $fail
