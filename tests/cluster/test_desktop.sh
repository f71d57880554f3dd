#!/usr/bin/env bash
# `cave run --present desktop` (issue 11, deliverable 6) on a real X server
# (Xvfb, started here with xvfb-run), Open MPI with 11 ranks on this machine:
#   - option checks: desktop with window, a bad --desktop-view: status 2;
#   - no X display (DISPLAY=:987, no server there): one line naming it,
#     non-zero exit, quickly;
#   - the preview window exists with its title at the composed picture's
#     size (the cross, the view along the gaze beside it, three readout
#     lines below) times the largest whole scale within 80% of the screen,
#     and its cross shows exactly the codes of the (labelled) uncompensated
#     montage the master wrote, wall names included (the scene is static, so
#     any frame after the first few is that frame); the cross's 3 x 3 cells:
#     the five walls lit, the four corners black;
#   - Right x4 moves the metrics' tracker head 4 x 5 cm along +x; a left
#     drag of 40 pixels turns the gaze 10 degrees right; R resets both;
#   - a drag of 200 pixels (50 degrees) changes the view along the gaze
#     (mean code difference before/after) more than 3 times as much as the
#     cross changes (whose walls do not depend on the gaze);
#   - closing the window stops every rank with exit 0, whole files and a
#     message naming the desktop window;
#   - --desktop-view front: the one wall, the same codes as its
#     _uncompensated PNG; Escape stops the service.
# Usage: test_desktop.sh CAVE XCHECK WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
CAVE="$1"; XCHECK="$2"; WORK="$3"; SRC="$4"; MPIEXEC="${5:-mpirun}"
if [ -z "${CAVE_IN_XVFB:-}" ]; then
  command -v xvfb-run >/dev/null || { echo "FAIL: xvfb-run not installed (Debian package xvfb; cluster/setup.sh installs it)"; exit 1; }
  export CAVE_IN_XVFB=1
  exec xvfb-run -n 121 -a -s "-screen 0 1280x800x24" bash "$0" "$@"
fi
source "$(dirname "${BASH_SOURCE[0]}")/x11_common.sh"
TITLE="cave desktop preview (cross)"

# The newest frame line's tracker: "hx hy hz gx gy gz" (metrics of run $1).
tracker() {
  python3 - "$1" <<'PY'
import json, sys
last = None
for l in open(sys.argv[1] + "/metrics.jsonl"):
    try:
        j = json.loads(l)
    except ValueError:
        continue  # a line being written
    if j.get("type") == "frame":
        last = j
t = last["tracker"] if last else None
print(" ".join("%.9f" % v for v in t["head"] + t["gaze"]) if t else "")
PY
}
# Waits (at most $3 s) until the tracker of run $1 satisfies the python
# expression $2 over h (head) and g (gaze); prints the tracker.
wait_tracker() {
  local run="$1" expr="$2" t=""
  for i in $(seq 1 $(( $3 * 4 ))); do
    t=$(tracker "$run")
    if [ -n "$t" ] && python3 -c "import sys; v=[float(x) for x in sys.argv[1].split()]; h, g = v[:3], v[3:]; sys.exit(0 if ($expr) else 1)" "$t"; then
      echo "$t"; return 0
    fi
    sleep 0.25
  done
  echo "$t"; return 1
}

# --- option checks (no MPI) -------------------------------------------------------
"$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt --present desktop,window >c1.out 2>&1; rc=$?
[ $rc -eq 2 ] && grep -q "^--present desktop and window do not combine" c1.out \
  && ok "desktop with window refused: $(grep 'do not combine' c1.out | cut -c1-60)..." || bad "desktop,window: rc $rc $(cat c1.out)"
"$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt --present desktop --desktop-view side >c2.out 2>&1; rc=$?
[ $rc -eq 2 ] && grep -q "^--desktop-view: expected cross or a wall of .* (front, left, right, floor, ceiling), got 'side'" c2.out \
  && ok "bad --desktop-view: $(head -1 c2.out | sed 's|/.*cave5.json|cave5.json|')" || bad "--desktop-view side: rc $rc $(cat c2.out)"
"$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt --present desktop,files >c3.out 2>&1; rc=$?
[ $rc -eq 0 ] && grep -q "desktop preview on \$DISPLAY (cross)" c3.out && ok "desktop,files is valid: $(head -1 c3.out)" \
  || bad "desktop,files --check: rc $rc $(cat c3.out)"

# --- no X display ---------------------------------------------------------------------
t0=$(date +%s.%N)
DISPLAY=:987 timeout 120 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --frames 2 --present desktop -o nod \
  >nod.out 2>nod.err; rc=$?
secs=$(python3 -c "import time, sys; print('%.1f' % (time.time() - float(sys.argv[1])))" "$t0")
n=$(grep -c "desktop" nod.err)
[ $rc -ne 0 ] && [ $rc -ne 124 ] && [ "$n" -eq 1 ] && grep -q "rank 0 (master): --present desktop: cannot open X display ':987'" nod.err \
  && ok "no X display: exit $rc after $secs s: $(grep desktop nod.err)" || bad "no display: rc $rc, $n lines: $(cat nod.err)"

