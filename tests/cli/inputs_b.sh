# Part b of test_inputs.sh (sourced: CAVE, ROOT, a.prt and the expect_* helpers are set).
# cabin, bake, tonemap, compensate, materials, tracker, cluster and `cave help`.

# b_expect_exit NAME RC PATTERN CMD...: expect_error, and the exit status is RC
# (2: a bad command-line value, 1: a file problem).
b_expect_exit() {
  local name=$1 want=$2 pat=$3
  shift 3
  expect_error "$name" "$pat" "$@"
  "$@" >/dev/null 2>&1
  local rc=$?
  if [ "$rc" -ne "$want" ]; then bad "$name: exit status $rc, expected $want"; fi
}

BQ="--bands 2 --rays 4 --bounces 0 --quiet"
"$CAVE" shade a.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size 16x8 -o bim16.exr >/dev/null 2>&1
"$CAVE" shade a.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size 32x16 -o bim32.exr >/dev/null 2>&1
WALL="$ROOT/configs/displays/two-sided-wall.json"

# item 3: compensate --right of another size than its --image (was a heap over-read / a crop)
b_expect_exit "compensate --right smaller" 2 \
  "--right bim16.exr is 16x8, its --image bim32.exr is 32x16: the eyes' images must match" \
  "$CAVE" compensate --display "$WALL" --image bim32.exr --right bim16.exr -o bJ.exr --quiet
b_expect_exit "compensate --right larger" 2 \
  "--right bim32.exr is 32x16, its --image bim16.exr is 16x8: the eyes' images must match" \
  "$CAVE" compensate --display "$WALL" --image bim16.exr --right bim32.exr -o bK.exr --quiet
expect_absent "compensate --right sizes" bJ_left.exr bJ_right.exr bK_left.exr bK_right.exr
cp bim32.exr bX_left.exr
b_expect_exit "compensate -o onto an input" 2 "-o: bX_left.exr: is an input image" \
  "$CAVE" compensate --display "$WALL" --image bX_left.exr --right bim32.exr -o bX.exr --quiet
expect_ok "compensate stereo, equal sizes" \
  "$CAVE" compensate --display "$WALL" --image bim32.exr --right bim32.exr -o bS.exr --quiet
[ -s bS_left.exr ] && [ -s bS_right.exr ] && ok "compensate stereo outputs" || bad "compensate stereo outputs"

# item 11: a folder in the way of the second output: nothing written
mkdir -p bQ_right.exr
b_expect_exit "compensate folder in the way" 1 "-o: cannot write bQ_right.exr: it is a folder" \
  "$CAVE" compensate --display "$WALL" --image bim32.exr --image bim32.exr -o bQ.exr --quiet
expect_absent "compensate folder in the way" bQ_left.exr

# item 4: tonemap luminances outside the float range / the operator's floor
b_expect_exit "tonemap --lwa 1e40" 2 "--lwa: expected 0.0001..1e+12 cd/m2, got '1e40'" \
  "$CAVE" tonemap bim32.exr --lwa 1e40 -o bt.png
b_expect_exit "tonemap --lmax 1e-30" 2 "--lmax: expected 0.0001..1e+12 cd/m2, got '1e-30'" \
  "$CAVE" tonemap bim32.exr --lmax 1e-30 -o bt.png
b_expect_exit "tonemap --lmax below lwa" 2 "--lmax: 0.01 cd/m2 is below 1e-6 x --lwa 100000" \
  "$CAVE" tonemap bim32.exr --lwa 1e5 --lmax 0.01 -o bt.png
b_expect_exit "tonemap --ldmax 1e40" 2 "--ldmax: expected 0 < L <= 1e+06 cd/m2, got '1e40'" \
  "$CAVE" tonemap bim32.exr --ldmax 1e40 -o bt.png
