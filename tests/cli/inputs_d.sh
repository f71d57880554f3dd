# Part d of test_inputs.sh (sourced: CAVE, ROOT, a.prt and the expect_* helpers are set):
# the follow-ups: an unknown option last on the line is "unknown" in every
# command (a known one without its value "needs a value"), a folder given as
# a display description says so, --size is strict in cave lcd too.
EYE_D="--eye -0.37,1.1,0.3"
expect_error "lcd: unknown option last" "unknown option '--acsii'" \
  "$CAVE" lcd a.prt $EYE_D --env-constant 1,1,1 -o d.exr --acsii
expect_error "lcd: --spp last" "option '--spp' needs a value" \
  "$CAVE" lcd a.prt $EYE_D --env-constant 1,1,1 -o d.exr --spp
expect_error "bake: unknown option last" "unknown option '--acsii'" "$CAVE" bake default -o d.prt --acsii
expect_error "bake: --rays last" "option '--rays' needs a value" "$CAVE" bake default -o d.prt --rays
expect_error "cabin: unknown option last" "unknown option '--nope'" "$CAVE" cabin -o d.obj --nope
expect_error "cabin: --tess last" "option '--tess' needs a value" "$CAVE" cabin -o d.obj --tess
expect_error "tonemap: --lwa last" "option '--lwa' needs a value" "$CAVE" tonemap in.exr -o d.png --lwa
expect_error "tonemap: unknown option last" "unknown option '--zz'" "$CAVE" tonemap in.exr -o d.png --zz
expect_error "render: --frames last" "option '--frames' needs a value" \
  "$CAVE" render "$ROOT/configs/caves/cave5.json" --scene a.prt --env-constant 1,1,1 -o drnd --frames
expect_error "render: unknown option last" "unknown option '--zz'" \
  "$CAVE" render "$ROOT/configs/caves/cave5.json" --scene a.prt --env-constant 1,1,1 -o drnd --zz
expect_error "compensate: unknown option last" "unknown option '--zz'" \
  "$CAVE" compensate --display "$ROOT/configs/displays/two-sided-wall.json" --image x.exr -o dI.exr --zz
expect_error "compensate: --levels last" "option '--levels' needs a value" \
  "$CAVE" compensate --display "$ROOT/configs/displays/two-sided-wall.json" --image x.exr -o dI.exr --levels
mkdir -p ddisp.json
expect_error "compensate: a folder as the display" "ddisp.json: is a folder, expected a JSON file" \
  "$CAVE" compensate --display ddisp.json --image x.exr -o dI.exr
expect_error "lcd: --size with a third field" "--size: expected WxH (1..16384), got '3x4x'" \
  "$CAVE" lcd a.prt $EYE_D --env-constant 1,1,1 --size 3x4x -o d.exr
expect_absent "follow-ups: no output" d.exr d.prt d.obj d.png drnd dI_left.exr
