#!/usr/bin/env bash
# `cave run --present window` on a real X server (issue 11): Xvfb started
# here with xvfb-run, Open MPI with 10-11 ranks on this machine.
#   - every wall-eye's window exists at its (tiled) geometry and shows the
#     same 8-bit codes as the PNG written for a frame (tolerance: 0 codes;
#     the scene is static, so any frame after the first few is that frame);
#   - swap skew, offset uncertainty and latency are in the metrics, finite;
#   - closing one window (WM_DELETE_WINDOW, as a window manager does) stops
#     every rank with exit 0, whole files and a message naming the rank;
#     Escape in a window does the same;
#   - --gpu 0 without a hardware EGL device: one-line error, non-zero exit;
#     --gpu software runs and says llvmpipe;
#   - quad-buffered stereo: an error naming the output.
# Usage: test_present.sh CAVE XCHECK WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
CAVE="$1"; XCHECK="$2"; WORK="$3"; SRC="$4"; MPIEXEC="${5:-mpirun}"
if [ -z "${CAVE_IN_XVFB:-}" ]; then
  command -v xvfb-run >/dev/null || { echo "FAIL: xvfb-run not installed (Debian package xvfb; cluster/setup.sh installs it)"; exit 1; }
  export CAVE_IN_XVFB=1
  exec xvfb-run -n 101 -a -s "-screen 0 1280x800x24" bash "$0" "$@"
fi
source "$(dirname "${BASH_SOURCE[0]}")/x11_common.sh"

# --- GPU choice -------------------------------------------------------------
timeout 120 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --frames 2 --gpu 0 -o g0 >g0.out 2>g0.err; rc=$?
n=$(grep -c "GPU 0" g0.err)
[ $rc -ne 0 ] && [ $rc -ne 124 ] && [ "$n" -eq 1 ] && grep -q "no hardware EGL device 0; this machine has 0" g0.err \
  && ok "--gpu 0 without a hardware device: $(grep 'GPU 0' g0.err)" || bad "--gpu 0: rc $rc, $(cat g0.err)"
timeout 300 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --frames 2 --gpu software -o gs >gs.out 2>gs.err; rc=$?
[ $rc -eq 0 ] && grep -q '"ranks"' gs/metrics.jsonl && head -1 gs/metrics.jsonl | grep -q "llvmpipe" \
  && ok "--gpu software runs and names llvmpipe in the ready line" || bad "--gpu software: rc $rc $(tail -3 gs.err)"
"$CAVE" run --http off "$CFG" "${COMMON[@]}" --gpu 3x >/dev/null 2>bad.err; rc=$?
[ $rc -eq 2 ] && grep -q "^--gpu: expected auto, software or a hardware device index" bad.err && ok "bad --gpu value: $(head -1 bad.err)" || bad "bad --gpu: rc $rc $(cat bad.err)"

# --- quad-buffered stereo where no stereo config exists ----------------------
python3 - "$CFG" > quad.json <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
outs = [{"wall": "front", "eye": "both", "stereo": "quad", "gpu": "auto"}]
for w in c["walls"][1:]:
    for e in ("left", "right"):
        outs.append({"wall": w["name"], "eye": e, "gpu": "auto"})
c["outputs"] = outs
print(json.dumps(c))
PY
"$CAVE" run --http off --check --ranks 10 quad.json --scene scene.prt >q.out 2>&1 && grep -q "rank 1: wall front, quad" q.out \
  && ok "quad config is valid: $(grep 'rank 1:' q.out)" || bad "quad --check: $(cat q.out)"
"$CAVE" run --http off --check --ranks 10 quad.json --scene scene.prt --present window >q.out 2>&1; rc=$?
[ $rc -ne 0 ] && grep -q "outputs\[0\] (wall front): quad-buffered stereo needs a stereo GL config" q.out \
  && ok "--check --present window refuses quad stereo as the run does" || bad "quad --check with windows: rc $rc $(cat q.out)"
timeout 120 "${MPI[@]}" -np 10 "$CAVE" run --http off quad.json "${COMMON[@]}" --frames 2 --present window -o q >q.out 2>q.err; rc=$?
[ $rc -ne 0 ] && [ $rc -ne 124 ] && grep -q "outputs\[0\] (wall front): quad-buffered stereo needs a stereo GL config" q.err \
  && ok "quad without a stereo config: $(grep -o 'outputs\[0\][^:]*: quad[^,]*' q.err | head -1)" || bad "quad: rc $rc $(cat q.err)"

# --- 11 ranks, windows and files ----------------------------------------------
# No scattering compensation here: its solve is warm-started and time-sliced
# (--compensation-ms), so two frames of a still scene may differ by a code or,
# when a slot runs out on a loaded machine, more; the window then shows a later
# frame than the last PNG.  Without it every frame of the still scene is the
# same image, and the window must show exactly its codes.
"${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --frames 0 --write-every 5 --clock sim \
  --no-compensation --present window,files -o w >w.out 2>w.err &
