#!/usr/bin/env bash
# The main job on the built-in default scene: installs what is missing,
# builds, bakes the default cabin (configs/scenes/default.json), relights it
# under blender-data's HDR maps and a Preetham sky, and writes PNG views of
# the driver's seat plus per-vertex PLYs into OUT (default out/main-job).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cave_install_packages
cave_build "$CAVE_ROOT/build"
CAVE="$CAVE_ROOT/build/cave"
OUT="${1:-$CAVE_ROOT/out/main-job}"
mkdir -p "$OUT"

"$CAVE" bake "$CAVE_ROOT/configs/scenes/default.json" -o "$OUT/default.prt"

# The driver's view: eye of the default cabin, looking ahead and a little down.
VIEW=(--view -0.37,1.02,0.10 --look -0.30,0.85,-1.0 --fov 80 --size 960x600)
for map in forest city courtyard sunrise sunset; do
  "$CAVE" shade "$OUT/default.prt" --env "$map.exr" "${VIEW[@]}" -o "$OUT/view-$map.png"
done
# The car turned 90 degrees to the left under the same forest light.
"$CAVE" shade "$OUT/default.prt" --env forest.exr --yaw 90 "${VIEW[@]}" -o "$OUT/view-forest-yaw90.png"
# A blend of two maps, and the analytic sky (turbidity 3, sun 35 deg high, front right).
"$CAVE" shade "$OUT/default.prt" --env forest.exr,city.exr --weights 0.5,0.5 "${VIEW[@]}" -o "$OUT/view-blend.png"
"$CAVE" shade "$OUT/default.prt" --sky 3,35,40 "${VIEW[@]}" -o "$OUT/view-sky.png"
"$CAVE" shade "$OUT/default.prt" --sky 3,35,40 "${VIEW[@]}" -o "$OUT/view-sky.exr"
"$CAVE" shade "$OUT/default.prt" --env forest.exr -o "$OUT/forest.ply"

echo
echo "main job done; results in $OUT:"
ls -l "$OUT"
