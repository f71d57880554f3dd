# Part c of test_inputs.sh (sourced: CAVE, ROOT, a.prt and the expect_* helpers are set).
# cave lcd, cave run --check, the config readers, the child-limit variables.
L="--env-constant 1,1,1 --spp 1"
EYE="--eye -0.37,1.1,0.3"

# --size WxH strictly (CLI item 6)
expect_error "lcd --size junk" "--size: expected WxH (1..16384), got '32x24junk'" $CAVE lcd a.prt $EYE $L --size 32x24junk -o p.exr
expect_error "lcd --size fraction" "--size: expected WxH (1..16384), got '32x24.9'" $CAVE lcd a.prt $EYE $L --size 32x24.9 -o p.exr
# an eye behind the panel or outside the car (CLI item 7)
expect_error "lcd eye behind the panel" "--eye: 0,0.6,-1.1 is behind panel 'lcd'" $CAVE lcd a.prt $L --size 8x6 --eye 0,0.6,-1.1 -o p.exr
expect_error "lcd eye outside the car" "--eye: 100,100,100 is outside the scene" $CAVE lcd a.prt $L --size 8x6 --eye 100,100,100 -o p.exr
# outputs checked before the rounds; nothing left behind (CLI item 10)
rm -f p.exr p.exr.json p.cr.png
expect_error "lcd -o missing folder" "-o: cannot write /nonexist/p.exr" $CAVE lcd a.prt $EYE $L --size 8x6 -o /nonexist/p.exr
expect_error "lcd --heatmap missing folder" "--heatmap: cannot write /nonexist/h.png" $CAVE lcd a.prt $EYE $L --size 8x6 -o p.exr --heatmap /nonexist/h.png
expect_absent "lcd --heatmap missing folder" p.exr p.exr.json
mkdir -p hdir.png
expect_error "lcd --heatmap a folder" "hdir.png" $CAVE lcd a.prt $EYE $L --size 8x6 -o p.exr --heatmap hdir.png
expect_absent "lcd --heatmap a folder" p.exr p.exr.json
# float options range-checked up front (CLI item 4)
expect_error "lcd --luminance 1e40" "--luminance: expected cd/m^2 in 0..1e6, got '1e40'" $CAVE lcd a.prt $EYE $L --luminance 1e40 -o p.exr
expect_error "lcd --black 1e40" "--black: expected cd/m^2 in 0..1e6" $CAVE lcd a.prt $EYE $L --black 1e40 -o p.exr
expect_error "lcd --adaptation 1e40" "--adaptation: expected cd/m^2 in 0..1e6" $CAVE lcd a.prt $EYE $L --adaptation 1e40 -o p.exr
expect_error "lcd --cr-min 1e40" "--cr-min: expected a ratio in 1..1000" $CAVE lcd a.prt $EYE $L --cr-min 1e40 -o p.exr
# one seed range for lcd.seed and --seed (docs C4)
expect_error "lcd --seed 2^32" "--seed: expected 0..4294967295" $CAVE lcd a.prt $EYE $L --seed 4294967296 -o p.exr
expect_ok "lcd --seed 2^32-1" $CAVE lcd a.prt $EYE $L --size 8x6 --seed 4294967295 -o p.exr
# an option overrides every panel's own value (docs C2)
printf '{"lcd": {"panels": [{"name": "lcd", "resolution": [20, 12], "content_luminance": 300}]}}\n' >own.json
expect_ok "lcd --size over a panel's resolution" $CAVE lcd a.prt $EYE $L --lcd-config own.json --size 8x6 --luminance 200 -o p.exr
if grep -q '"width": 8, "height": 6' p.exr.json && grep -q '"white_luminance": 200' p.exr.json; then ok "lcd options override the panel"; else bad "lcd options override the panel: $(head -c 300 p.exr.json)"; fi
expect_ok "run --lcd-size over a panel's resolution" $CAVE run --check --ranks 11 "$ROOT/configs/caves/cave5.json" --scene a.prt --scene-config own.json --lcd-size 8x6
if grep -q "lcd 8x6 texels" out.txt; then ok "run --lcd-size overrides the panel"; else bad "run --lcd-size overrides the panel: $(grep LCD out.txt)"; fi

