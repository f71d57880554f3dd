# Part a of test_inputs.sh (sourced: CAVE, ROOT, a.prt and the expect_* helpers are set).

# 1. a camera Embree cannot trace: a clean error before any work (was an assertion, exit 134)
SV="--env-constant 1,1,1 --size 8x6"
expect_error "shade looking straight down" "--view-up: expected a vector not along the view" \
  "$CAVE" shade a.prt $SV --view -0.37,1.1,0.3 --look -0.37,0,0.3 -o down.png
expect_error "shade look == view" "--look: expected a point other than --view" \
  "$CAVE" shade a.prt $SV --view 0,1,0 --look 0,1,0 -o v.exr
expect_error "shade view-up along the view" "--view-up: expected a vector not along" \
  "$CAVE" shade a.prt $SV --view 0,1,0 --look 0,1,-1 --view-up 0,0,1 -o v.exr
expect_error "shade zero view-up" "--view-up: expected a non-zero x,y,z, got '0,0,0'" \
  "$CAVE" shade a.prt $SV --view -0.37,1.1,0.3 --look 0,1,-1 --view-up 0,0,0 -o v.exr
expect_error "shade eye far away" "--view: expected x,y,z within +-1e6 m, got '1e30,1,1'" \
  "$CAVE" shade a.prt $SV --view 1e30,1,1 --look 0,1,-1 -o v.exr
expect_error "reference eye far away" "--view: expected x,y,z within +-1e6 m, got '1e30,1,1'" \
  "$CAVE" reference a.prt $SV --spp 1 --view 1e30,1,1 --look 0,1,-1 -o r.exr
expect_error "reference look far away" "--look: expected x,y,z within +-1e6 m" \
  "$CAVE" reference a.prt $SV --spp 1 --view 0,1,0 --look 0,1,-2e6 -o r.exr
expect_error "reference looking straight down" "--view-up: expected a vector not along" \
  "$CAVE" reference a.prt $SV --spp 1 --view -0.37,1.1,0.3 --look -0.37,0,0.3 -o r.exr
expect_ok "shade looking down with --view-up" \
  "$CAVE" shade a.prt $SV --view -0.37,1.1,0.3 --look -0.37,0,0.3 --view-up 0,0,-1 -o down.png
expect_absent "camera errors" v.exr r.exr

# 2. an empty --env (an unset $MAP) was a segfault in shade, bake, lcd and render
expect_error "shade --env ''" "--env: expected FILE\[,FILE...\], got ''" "$CAVE" shade a.prt --env "" -o e.ply
expect_error "shade --env ," "--env: expected FILE\[,FILE...\], got ','" "$CAVE" shade a.prt --env , -o e.ply
expect_error "shade --env a,,b" "--env: expected FILE\[,FILE...\], got 'forest.exr,,city.exr'" \
  "$CAVE" shade a.prt --env forest.exr,,city.exr -o e.ply
expect_error "bake --env ''" "--env: expected FILE" \
  "$CAVE" bake default --bands 2 --rays 4 --bounces 0 --env "" -o e.prt
expect_error "lcd --env ," "--env: expected FILE" \
  "$CAVE" lcd a.prt --eye -0.37,1.1,0.3 --env , --size 40x24 --spp 1 -o e.exr
expect_error "render --env ," "--env: expected FILE" \
  "$CAVE" render "$ROOT/configs/caves/cave5.json" --scene a.prt --gpu software --size 16 --env , -o erend
expect_absent "empty --env" e.ply e.prt e.exr erend

# 4. float overflow: the scene config's ranges
expect_error "shade --env-constant 1e40" "--env-constant: expected R,G,B each in \[0, 1e9\], got '1e40,1,1'" \
  "$CAVE" shade a.prt --env-constant 1e40,1,1 -o f.ply
expect_error "render --env-constant 1e40" "--env-constant: expected R,G,B each in \[0, 1e9\]" \
  "$CAVE" render "$ROOT/configs/caves/cave5.json" --scene a.prt --gpu software --size 16 --env-constant 1e40,1,1 -o frend
expect_error "lcd --env-constant 1e40" "--env-constant: expected R,G,B each in \[0, 1e9\]" \
  "$CAVE" lcd a.prt --eye -0.37,1.1,0.3 --env-constant 1e40,1,1 --size 40x24 --spp 1 -o f.exr
expect_error "shade --scale 1e40" "--scale: expected a number in \[0, 1e9\]" \
  "$CAVE" shade a.prt --env forest.exr --scale 1e40 -o f.ply
expect_error "shade --weights 1e40" "--weights: expected weights in \[0, 1e9\]" \
  "$CAVE" shade a.prt --env forest.exr,city.exr --weights 1e40,1 -o f.ply
expect_error "shade --sky azimuth 1e300" "--sky: expected .*AZIMUTH(-360..360)" \
  "$CAVE" shade a.prt --sky 3,30,1e300 -o f.ply
expect_error "shade --yaw 1e300" "--yaw: expected degrees in \[-360, 360\]" \
  "$CAVE" shade a.prt --env-constant 1,1,1 --yaw 1e300 -o f.ply
expect_error "shade --pitch 91" "--pitch: expected degrees in \[-90, 90\]" \
  "$CAVE" shade a.prt --env-constant 1,1,1 --pitch 91 -o f.ply
expect_absent "float overflow" f.ply f.exr frend

# 5. empty fields in comma lists
expect_error "--translate 5,,0,0" "--translate: expected X,Y,Z (metres), got '5,,0,0'" \
  "$CAVE" bake default --bands 2 --rays 4 --bounces 0 --translate 5,,0,0 -o g.prt
expect_error "--rotate ,5,0,0," "--rotate: expected X,Y,Z (degrees), got ',5,0,0,'" \
  "$CAVE" bake default --bands 2 --rays 4 --bounces 0 --rotate ,5,0,0, -o g.prt