# --- 11 ranks, the cross, keys, mouse, close ------------------------------------------
"${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --frames 0 --write-every 5 --clock sim --desktop-fps 0 \
  --present desktop,files -o d >d.out 2>d.err &
pid=$!
for i in $(seq 1 240); do [ -s d/montage00020_L_uncompensated.png ] && break; sleep 0.5; done
[ -s d/montage00020_L_uncompensated.png ] && ok "frames 0-20 previewed and written" || bad "no frame 20 after 120 s: $(tail -3 d.err)"
read -r wid x y ww hh < <("$XCHECK" find "$TITLE" 2>/dev/null) || true
# composed: cross 3S x 3S, the gaze view 3S x 3S beside it, a band of 3 lines of 9 px + 2 below
# (label scale 1 below 192-px walls); the window K times that, K the largest whole number
# within 80% of the 1280 x 800 screen
CW=$((6 * S)); CH=$((3 * S + 29))
K=$(python3 -c "import math; print(max(1, math.floor(min(0.8 * 1280 / $CW, 0.8 * 800 / $CH))))")
[ "${ww:-}" = $((K * CW)) ] && [ "${hh:-}" = $((K * CH)) ] && ok "window '$TITLE' ${ww}x$hh ($K x ${CW}x$CH: cross, gaze view, readouts)" \
  || bad "window '$TITLE': ${wid:-none} ${ww:-?}x${hh:-?}, expected $((K * CW))x$((K * CH))"
same=0
for try in 1 2 3; do
  mont=$(ls d/montage*_L_uncompensated.png | tail -1)
  r=$("$XCHECK" compare "$TITLE" "$mont" "$K" $((3 * S)) 2>&1)
  echo "$r" | grep -q "^max 0 " && { same=1; break; }
  sleep 1
done
[ $same -eq 1 ] && ok "the window shows exactly the codes of $mont (max difference 0)" || bad "window vs $mont: $r"
"$XCHECK" grab "$TITLE" desktop.png >/dev/null 2>&1 && ok "screenshot desktop.png" || bad "screenshot"
"$XCHECK" cells "$TITLE" 3 3 $((K * 3 * S)) $((K * 3 * S)) > cells.txt
python3 - cells.txt <<'PY' && ok "cross layout: ceiling / left front right / floor lit, the four corners black" || bad "cells: $(tr '\n' ';' < cells.txt)"
import sys
cells = {(int(c), int(r)): (float(m), int(x)) for c, r, m, x in (l.split() for l in open(sys.argv[1]))}
lit = {(1, 0), (0, 1), (1, 1), (2, 1), (1, 2)}
for k, (mean, mx) in cells.items():
    assert (mean > 5) if k in lit else (mx == 0), (k, mean, mx)
PY
# Right x4: +4 x 5 cm along x (the gaze looks along -z: right is +x)
read -r h0x h0y h0z _ < <(tracker d)
xdotool key --window "$wid" Right Right Right Right 2>/dev/null
t=$(wait_tracker d "abs(h[0] - ($h0x + 0.2)) < 1e-6 and abs(h[1] - $h0y) < 1e-9 and abs(h[2] - $h0z) < 1e-9" 30) \
  && ok "Right x4: tracker head ($h0x, $h0y, $h0z) -> $(echo $t | cut -d' ' -f1-3) (+0.20 m in x)" \
  || bad "Right x4: head ($h0x, $h0y, $h0z) -> $t"
python3 - d <<'PY' && ok "metrics: tracker source desktop, age and desktop inputs in the frame lines" || bad "tracker metrics"
import json, sys
fr = [json.loads(l) for l in open(sys.argv[1] + "/metrics.jsonl") if '"type":"frame"' in l][-3:]
for f in fr:
    assert f["tracker"]["source"] == "desktop" and 0 <= f["tracker"]["age_s"] < 5, f["tracker"]
    assert f["desktop"]["inputs"] >= 1 and f["desktop"]["shown"] > 0, f["desktop"]
PY
# a left drag of 40 pixels to the right: the gaze turns 40 x 0.25 = 10 degrees right
xdotool mousemove --window "$wid" 60 96 mousedown 1 mousemove --window "$wid" 80 96 \
  mousemove --window "$wid" 100 96 mouseup 1 2>/dev/null
t=$(wait_tracker d "abs(g[0] - 0.173648) < 1e-3 and abs(g[2] + 0.984808) < 1e-3 and abs(g[1]) < 1e-9" 30) \
  && ok "left drag 40 px: gaze -> $(echo $t | cut -d' ' -f4-6) (10 degrees right)" || bad "drag: gaze $t"
# a drag of 200 pixels: 50 degrees; the view along the gaze turns, the cross barely changes
sleep 1
"$XCHECK" grab "$TITLE" before_drag.png >/dev/null 2>&1
xdotool mousemove --window "$wid" 60 96 mousedown 1 mousemove --window "$wid" 160 96 \
  mousemove --window "$wid" 260 96 mouseup 1 2>/dev/null