# cave run --check refuses what the run refuses (CLI item 12)
C5="$ROOT/configs/caves/cave5.json"
head -c 400000 a.prt >trunc.prt
expect_error "run --check truncated prt" "cave run: 1 problem" $CAVE run --check --ranks 11 "$C5" --scene trunc.prt
grep -q "need a [0-9]*-byte payload" err.txt && ok "run --check names the payload" || bad "run --check names the payload: $(cat err.txt)"
expect_error "run --check truncated prt --no-lcd" "cave run: 1 problem" $CAVE run --check --ranks 11 "$C5" --scene trunc.prt --no-lcd
expect_error "run --check -o a file" "cave run: 1 problem" $CAVE run --check --ranks 11 "$C5" --scene a.prt -o a.prt
grep -q "^-o: a.prt: is a file, expected a folder" err.txt && ok "run -o a file named" || bad "run -o a file named: $(cat err.txt)"
expect_error "run --check --metrics missing folder" "cave run: 1 problem" $CAVE run --check --ranks 11 "$C5" --scene a.prt --metrics /nonexist/m.jsonl
grep -q "^--metrics: cannot write /nonexist/m.jsonl" err.txt && ok "run --metrics named" || bad "run --metrics named: $(cat err.txt)"
expect_error "run --check --dtrack-host" "cave run: 1 problem" $CAVE run --check --ranks 11 "$C5" --scene a.prt --dtrack 5000 --dtrack-host 999.1.1.1
grep -q "^--dtrack-host: '999.1.1.1' is not an IPv4 address" err.txt && ok "run --dtrack-host named" || bad "run --dtrack-host named: $(cat err.txt)"
expect_error "run --check --lcd-content not an image" "cave run: 1 problem" $CAVE run --check --ranks 11 "$C5" --scene a.prt --lcd-content a.prt
grep -q "^--lcd-content: a.prt" err.txt && ok "run --lcd-content named" || bad "run --lcd-content named: $(cat err.txt)"
# the same ranges as the configs (docs C4)
expect_error "run --reflectance 1" "cave run: 1 problem" $CAVE run --check --ranks 11 "$C5" --scene a.prt --reflectance 1
expect_ok "run --lcd-tolerance 1e-5 --seed 2^32-1" $CAVE run --check --ranks 11 "$C5" --scene a.prt --lcd-tolerance 1e-5 --seed 4294967295
# a CAVE config stands in for a display description (docs C1)
expect_ok "run --display CAVE config" $CAVE run --check --ranks 11 "$C5" --scene a.prt --display "$C5"

# a folder where a config is expected (CLI item 16)
mkdir -p dj.json
expect_error "bake config folder" "dj.json: is a folder, expected a JSON file" $CAVE bake dj.json -o x.prt
expect_error "run config folder" "cave run: 1 problem" $CAVE run --check --ranks 11 dj.json --scene a.prt
grep -q "^dj.json: is a folder, expected a JSON file" err.txt && ok "run config folder named" || bad "run config folder named: $(cat err.txt)"
expect_error "lcd --lcd-config folder" "dj.json: is a folder, expected a JSON file" $CAVE lcd a.prt $EYE $L --lcd-config dj.json -o p.exr
printf '{"lighting": {"env": ""}}\n' >envempty.json
expect_error "scene lighting.env empty" "envempty.json: lighting.env: expected a file name" $CAVE lcd envempty.json $EYE $L -o p.exr
# exact range limits (CLI item 17)
printf '{"prt": {"rays": -3}}\n' >rays.json
expect_error "prt.rays range" "prt.rays: -3 is outside \[1, 16777216\]" $CAVE bake rays.json -o x.prt
printf '{"prt": {"seed": -1}}\n' >seed.json
expect_error "prt.seed range" "prt.seed: -1 is outside \[0, 2147483647\]" $CAVE bake seed.json -o x.prt

# the child limits' variables (CLI item 20)
"$CAVE" cabin -o cab.obj >/dev/null 2>&1
CAVE_IMPORT_TIMEOUT=abc expect_error "CAVE_IMPORT_TIMEOUT bad" "CAVE_IMPORT_TIMEOUT: expected seconds >= 0 (0 = none), got 'abc'" $CAVE bake cab.obj --bands 2 --rays 4 --bounces 0 -o x.prt --quiet
CAVE_IMPORT_MEMORY_MB=-5 expect_error "CAVE_IMPORT_MEMORY_MB bad" "CAVE_IMPORT_MEMORY_MB: expected megabytes >= 0" $CAVE bake cab.obj --bands 2 --rays 4 --bounces 0 -o x.prt --quiet
expect_absent "bad limit variable" x.prt
