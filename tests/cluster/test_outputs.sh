#!/usr/bin/env bash
# The run's outputs readable (issue 33, deliverables 4 and 5), one run of 12
# ranks (a gather rank, so the LCD has rounds while the frames run) with two
# LCD panels, a turning drive, --metrics-every 2 and a small rotation size:
#  - --metrics-every 2: only even frames have lines, in every file; the
#    ready line first in the oldest file kept, the summary last in
#    metrics.jsonl; rotation: metrics.1.jsonl .. metrics.3.jsonl, each whole
#    JSON lines and within --metrics-max-mb (or one line), frames increasing
#    across the set oldest first, the summary's metrics_rotations counting
#    the rotations before it; bad values refused by --check (exit 2, the
#    option named);
#  - labelled montages: a caption band below the cross (the PNG 29 rows
#    taller) with white text in it, each wall's name in yellow at its cell's
#    corner; lcd.png has both panels' names;
#  - cave plot reads the rotated set in order and writes four PNGs (each
#    decodes, 1100 x 500); a missing file, a garbled line (named by line), a
#    set given twice and a missing -o are refused;
#  - index.html: every relative link exists, no external resource, and
#    headless Chromium renders it with the montages and the plots on it (the
#    screenshot has many colours).
# Usage: test_outputs.sh CAVE WORKDIR SRC [MPIEXEC]
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"; MPIEXEC="${4:-mpirun}"
source "$(dirname "${BASH_SOURCE[0]}")/mpi_common.sh"
S=48
cat > two.json <<'JSON'
{"mesh": {"source": "cabin", "tess": 1},
 "lcd": {"panels": [{"name": "centre"},
   {"name": "cluster", "content_luminance": 300,
    "corners": [[-0.46, 0.6813, -0.9772], [-0.28, 0.6813, -0.9772], [-0.46, 0.7596, -0.9937]]}]}}
JSON
cat > turn.json <<'JSON'
{"description": "turning under forest", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 0, "weights": [1]}, {"t": 10, "yaw": 300}]}
JSON
M=(--metrics-every 2 --metrics-max-mb 0.03 --metrics-keep 3)
timeout 600 "${MPI[@]}" -np 12 "$CAVE" run --http off "$CFG" --scene scene.prt --size $S --lcd-size 40x30 --lcd-spp 4 \
  --patches 8 --quiet --scene-config two.json --drive turn.json --frames 24 --dt 0.3 --max-fps 8 --present files \
  --write-every 8 --lcd-budget 8 --lcd-wait "${M[@]}" -o o >o.out 2>o.err; rc=$?
[ $rc -eq 0 ] && ok "run with ${M[*]}" || bad "run: rc $rc $(tail -3 o.err)"

# --- metrics: cadence and rotation ---------------------------------------------------
python3 - o > rot.txt <<'PY' && ok "rotation: $(cat rot.txt)" || bad "rotation: $(cat rot.txt)"
import json, os, sys
d = sys.argv[1]
rot = sorted((int(f.split(".")[1]), f) for f in os.listdir(d) if f.startswith("metrics.") and f.count(".") == 2)
files = [f for _, f in reversed(rot)] + ["metrics.jsonl"]
assert [k for k, _ in rot] == [1, 2, 3], rot  # --metrics-keep 3, more rotations than that
lines, prev = [], -1
for f in files:
    raw = open(os.path.join(d, f), "rb").read()
    assert raw.endswith(b"\n"), f
    ls = [json.loads(l) for l in raw.decode().splitlines()]
    assert len(raw) <= 30000 or len(ls) == 1, (f, len(raw))
    for l in ls:
        if l["type"] == "frame":
            assert l["frame"] % 2 == 0 and l["frame"] > prev, (f, l["frame"], prev)
            prev = l["frame"]
    lines += [(f, l) for l in ls]