expect_error "--weights 1,,1" "--weights: expected 2 comma-separated numbers, got '1,,1'" \
  "$CAVE" shade a.prt --env forest.exr,city.exr --weights 1,,1 -o g.ply
expect_error "--view with an empty field" "--view: expected x,y,z, got '-0.37,,1.1,0.3'" \
  "$CAVE" shade a.prt --env-constant 1,1,1 --view -0.37,,1.1,0.3 --look 0,1,-1 -o g.exr
expect_error "--env-constant trailing comma" "--env-constant: expected R,G,B" \
  "$CAVE" shade a.prt --env-constant 1,1,1, -o g.ply
expect_error "--eye with an empty field" "--eye: expected x,y,z, got ',-0.37,1.1,0.3'" \
  "$CAVE" lcd a.prt --eye ,-0.37,1.1,0.3 --env-constant 1,1,1 --size 40x24 --spp 1 -o g.exr
expect_error "--head with an empty field" "--head: expected x,y,z, got '0,,1.5'" \
  "$CAVE" render "$ROOT/configs/caves/cave5.json" --scene a.prt --gpu software --size 16 --env-constant 1,1,1 --head 0,,1.5 -o grend
expect_absent "empty fields" g.prt g.ply g.exr grend

# 6. --size WxH: the whole string, integers, in range
for s in 32x24junk 32x24.9 +32x24 " 32x24" 0x24 32x16385 32 x24 32x 1e1x24; do
  expect_error "shade --size '$s'" "--size: expected WxH (1..16384), got '$s'" \
    "$CAVE" shade a.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size "$s" -o h.exr
  expect_error "reference --size '$s'" "--size: expected WxH (1..16384), got '$s'" \
    "$CAVE" reference a.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size "$s" -o h.exr
done
expect_absent "bad --size" h.exr
expect_ok "shade --size 32x24" "$CAVE" shade a.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size 32x24 -o h.exr

# 9. reference checks every output before the render and leaves nothing behind
RR="a.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size 16x12 --spp 4 --quiet"
expect_error "reference -o in a missing folder" "-o: cannot write /nonexist/r.exr" \
  "$CAVE" reference $RR -o /nonexist/r.exr
expect_error "reference --error in a missing folder" "--error: cannot write /nonexist/se.exr" \
  "$CAVE" reference $RR -o r.exr --error /nonexist/se.exr
expect_error "reference --ids in a missing folder" "--ids: cannot write /nonexist/i.exr" \
  "$CAVE" reference $RR -o r3.exr --ids /nonexist/i.exr
mkdir -p r4.png
expect_error "reference --png onto a folder" "--png: cannot write r4.png: it is a folder" \
  "$CAVE" reference $RR -o r4.exr --png
expect_error "reference --error the same as -o" "--error: 'r5.exr' is also the -o output" \
  "$CAVE" reference $RR -o r5.exr --error r5.exr
expect_absent "reference output errors" r.exr r3.exr r4.exr r5.exr
expect_error "shade -o onto a folder" "-o: cannot write r4.png: it is a folder" \
  "$CAVE" shade a.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size 8x6 -o r4.png

# 13. a misspelled flag last on the line is unknown, not "needs a value"
expect_error "shade misspelled flag last" "unknown option '--acsii'" \
  "$CAVE" shade a.prt --env-constant 1,1,1 -o k.ply --acsii
expect_error "reference misspelled flag last" "unknown option '--qiuet'" \
  "$CAVE" reference $RR -o k.exr --qiuet
expect_error "shade value option last" "option '--fov' needs a value" \
  "$CAVE" shade a.prt --env-constant 1,1,1 -o k.ply --fov
expect_error "reference value option last" "option '--spp' needs a value" \
  "$CAVE" reference $RR -o k.exr --spp
expect_absent "misspelled flags" k.ply k.exr

# 21/O1. the camera's up vector is --view-up; --up (a file's up axis) gets a hint
expect_error "shade --up x,y,z" "--up: the camera's up vector is --view-up x,y,z" \
  "$CAVE" shade a.prt --env-constant 1,1,1 --view 0,1,0 --look 0,1,-1 --up 0,1,0 -o u.exr
expect_error "reference --up x,y,z" "--up: the camera's up vector is --view-up x,y,z" \
  "$CAVE" reference $RR --up 0,1,0 -o u.exr
expect_ok "reference --view-up" "$CAVE" reference $RR --view-up 0.1,1,0 -o u.exr
expect_error "reference --view-up bad" "--view-up: expected x,y,z, got '0,1'" \
  "$CAVE" reference $RR --view-up 0,1 -o u2.exr

# 14/O3. reference --png is a flag, as in cave lcd: the preview next to -o
expect_ok "reference --png flag" "$CAVE" reference $RR -o p.exr --png
[ -s p.exr ] && [ -s p.png ] && grep -q "p.png" out.txt && ok "reference --png wrote p.png and says so" \
  || bad "reference --png: p.png missing or not named"
expect_error "reference --png FILE (the old form)" "--png: a flag (the preview goes next to -o" \
  "$CAVE" reference $RR --png p2.png -o p2.exr
expect_absent "reference --png FILE" p2.exr p2.png

# 10. reference --help ends with examples; --no-sun says why
if "$CAVE" reference --help >out.txt 2>&1 && sed -n '/^examples:/,$p' out.txt | sed -n 2p |
   grep -q "^  cave reference"; then ok "reference --help ends with examples"
else bad "reference --help has no examples"; fi
expect_error "reference --no-sun" "--no-sun: not taken: cave reference always keeps a map's sun in the map" \
  "$CAVE" reference $RR --no-sun -o ns.exr