pid=$!
for i in $(seq 1 240); do [ -s w/montage00020_L.png ] && break; sleep 0.5; done
[ -s w/montage00020_L.png ] && ok "frames 0-20 shown and written" || bad "no frame 20 after 120 s: $(tail -3 w.err)"
sleep 1
"$XCHECK" grab root screen.png >/dev/null 2>&1 && ok "screenshot screen.png" || bad "screenshot"
walls=(front left right floor ceiling)
geo_ok=0; px_ok=0; worst=""
for w in 0 1 2 3 4; do
  for e in 0 1; do
    i=$((2 * w + e)); rank=$((i + 1)); eye=$([ $e -eq 0 ] && echo L || echo R)
    title="cave ${walls[$w]} $eye (rank $rank)"
    read -r id x y ww hh < <("$XCHECK" find "$title" 2>/dev/null) || true
    ex=$(( (i % 5) * S )); ey=$(( (i / 5) * S ))
    if [ "${x:-}" = "$ex" ] && [ "${y:-}" = "$ey" ] && [ "${ww:-}" = "$S" ] && [ "${hh:-}" = "$S" ]; then
      geo_ok=$((geo_ok + 1))
    else
      echo "  $title: at ${x:-?},${y:-?} ${ww:-?}x${hh:-?}, expected $ex,$ey ${S}x$S"
    fi
    last=$(ls w/frame*_${walls[$w]}_${eye}.png | tail -1)
    r=$("$XCHECK" compare "$title" "$last" 2>&1)
    if echo "$r" | grep -q "^max 0 "; then px_ok=$((px_ok + 1)); else worst="$worst [$title vs $last: $r]"; fi
  done
done
[ $geo_ok -eq 10 ] && ok "10 windows at their tiled geometry (${S}x$S, 5 per row)" || bad "window geometry: $geo_ok of 10"
[ $px_ok -eq 10 ] && ok "10 windows show exactly the PNG codes of their wall-eye (max difference 0)" || bad "window pixels: $px_ok of 10 equal;$worst"
"$XCHECK" close "cave left R (rank 4)" && ok "asked window 'cave left R (rank 4)' to close"
for i in $(seq 1 120); do kill -0 $pid 2>/dev/null || break; sleep 0.5; done
if kill -0 $pid 2>/dev/null; then bad "service still running 60 s after the window closed"; kill -TERM $pid; sleep 5; kill -KILL $pid 2>/dev/null; fi
wait $pid; rc=$?
[ $rc -eq 0 ] && grep -q "stopping: rank 4 (wall left, right eye, X display '$DISPLAY'): window closed" w.err \
  && ok "closing a window stopped every rank (exit 0): $(grep stopping w.err)" || bad "close: rc $rc, $(tail -3 w.err)"
python3 - w <<'PY' && ok "metrics: swap skew and latency present and finite; summary with the stop reason" || bad "window metrics"
import json, math, sys
lines = [json.loads(l) for l in open(sys.argv[1] + "/metrics.jsonl")]
ready = lines[0]
assert ready["type"] == "ready" and ready["windows"] and ready["swap_lock"], ready
assert all("llvmpipe" in v for v in ready["ranks"].values()), ready["ranks"]
frames = [l for l in lines if l["type"] == "frame"]
s = lines[-1]
assert s["type"] == "summary" and s["interrupted"] and "window closed" in s["stop_reason"], s
skews = [f["sync"]["swap_skew_us"] for f in frames if "swap_skew_us" in f["sync"]]
assert len(skews) >= len(frames) - 3 and all(math.isfinite(v) and v >= 0 for v in skews), skews
for k in ("swap_skew_us_p50", "swap_skew_us_p99", "swap_skew_us_max", "offset_uncertainty_us",
          "motion_to_photon_ms_p50", "motion_to_photon_ms_p99", "tracker_age_at_swap_ms_p50"):
    assert k in s and math.isfinite(s[k]) and s[k] >= 0, (k, s.get(k))
assert s["nonfinite_metrics"] == 0
print("frames", len(frames), "swap skew p50/p99/max us: %.0f / %.0f / %.0f" % (s["swap_skew_us_p50"], s["swap_skew_us_p99"], s["swap_skew_us_max"]),
      "offset uncertainty %.0f us" % s["offset_uncertainty_us"])
PY
n=$(ls w/frame*_*.png | wc -l); bad_png=0
for f in w/frame*_front_L.png; do "$XCHECK" 2>/dev/null; python3 -c "import sys; d=open('$f','rb').read(); sys.exit(0 if d[:8]==b'\x89PNG\r\n\x1a\n' and d[-8:-4]==b'IEND' else 1)" || bad_png=$((bad_png+1)); done
[ $bad_png -eq 0 ] && ok "files whole after the stop ($n PNGs)" || bad "$bad_png truncated PNGs"

# --- Escape in a window; the frame ending on the GPU (--post gpu: the window
# draws the post pass's 8-bit image, no upload) ------------------------------------
"${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --frames 0 --post gpu --no-compensation \
  --present window,files --write-every 2 -o esc >esc.out 2>esc.err &
pid=$!
for i in $(seq 1 240); do grep -q '"frame":5,' esc/metrics.jsonl 2>/dev/null && break; sleep 0.5; done
sleep 1
"$XCHECK" grab root screen_gpu.png >/dev/null 2>&1 || bad "screenshot of the --post gpu windows"
last=$(ls esc/frame*_floor_L.png 2>/dev/null | tail -1)
r=$("$XCHECK" compare "cave floor L (rank 7)" "$last" 2>&1)
echo "$r" | grep -q "^max 0 " && head -1 esc/metrics.jsonl | grep -q "frame end on the GPU" \
  && ok "--post gpu: the window shows exactly the codes of the PNG ($last)" || bad "--post gpu window vs $last: $r"
wid=$("$XCHECK" find "cave floor L (rank 7)" | cut -d' ' -f1)
xdotool key --window "$wid" Escape 2>/dev/null
for i in $(seq 1 120); do kill -0 $pid 2>/dev/null || break; sleep 0.5; done
if kill -0 $pid 2>/dev/null; then bad "Escape did not stop the service"; kill -TERM $pid; sleep 5; kill -KILL $pid 2>/dev/null; fi
wait $pid; rc=$?
[ $rc -eq 0 ] && grep -q "rank 7 (wall floor, left eye.*Escape pressed" esc.err && ok "Escape stopped the service: $(grep stopping esc.err)" \
  || bad "Escape: rc $rc $(tail -3 esc.err)"

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