assert lines[-1][1]["type"] == "summary" and lines[-1][0] == "metrics.jsonl"
s = lines[-1][1]
alone = len(open(os.path.join(d, "metrics.jsonl")).read().splitlines()) == 1  # the summary rotated the file itself
assert s["frames"] >= 24 and s["metrics_rotations"] + alone >= 3, (s["metrics_rotations"], alone)
assert all(l["type"] != "ready" for _, l in lines[1:])
frames = [l["frame"] for _, l in lines if l["type"] == "frame"]
assert frames[-1] == (s["frames"] - 1) // 2 * 2, (frames, s["frames"])
print("%d rotations, %d files kept, frame lines %s..%s every 2" % (s["metrics_rotations"], len(files), frames[0], frames[-1]))
PY
for bad_opt in "--metrics-every 0" "--metrics-max-mb 0.001" "--metrics-keep 0"; do
  "$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt $bad_opt >chk.out 2>&1; rc=$?
  [ $rc -eq 2 ] && grep -q "^${bad_opt%% *}: expected" chk.out && ok "--check refuses $bad_opt: $(grep '^--' chk.out)" \
    || bad "--check $bad_opt: rc $rc $(cat chk.out)"
done

# --- labels ----------------------------------------------------------------------------
cat > png.py <<'PY'
import struct, sys, zlib
def read(path):  # 8-bit RGB/RGBA, not interlaced: (w, h, rows of (r, g, b) tuples)
    d = open(path, "rb").read()
    assert d[:8] == b"\x89PNG\r\n\x1a\n", path
    i, idat, w = 8, b"", 0
    while i < len(d):
        n, t = struct.unpack(">I4s", d[i:i + 8]); c = d[i + 8:i + 8 + n]; i += 12 + n
        if t == b"IHDR": w, h, bd, ct = struct.unpack(">IIBB", c[:10]); assert bd == 8 and ct in (2, 6)
        elif t == b"IDAT": idat += c
    bpp = 3 if ct == 2 else 4
    raw, rows, prev, st = zlib.decompress(idat), [], bytearray(w * bpp), w * bpp + 1
    for y in range(h):
        f, line = raw[y * st], bytearray(raw[y * st + 1:(y + 1) * st])
        for x in range(len(line)):
            a = line[x - bpp] if x >= bpp else 0; b = prev[x]; c = prev[x - bpp] if x >= bpp else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append([tuple(line[k:k + 3]) for k in range(0, len(line), bpp)]); prev = line
    return w, h, rows
def count(rows, x0, y0, x1, y1, rgb):
    return sum(1 for y in range(y0, y1) for x in range(x0, x1) if rows[y][x] == rgb)
PY
python3 - o $S <<'PY' >lab.txt && ok "labels: $(cat lab.txt)" || bad "labels: $(cat lab.txt)"
import sys; sys.path.insert(0, "."); import png
d, S = sys.argv[1], int(sys.argv[2])
w, h, rows = png.read(d + "/montage00008_L_uncompensated.png")
assert (w, h) == (3 * S, 3 * S + 29), (w, h)  # the caption band: 3 lines of 9 px + 2
band = png.count(rows, 0, 3 * S, w, h, (255, 255, 255))
names = [png.count(rows, cx * S, cy * S, cx * S + S, cy * S + 9, (255, 255, 160)) for cx, cy in ((1, 0), (0, 1), (1, 1), (2, 1), (1, 2))]
assert band > 200 and min(names) > 20, (band, names)
lw, lh, lrows = png.read(d + "/lcd.png")
# each panel's name at its top-left: yellow runs starting in two separate row bands
ys = sorted({y for y in range(lh) if png.count(lrows, 0, y, lw, y + 1, (255, 255, 160)) > 0})
bands = 1 + sum(1 for a, b in zip(ys, ys[1:]) if b - a > 12)
tops = (len(ys), bands)
assert bands == 2, tops
print("montage %dx%d, %d white caption pixels, wall names %s yellow pixels; lcd.png: %s rows with name pixels in (rows, bands)" % (w, h, band, names, tops))
PY

