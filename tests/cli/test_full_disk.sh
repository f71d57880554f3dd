#!/usr/bin/env bash
# A full disk (issue 35, defects 1, 3 and 9), on a real 2 MB tmpfs (root only):
#  - cave render, cave lcd and cave compensate with -o on it end (within 60 s)
#    with one line naming the file and "No space left on device", exit 1,
#    and leave no *.tmp.* (they hung for ever: a self-deadlock in the EXR
#    writer's error handler);
#  - cave tonemap to PNG says "No space left on device" (not "libpng: Write
#    Error");
#  - cave lcd --drive with 28 KB free does not report a cut-short series.png
#    as written: exit 1, the plot named, no series.png, no temporary.
# Usage: test_full_disk.sh CAVE WORKDIR SRC
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"
if [ "$(id -u)" -ne 0 ]; then echo "SKIP: test_full_disk needs root (mount -t tmpfs)"; exit 0; fi
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK" || exit 1
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
mkdir full
mount -t tmpfs -o size=2m tmpfs full || { echo "FAIL: cannot mount a tmpfs"; exit 1; }
trap 'umount -l "$WORK/full" 2>/dev/null' EXIT
fill() { # fill KB: leave about KB kilobytes free (0: none)
  rm -f full/fill full/fill2
  fallocate -l $((2048 - $1))k full/fill 2>/dev/null
  [ "$1" -eq 0 ] && dd if=/dev/zero of=full/fill2 bs=1k 2>/dev/null
  return 0
}
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null || { echo "FAIL: bake"; exit 1; }
"$CAVE" shade scene.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 --look 0,1,-1 --size 32x16 -o img.exr >/dev/null 2>&1
"$CAVE" lcd scene.prt --eye 0.37,1.15,0.3 --sky 3,30,120 --spp 2 --size 40x30 -o panel.exr >/dev/null 2>&1
# expect_full NAME FILE CMD...: exit 1 within 60 s, one stderr line naming FILE and ENOSPC, no temporary
expect_full() {
  local name=$1 file=$2; shift 2
  fill 0
  timeout 60 "$@" >"$name.out" 2>"$name.err"; local rc=$?
  local n; n=$(grep -c "$file.*No space left on device" "$name.err")
  local tmp; tmp=$(find full -name '*.tmp.*' | wc -l)
  if [ $rc -eq 1 ] && [ "$n" -eq 1 ] && [ "$tmp" -eq 0 ] && [ ! -e "$file" ]; then
    ok "$name on a full disk: exit 1, '$(grep "No space" "$name.err")'"
  else
    bad "$name on a full disk: rc $rc (124: hung), $n lines naming it, $tmp temporaries: $(tail -2 "$name.err")"
  fi
}
mkdir -p full/r
expect_full render full/r/front_L.exr "$CAVE" render "$SRC/configs/caves/cave5.json" --scene scene.prt \
  --sky 3,30,120 --size 64 -o full/r
expect_full lcd full/lcd.exr "$CAVE" lcd scene.prt --eye 0.37,1.15,0.3 --sky 3,30,120 --spp 2 --size 40x30 \
  -o full/lcd.exr
expect_full compensate full/c.exr "$CAVE" compensate --display "$SRC/configs/displays/two-sided-wall.json" \
  --image img.exr -o full/c.exr --quiet
expect_full tonemap full/t.png "$CAVE" tonemap panel.exr -o full/t.png

# the drive's plot with 28 KB free: the CSV fits, the plot (about 30 KB) not
if command -v gnuplot >/dev/null; then
  printf '{ "loop": false, "sky": true, "keyframes": [\n {"t": 0, "yaw": 0, "pitch": 0, "roll": 0, "turbidity": 3, "sun_elevation": 3, "sun_azimuth": 0},\n {"t": 2, "turbidity": 3, "sun_elevation": 15} ] }\n' >rise.json
  "$CAVE" lcd scene.prt --drive rise.json --eye -0.37,1.02,0 --size 40x24 --spp 8 --dt 1 -o roomy.csv >roomy.out 2>&1
  sz=$(stat -c %s roomy.png 2>/dev/null || echo 0)
  fill 28
  mkdir -p full/d
  timeout 120 "$CAVE" lcd scene.prt --drive rise.json --eye -0.37,1.02,0 --size 40x24 --spp 8 --dt 1 \
    -o full/d/series.csv >drive.out 2>drive.err; rc=$?
  tmp=$(find full -name '*.tmp.*' | wc -l)
  if [ "$sz" -gt 28672 ] && [ $rc -eq 1 ] && ! grep -q "wrote.*series.png" drive.out && [ ! -e full/d/series.png ] \
     && [ "$tmp" -eq 0 ] && grep -q "series.png: not written" drive.err; then
    ok "lcd --drive, 28 KB free (the plot is $sz bytes): exit 1, '$(cat drive.err)'"
  else
    bad "lcd --drive with 28 KB free: plot $sz bytes, rc $rc, $tmp temporaries, $(ls full/d); $(tail -1 drive.out) $(cat drive.err)"
  fi
else
  echo "SKIP: lcd --drive plot (gnuplot is not installed)"
fi
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