expect_absent "tonemap ranges" bt.png
expect_ok "tonemap given lwa, lmax" "$CAVE" tonemap bim32.exr --lwa 2000 --lmax 2e5 -o bt.png
grep -q "lwa 2000 cd/m2 (given), lmax 200000 cd/m2 (given)" out.txt && ok "tonemap prints the given values" \
  || { bad "tonemap given values"; cat out.txt; }

# item 8: an output that is the input, or of the wrong kind
cp bim32.exr bin.exr
sum_before=$(cksum <bin.exr)
b_expect_exit "tonemap -o the input" 2 "-o: bin.exr: is the input image" "$CAVE" tonemap bin.exr -o bin.exr
b_expect_exit "tonemap -o the input, other spelling" 2 "-o: ./bin.exr: is the input image" \
  "$CAVE" tonemap bin.exr -o ./bin.exr
[ "$(cksum <bin.exr)" = "$sum_before" ] && ok "tonemap input kept" || bad "tonemap overwrote its input"
"$CAVE" cabin --tess 1 -o bcab.obj >/dev/null 2>&1
sum_before=$(cksum <bcab.obj)
b_expect_exit "bake -o the input mesh" 2 "-o: bcab.obj: is the input; expected a new .prt path" \
  "$CAVE" bake bcab.obj $BQ -o bcab.obj
[ "$(cksum <bcab.obj)" = "$sum_before" ] && ok "bake input kept" || bad "bake overwrote its input"
b_expect_exit "bake -o not .prt" 2 "-o: expected a .prt path, got 'bx.obj'" "$CAVE" bake bcab.obj $BQ -o bx.obj
b_expect_exit "cabin -o x.mtl" 2 "-o: expected an .obj path, got 'bx.mtl'" "$CAVE" cabin -o bx.mtl
expect_absent "wrong output kinds" bx.obj bx.mtl bx.mtl.mtl

# item 11: leftovers and late failures
mkdir -p bdir.obj bdir.prt bdir.png
b_expect_exit "cabin -o a folder" 1 "-o: cannot write bdir.obj: it is a folder" "$CAVE" cabin -o bdir.obj
mkdir -p bsib.mtl
b_expect_exit "cabin: a folder in the way of the .mtl" 1 "-o: cannot write bsib.mtl: it is a folder" \
  "$CAVE" cabin -o bsib.obj
b_expect_exit "cabin -o a folder without .obj" 2 "-o: expected an .obj path, got 'bdir.prt'" \
  "$CAVE" cabin -o bdir.prt
b_expect_exit "cabin -o ''" 2 "-o: expected a file name" "$CAVE" cabin -o ""
expect_absent "cabin errors" bdir.mtl bdir.prt.mtl .mtl bsib.obj
b_expect_exit "bake -o a folder" 1 "-o: cannot write bdir.prt: it is a folder" "$CAVE" bake default $BQ -o bdir.prt
grep -q "^bake:" out.txt && bad "bake -o a folder: baked before failing" || ok "bake -o a folder: refused before the bake"
b_expect_exit "tonemap -o a folder" 1 "-o: cannot write bdir.png: it is a folder" "$CAVE" tonemap bim32.exr -o bdir.png

# item 15: tracker ranges and configs that are not JSON
b_expect_exit "tracker --count 0" 2 "--count: expected a pose count 1..1073741824, got '0'" \
  "$CAVE" tracker --listen --count 0
b_expect_exit "tracker --seconds abc" 2 "--seconds: expected seconds > 0 (up to 1e9), got 'abc'" \
  "$CAVE" tracker --listen --seconds abc
b_expect_exit "tracker --port 70000" 2 "--port: expected a UDP port 0..65535, got '70000'" \
  "$CAVE" tracker --listen --port 70000
: >bempty.json
printf '{"a":' >btrunc.json
b_expect_exit "tracker empty config" 1 "bempty.json: line 1, column 1: empty file (expected a JSON object)" \
  "$CAVE" tracker bempty.json --listen