# --- cave plot -----------------------------------------------------------------------------
"$CAVE" plot o/metrics.jsonl -o o/plots --index o >plot.out 2>plot.err; rc=$?
python3 - o/plots <<'PY' >plots.txt && [ $rc -eq 0 ] && ok "cave plot: $(cat plots.txt); $(grep -c wrote plot.out) lines" || bad "cave plot: rc $rc $(cat plots.txt plot.err)"
import sys; sys.path.insert(0, "."); import png
out = []
for n in ("frame_time", "swap_skew", "latency", "readability"):
    w, h, rows = png.read("%s/%s.png" % (sys.argv[1], n))
    assert (w, h) == (1100, 500), (n, w, h)
    colours = len({p for r in rows[::4] for p in r[::4]})
    assert colours > 8, (n, colours)  # lines and text, not a blank canvas
    out.append("%s.png %d colours" % (n, colours))
print(", ".join(out))
PY
grep -q "read [0-9]* frame lines from 4 files" plot.out && ok "cave plot read the rotated set: $(grep 'frame lines' plot.out)" \
  || bad "cave plot set: $(cat plot.out)"
"$CAVE" plot nothere.jsonl -o p2 >e1.out 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "nothere.jsonl: cannot read: No such file" e1.out && ok "missing file: $(cat e1.out)" || bad "missing: rc $rc $(cat e1.out)"
{ echo '{"type": "ready"}'; echo '{"type": "frame", "frame": 0, "frame_ms": 30}'; echo '{"type": "frame", "frame": 1, garbled'; } > garbled.jsonl
"$CAVE" plot garbled.jsonl -o p2 >e2.out 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "garbled.jsonl line 3: not a JSON object" e2.out && ok "garbled line: $(cat e2.out)" || bad "garbled: rc $rc $(cat e2.out)"
"$CAVE" plot o/metrics.jsonl o/metrics.jsonl -o p2 >e3.out 2>&1; rc=$?
[ $rc -eq 1 ] && grep -q "out of order, or one run's file was given twice" e3.out && ok "a set twice: $(cat e3.out)" || bad "twice: rc $rc $(cat e3.out)"
"$CAVE" plot o/metrics.jsonl >e4.out 2>&1; rc=$?
[ $rc -eq 2 ] && tail -1 e4.out | grep -q "expected -o DIR" && ok "no -o: exit 2" || bad "no -o: rc $rc $(cat e4.out)"

# --- index.html ------------------------------------------------------------------------------
python3 - o <<'PY' >idx.txt && ok "index.html: $(cat idx.txt)" || bad "index.html: $(cat idx.txt)"
import os, re, sys
d = sys.argv[1]
t = open(d + "/index.html").read()
links = set(re.findall(r'(?:src|href)="([^"]+)"', t))
assert links and not [l for l in links if "://" in l or l.startswith("/")], links
missing = [l for l in links if not os.path.exists(os.path.join(d, l))]
assert not missing, missing
last = max(int(f[7:12]) for f in os.listdir(d) if f.startswith("montage"))
need = ["montage%05d_L%s.png" % (last, v) for v in ("", "_uncompensated", "_viewer", "_viewer_uncompensated")]
need += ["lcd.png", "metrics.jsonl"] + ["plots/%s.png" % p for p in ("frame_time", "swap_skew", "latency", "readability")]
assert all(n in links for n in need), sorted(links)
print("%d relative links, all present (the 4 newest montages of frame %d, lcd.png, the 4 plots)" % (len(links), last))
PY
if command -v chromium >/dev/null; then
  timeout 120 chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=1300,2400 \
    --screenshot="$PWD/index.png" "file://$PWD/o/index.html" >chr.out 2>&1
  python3 - index.png <<'PY' >shot.txt && ok "Chromium renders index.html: $(cat shot.txt)" || bad "index.html screenshot: $(cat shot.txt) $(tail -2 chr.out)"
import sys; sys.path.insert(0, "."); import png
w, h, rows = png.read(sys.argv[1])
colours = len({p for r in rows[::3] for p in r[::3]})
assert colours > 500, colours  # photographs of the CAVE and plots, not text on a background
print("%dx%d screenshot index.png, %d colours" % (w, h, colours))
PY
else
  bad "chromium not installed (Debian package chromium; cluster/setup.sh installs it)"
fi
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