t=$(wait_tracker d "abs(g[0] - 0.866025) < 1e-3 and abs(g[2] + 0.5) < 1e-3" 30) || bad "drag 200 px: gaze $t"
sleep 2
"$XCHECK" grab "$TITLE" after_drag.png >/dev/null 2>&1
P=$((K * 3 * S))
dg=$("$XCHECK" diff before_drag.png after_drag.png $P 0 $P $P 2>&1); dc=$("$XCHECK" diff before_drag.png after_drag.png 0 0 $P $P 2>&1)
python3 -c "import sys; g, c = float(sys.argv[1]), float(sys.argv[2]); sys.exit(0 if g > 5 and g > 3 * c else 1)" "$dg" "$dc" 2>/dev/null \
  && ok "drag 200 px (gaze 10 -> 60 degrees right): the view along the gaze changed by $dg codes (mean), the cross by $dc" \
  || bad "drag 200 px: view along the gaze changed by $dg, the cross by $dc (before_drag.png, after_drag.png)"
xdotool key --window "$wid" r 2>/dev/null
t=$(wait_tracker d "abs(h[0]) < 1e-9 and abs(h[1] - 1.2) < 1e-9 and abs(h[2]) < 1e-9 and abs(g[2] + 1) < 1e-9" 30) \
  && ok "R: back to the config's head and gaze: $t" || bad "R: $t"
"$XCHECK" close "$TITLE" && ok "asked '$TITLE' to close"
for i in $(seq 1 120); do kill -0 $pid 2>/dev/null || break; sleep 0.5; done
if kill -0 $pid 2>/dev/null; then bad "service still running 60 s after the window closed"; kill -TERM $pid; sleep 5; kill -KILL $pid 2>/dev/null; fi
wait $pid; rc=$?
[ $rc -eq 0 ] && grep -q "stopping: desktop window (rank 0, X display '.*'): window closed" d.err \
  && ok "closing the window stopped every rank (exit 0): $(grep stopping d.err)" || bad "close: rc $rc, $(tail -3 d.err)"
python3 - d <<'PY' && ok "summary: stop reason, previews shown" || bad "summary"
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1] + "/metrics.jsonl")]
assert lines[0]["type"] == "ready" and lines[0]["desktop"] and not lines[0]["windows"], lines[0]
s = lines[-1]
assert s["type"] == "summary" and s["interrupted"] and "desktop window" in s["stop_reason"], s
assert 10 <= s["desktop_previews"] <= s["desktop_preview_frames"] and s["nonfinite_metrics"] == 0, s
print("frames", s["frames"], "previews", s["desktop_previews"], "of", s["desktop_preview_frames"], "marked",
      "fps %.1f" % s["fps"])
PY
bad_png=0; n=0
for f in d/*.png; do
  n=$((n + 1))
  python3 -c "import sys; d=open('$f','rb').read(); sys.exit(0 if d[:8]==b'\x89PNG\r\n\x1a\n' and d[-8:-4]==b'IEND' else 1)" || bad_png=$((bad_png + 1))
done
[ $bad_png -eq 0 ] && ok "files whole after the stop ($n PNGs)" || bad "$bad_png truncated PNGs"

# --- one wall, Escape -----------------------------------------------------------------
"${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --frames 0 --write-every 5 --clock sim \
  --present desktop,files --desktop-view front -o f >f.out 2>f.err &
pid=$!
for i in $(seq 1 240); do [ -s f/montage00010_L.png ] && break; sleep 0.5; done
FT="cave desktop preview (front)"
FW=$((2 * S)); FH=$((S + 29)) # the wall, the gaze view as tall, the readouts
KF=$(python3 -c "import math; print(max(1, math.floor(min(0.8 * 1280 / $FW, 0.8 * 800 / $FH))))")
read -r wid x y ww hh < <("$XCHECK" find "$FT" 2>/dev/null) || true
same=0
for try in 1 2 3; do
  png=$(ls f/frame*_front_L_uncompensated.png | tail -1)
  r=$("$XCHECK" compare "$FT" "$png" "$KF" "$S" 2>&1)
  echo "$r" | grep -q "^max 0 " && { same=1; break; }
  sleep 1
done
[ "${ww:-}" = $((KF * FW)) ] && [ "${hh:-}" = $((KF * FH)) ] && [ $same -eq 1 ] && ok "--desktop-view front: ${ww}x$hh ($KF x ${FW}x$FH), the codes of $png" || bad "front view: ${ww:-?}x${hh:-?} $r"
xdotool key --window "$wid" Escape 2>/dev/null
for i in $(seq 1 120); do kill -0 $pid 2>/dev/null || break; sleep 0.5; done
if kill -0 $pid 2>/dev/null; then bad "Escape did not stop the service"; kill -TERM $pid; sleep 5; kill -KILL $pid 2>/dev/null; fi
wait $pid; rc=$?
[ $rc -eq 0 ] && grep -q "stopping: desktop window .*: Escape pressed" f.err && ok "Escape stopped the service: $(grep stopping f.err)" \
  || bad "Escape: rc $rc $(tail -3 f.err)"

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