b_expect_exit "tracker truncated config" 1 "btrunc.json: line 1, column 6: .*unclosed { or \[?" \
  "$CAVE" tracker btrunc.json --listen

# item 18: a bad value names its option and exits 2
b_expect_exit "cabin --length -1" 2 "--length: expected metres in 1.5..5, got '-1'" "$CAVE" cabin --length -1 -o bc.obj
b_expect_exit "cabin --height 3" 2 "--height: expected metres in 0.9..2, got '3'" "$CAVE" cabin --height 3 -o bc.obj
expect_absent "cabin ranges" bc.obj bc.mtl
"$CAVE" cabin --help | grep -q -- "--length M .*1.5..5" && ok "cabin help gives the ranges" || bad "cabin help ranges"
b_expect_exit "cluster --gather 99990" 2 "--gather: expected 0..99989 for .*cave5.json" \
  "$CAVE" cluster rankfile "$ROOT/configs/caves/cave5.json" --gather 99990
b_expect_exit "cluster --master-host ''" 2 "--master-host: expected a host name" \
  "$CAVE" cluster rankfile "$ROOT/configs/caves/cave5-2hosts.json" --master-host ""

# item 19 (bake): lighting modifiers without their light, --no-sun, --tess for a mesh file
b_expect_exit "bake --weights without --env" 2 "--weights needs --env" "$CAVE" bake default $BQ --weights 1,2 -o bw.prt
b_expect_exit "bake --scale without --env" 2 "--scale needs --env" "$CAVE" bake default $BQ --scale 2 -o bw.prt
b_expect_exit "bake --illuminance with a constant" 2 "--illuminance needs --env" \
  "$CAVE" bake default $BQ --env-constant 1,1,1 --illuminance 100 -o bw.prt
b_expect_exit "bake --yaw without lighting" 2 "--yaw needs the lighting" "$CAVE" bake default $BQ --yaw 30 -o bw.prt
b_expect_exit "bake --no-sun without lighting" 2 "--no-sun: applies to env maps" "$CAVE" bake default $BQ --no-sun -o bw.prt
b_expect_exit "bake --no-sun with --sky" 2 "--no-sun: .*not to --sky: its sun is always split out" \
  "$CAVE" bake default $BQ --sky 3,30,0 --no-sun -o bw.prt
b_expect_exit "bake --tess for a mesh file" 2 "--tess: applies to the built-in cabin, not to a mesh file" \
  "$CAVE" bake bcab.obj $BQ --tess 3 -o bw.prt
expect_absent "bake lighting errors" bw.prt
expect_ok "bake --yaw on the config's lighting, --no-sun" \
  "$CAVE" bake "$ROOT/configs/scenes/default.json" $BQ --tess 1 --yaw 30 --no-sun -o bw.prt
grep -q "lighting: 1 env map .*yaw 30" out.txt && ok "bake: --yaw applied to the config's map" \
  || { bad "bake --yaw on the config"; grep lighting out.txt; }
bhelp=$("$CAVE" bake --help)
for o in --weights --scale --illuminance --no-sun --yaw --view-budget; do
  case "$bhelp" in *"$o"*) ok "bake help lists $o" ;; *) bad "bake help lacks $o" ;; esac
done

# minor and docs: cave help <command>, cabin's default tess, materials' usage
"$CAVE" help bake | head -n 1 | grep -q "^usage: cave bake" && ok "cave help bake" || bad "cave help bake"
b_expect_exit "cave help nosuch" 2 "'nosuch' is not a command" "$CAVE" help nosuch
expect_ok "cabin default" "$CAVE" cabin -o bdef.obj
grep -q "(tess 2)" out.txt && ok "cabin default tess 2 (the default scene's)" || { bad "cabin default tess"; cat out.txt; }
"$CAVE" materials --help | head -n 1 | grep -q "| default>" && ok "materials usage names default" || bad "materials usage"
