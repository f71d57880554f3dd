#!/usr/bin/env bash
# End-to-end tests of `cave run` under mpirun (issue 6): an 11-rank run gives
# finite frames for every wall-eye and one adaptation state on all ranks; the
# LCD image is bit-identical for 11 and 13 ranks at the same sample budget;
# a stopped gather rank does not stall the frames beyond the timeout; SIGTERM
# ends the run cleanly with whole files; configuration errors are reported
# before anything starts.
# Usage: test_cluster.sh CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"; MPIEXEC="${4:-mpirun}"
source "$(dirname "${BASH_SOURCE[0]}")/mpi_common.sh"
cat > still.json <<'JSON'
{"description": "standing still under forest", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 30, "weights": [1]}, {"t": 10, "yaw": 30}]}
JSON
COMMON=(--scene scene.prt --size 48 --lcd-size 40x30 --lcd-spp 4 --patches 8 --quiet)
# Two LCD panels: the cabin's (the centre display, its triangles tagged lcd)
# and an instrument cluster in front of the driver on the same dashboard face.
cat > two.json <<'JSON'
{"mesh": {"source": "cabin", "tess": 1},
 "lcd": {"panels": [{"name": "centre"},
   {"name": "cluster", "content_luminance": 300,
    "corners": [[-0.46, 0.6813, -0.9772], [-0.28, 0.6813, -0.9772], [-0.46, 0.7596, -0.9937]]}]}}
JSON

# --- configuration errors before launch ------------------------------------
"$CAVE" run --http off --check --ranks 3 "$CFG" --scene scene.prt >out.txt 2>err.txt; rc=$?
[ $rc -ne 0 ] && grep -q "at least 1 + 10 = 11 ranks" err.txt && ok "too few ranks (check): $(head -1 err.txt)" || bad "too few ranks: rc $rc $(cat err.txt)"
"$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt >out.txt 2>err.txt \
  && grep -q "rank 10: wall ceiling, right eye" out.txt && ok "layout: $(cat out.txt)" || bad "layout $(cat out.txt err.txt)"
sed 's/"name": "left"/"name": "front"/' "$CFG" > dup.json
"$CAVE" run --http off --check --ranks 11 dup.json --scene missing.prt --drive nodrive.json >out.txt 2>err.txt; rc=$?
n=$(grep -c "" err.txt)
[ $rc -ne 0 ] && grep -q "front" err.txt && grep -q "missing.prt" err.txt && grep -q "nodrive.json" err.txt \
  && ok "every problem listed ($n lines)" || bad "problem list: $(cat err.txt)"
sed 's/-0.9772\]/-3.5]/g; s/-0.9937\]/-3.5165]/' two.json > outside.json
"$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt --scene-config outside.json >out.txt 2>err.txt; rc=$?
[ $rc -eq 2 ] && grep -q "outside.json: lcd.panels\[1\].corners\[0\]: .*outside the scene" err.txt \
  && ok "panel outside the scene (check): $(head -1 err.txt)" || bad "panel outside the scene: rc $rc $(cat err.txt)"
timeout 120 "${MPI[@]}" -np 3 "$CAVE" run --http off "$CFG" "${COMMON[@]}" -o r3 >out.txt 2>err.txt; rc=$?
[ $rc -ne 0 ] && [ $rc -ne 124 ] && grep -q "11 ranks" err.txt && ok "mpirun with too few ranks ends at once (rc $rc)" || bad "mpirun too few ranks: rc $rc $(tail -3 err.txt)"

# --- 11 ranks, a few frames ------------------------------------------------
timeout 600 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --drive still.json --frames 4 \
  --write-every 2 --lcd-budget 20 -o r11 >out11.txt 2>err11.txt; rc=$?
if [ $rc -eq 0 ]; then ok "11-rank run"; else bad "11-rank run rc $rc: $(tail -5 err11.txt)"; fi
nexr=$(ls r11/frame00003_*.exr 2>/dev/null | wc -l)
[ "$nexr" -eq 10 ] && ok "10 wall-eye EXRs for the last frame" || bad "wall-eye EXRs: $nexr"
[ -s r11/montage00003_L.png ] && ok "montage written" || bad "no montage"
python3 - r11 <<'PY' && ok "metrics: every frame on time, one adaptation state from frame 0's luminance, finite" || bad "metrics"
import json, math, sys
lines = [json.loads(l) for l in open(sys.argv[1] + "/metrics.jsonl")]
frames = [l for l in lines if l["type"] == "frame"]
summary = [l for l in lines if l["type"] == "summary"]
assert len(frames) == 4 and len(summary) == 1, (len(frames), len(summary))
for f in frames:
    assert f["late_walleyes"] == 0, f
    assert f["state_mismatch"] == 0, f
    a = f["adaptation"]
    assert a["lwa"] is not None and math.isfinite(a["lwa"]) and a["lwa"] > 0, a
# adaptation starts from frame 0's own luminance (the priming round), not
# 1 cd/m2: standing still, frame 0 and frame 1 are adapted alike
l0, l1 = frames[0]["adaptation"]["lwa"], frames[1]["adaptation"]["lwa"]
assert abs(l0 - 1.0) > 1e-3 and abs(l0 / l1 - 1) < 0.1, (l0, l1)
print("lwa per frame:", [round(f["adaptation"]["lwa"], 4) for f in frames],
      "master p99 ms:", summary[0].get("master_ms_p99"))
PY
"$CAVE" tonemap r11/frame00003_front_L.exr -o front.png >tm.txt 2>&1 && grep -q "invalid 0\|0 invalid" tm.txt \
  && ok "front wall EXR finite" || bad "front EXR: $(cat tm.txt)"

# --- calibrated tracker: DTrack packets on loopback -> both eyes per frame ---
TPORT=$(python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cat > trk.json <<JSON
{"units": "mm", "body_id": 3, "room_to_cave": {"rotate_deg": [0, 90, 0], "translate": [0, 0, 1]},
 "eye_offset": [0, -0.1, -0.08], "ipd": 0.064, "udp": {"port": $TPORT, "bind": "127.0.0.1"}}
JSON
printf '{"units": "furlong"}\n' >badtrk.json
"$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt --tracker badtrk.json >out.txt 2>err.txt; rc=$?
[ $rc -ne 0 ] && grep -q "\-\-tracker: badtrk.json: units: unknown unit 'furlong'" err.txt && ok "bad tracker config listed" || bad "bad tracker config: $(cat err.txt)"
python3 - "$TPORT" <<'PY' &
import socket, sys, time
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
ok = b"fr %d\r\n6d 1 [3 1.000][1000 1500 -500 0 0 0][1 0 0 0 1 0 0 0 1]\r\n"
t0 = time.time(); n = 0
while time.time() - t0 < 60:
    n += 1
    for p in (ok % n, b"fr 0\r\n6d 1 [3 1.000][nan 0 0 0 0 0][1 0 0 0 1 0 0 0 1]\r\n", b"fr 0\r\n6d 0\r\n"):
        s.sendto(p, ("127.0.0.1", int(sys.argv[1])))
    time.sleep(0.02)
PY
spid=$!
timeout 300 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --drive still.json --frames 12 --max-fps 8 \
  --no-compensation --tracker trk.json -o rt >outrt.txt 2>errrt.txt; rc=$?
kill $spid 2>/dev/null; wait $spid 2>/dev/null
python3 - rt <<'PY' && ok "tracker config: calibrated eyes in every frame after the first packet, NaN and missing body counted" || bad "calibrated tracker (rc $rc): $(tail -3 errrt.txt)"
import json, sys
frames = [json.loads(l) for l in open(sys.argv[1] + "/metrics.jsonl")]
frames = [f for f in frames if f["type"] == "frame"]
t = frames[-1]["tracker"]
assert t["source"] == "dtrack-calibrated", t
want = [-0.58, 1.4, 0.032, -0.58, 1.4, -0.032]
assert all(abs(a - b) < 1e-9 for a, b in zip(t["eyes"], want)), t["eyes"]
assert all(abs(a - b) < 1e-9 for a, b in zip(t["head"], [-0.58, 1.4, 0.0])), t["head"]
assert t["malformed"] >= 1 and t["no_body"] >= 1, t
print("eyes", t["eyes"], "packets", t["packets"], "malformed", t["malformed"], "no_body", t["no_body"])
PY

# --- LCD: bit-identical for 11 and 13 ranks at one budget -------------------
L=(--drive still.json --frames 2 --lcd-budget 12 --lcd-wait --no-compensation --scene-config two.json)
timeout 600 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" "${L[@]}" -o l11 >/dev/null 2>l11.txt; rc1=$?
timeout 600 "${MPI[@]}" -np 13 "$CAVE" run --http off "$CFG" "${COMMON[@]}" "${L[@]}" -o l13 >/dev/null 2>l13.txt; rc2=$?
r11=$(grep -o '"lcd_rounds":[0-9]*' l11/metrics.jsonl | tail -1 | grep -o '[0-9]*$')
r13=$(grep -o '"lcd_rounds":[0-9]*' l13/metrics.jsonl | tail -1 | grep -o '[0-9]*$')
if [ $rc1 -eq 0 ] && [ $rc2 -eq 0 ] && [ "$r11" = 12 ] && [ "$r13" = 12 ] && cmp -s l11/lcd.exr l13/lcd.exr; then
  ok "LCD image bit-identical for 11 and 13 ranks (12 rounds from 10 and 12 contributors)"
  # with 13 ranks the gather ranks' rounds (10 and 11) came by the allreduce
  ar=$(tail -1 l13/metrics.jsonl | grep -o '"lcd_allreduce":{[^}]*}')
  python3 -c 'import json,sys; a=json.loads(sys.argv[1]); sys.exit(not (a["members"] == 3 and a["rounds"] >= 1))' \
    "${ar#\"lcd_allreduce\":}" 2>/dev/null && ok "13 ranks: gather ranks' rounds summed by the allreduce ($ar)" \
    || bad "13 ranks: no allreduce rounds in the metrics: $ar"
else
  bad "LCD 11 vs 13: rc $rc1 $rc2, rounds $r11 $r13 $(tail -2 l11.txt l13.txt)"
fi

# --- the same with 4 gather ranks: the master is the last rank of the LCD
# communicator (a leaf of the sum's tree, comm.c), the gather ranks report
# their rounds and CPU times in the header ---------------------------------
timeout 600 "${MPI[@]}" -np 15 "$CAVE" run --http off "$CFG" "${COMMON[@]}" "${L[@]}" -o l15 >/dev/null 2>l15.txt; rc2=$?
ar=$(tail -1 l15/metrics.jsonl 2>/dev/null | grep -o '"lcd_allreduce":{[^}]*}')
if [ $rc2 -eq 0 ] && cmp -s l11/lcd.exr l15/lcd.exr &&
   python3 -c 'import json,sys; a=json.loads(sys.argv[1]); sys.exit(not (a["members"] == 5 and a["rounds"] >= 1 and a["gather_rounds"] >= a["rounds"] and a["gather_round_cpu_ms"] > 0))' \
     "${ar#\"lcd_allreduce\":}" 2>/dev/null; then
  ok "LCD image bit-identical for 11 and 15 ranks, 4 gather ranks by the allreduce ($ar)"
else
  bad "LCD 11 vs 15 ranks: rc $rc2, $ar $(tail -2 l15.txt)"
fi

# --- `cave lcd` and `cave run` give the same numbers for the same pose and
# light, both with their defaults and the same scene config (two panels):
# the 11-rank image above (still drive, default head (0, 1.2, 0) + the scene
# offset = eye (-0.37, 1.02, 0), 12 rounds of 4 spp at 40 x 30 per panel)
# against `cave lcd --drive` at that eye.  The same samples and the same
# veil: L_r, L_v and CR agree to the printed digits, per panel.
"$CAVE" lcd two.json --prt scene.prt --drive still.json --eye -0.37,1.02,0 --dt 10 --spp 4 --rounds 12 \
  --size 40x30 -o same_lcd.csv >same_lcd.txt 2>&1; rc=$?
python3 - l11/metrics.jsonl same_lcd.csv <<'PY' >same.txt && ok "cave lcd = cave run: $(cat same.txt)" || bad "cave lcd vs cave run: rc $rc $(cat same.txt) $(tail -2 same_lcd.txt)"
import csv, json, sys
s = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])["lcd_readability"]
c = list(csv.DictReader(open(sys.argv[2])))[0]
ok = s["rounds"] == 12 and s["veil_included"] is True
out = []
for name in ("centre", "cluster"):
    r = s["panels"][name]
    for key, col in (("reflected_luminance", "L_r"), ("veiling_luminance", "L_v"), ("contrast_ratio", "CR")):
        a, b = r[key], float(c[name + "." + col])
        ok = ok and b > 0 and abs(a - b) <= 1e-5 * abs(b)
    out.append("%s: L_r %.6g / %s, L_v %.6g / %s, CR %.6g / %s" % (
        name, r["reflected_luminance"], c[name + ".L_r"], r["veiling_luminance"], c[name + ".L_v"],
        r["contrast_ratio"], c[name + ".CR"]))
print("(run / lcd, %d rounds) " % s["rounds"] + "; ".join(out))
sys.exit(0 if ok else 1)
PY

# --- the scene's panels travel with the bake (issue 34): `cave run --scene
# two.prt` without --scene-config uses two.json's panels (the lcd block `cave
# bake` wrote next to two.prt: the same cabin and bake as scene.prt, so the
# same image as l11's); a .prt without a block says so in the ready line; the
# forest map is unscaled: every figure is marked uncalibrated, no verdict ---
"$CAVE" bake two.json -o two.prt --bands 3 --rays 32 --bounces 1 --quiet >/dev/null 2>&1 \
  || bad "bake two.json"
L2=(--drive still.json --frames 2 --lcd-budget 12 --lcd-wait --no-compensation)
timeout 600 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]/scene.prt/two.prt}" "${L2[@]}" -o lp >/dev/null 2>lp.txt; rc=$?
python3 - lp/metrics.jsonl r11/metrics.jsonl <<'PY' >lp_check.txt && cmp -s l11/lcd.exr lp/lcd.exr \
  && ok "cave run --scene two.prt uses its baked panels: $(cat lp_check.txt)" \
  || bad "cave run --scene two.prt: rc $rc $(cat lp_check.txt) $(tail -2 lp.txt)"
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1])]
ready, summ = lines[0], lines[-1]
r0 = json.loads(open(sys.argv[2]).readline())
s = summ["lcd_readability"]
ok = (ready["type"] == "ready" and "two.prt.lcd.json" in ready["lcd_panels"]
      and "has no lcd block" in r0["lcd_panels"] and set(s["panels"]) == {"centre", "cluster"}
      and s["calibrated"] is False and s["illuminance_unit"] == "relative"
      and "uncalibrated" in s["light_source"] and s["outdoor_horizontal_illuminance"] > 0
      and s["eye_horizontal_illuminance"] > 0 and s["eye_vertical_illuminance"] > 0
      and all(p["verdict"] == "uncalibrated" for p in s["panels"].values()))
print("ready: %s; scene.prt: %s; panels %s, verdicts %s, outdoor %.4g, eye %.4g / %.4g (%s)" % (
    ready["lcd_panels"], r0["lcd_panels"], sorted(s["panels"]),
    [p["verdict"] for p in s["panels"].values()], s["outdoor_horizontal_illuminance"],
    s["eye_horizontal_illuminance"], s["eye_vertical_illuminance"], s["illuminance_unit"]))
sys.exit(0 if ok else 1)
PY

# --- readability during a drive: every frame a new key (the car turns), yet
# the frames carry lcd.readability from rounds of earlier snapshots ----------
cat > turn.json <<'JSON'
{"description": "turning under forest", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 0, "weights": [1]}, {"t": 10, "yaw": 300}]}
JSON
timeout 600 "${MPI[@]}" -np 12 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --drive turn.json --frames 16 --dt 0.3 \
  --max-fps 4 --no-compensation -o turn >/dev/null 2>turn.txt; rc=$?
python3 - turn <<'PY' && ok "readability during the drive: $(cat turn/drive_check.txt)" || bad "readability during the drive: rc $rc $(cat turn/drive_check.txt 2>/dev/null) $(tail -2 turn.txt)"
import json, sys
d = sys.argv[1]
lines = [json.loads(l) for l in open(d + "/metrics.jsonl")]
frames = [l for l in lines if l.get("type") == "frame" and l["frame"] < 16]
keys = {l["lcd"]["key"] for l in frames}
with_r = [l for l in frames if l["lcd"].get("readability", {}).get("rounds", 0) > 0]
msg = "%d of %d drive frames carry readability, %d keys" % (len(with_r), len(frames), len(keys))
if with_r:
    r = with_r[-1]["lcd"]["readability"]
    msg += "; frame %d: key %s of frame %d, %d rounds, age %.2f s, CR %.2f +- %.2f" % (
        with_r[-1]["frame"], r["key"], r["frame"], r["rounds"], r["age_s"], r["contrast_ratio"], r["contrast_ratio_se"])
open(d + "/drive_check.txt", "w").write(msg)
ok = len(keys) >= 8 and len(with_r) >= 2 and all(
    l["lcd"]["readability"]["frame"] <= l["frame"] and l["lcd"]["readability"]["age_s"] >= 0 for l in with_r)
sys.exit(0 if ok else 1)
PY

# --- the whole drive in the summary (issue 34): per panel the lowest CR over
# the drive's frames equals the lowest on their metrics lines, with its frame
# and time, and the frames below 3:1; held frames (--lcd-wait) are left out --
python3 - turn/metrics.jsonl l11/metrics.jsonl <<'PY' >ldrive.txt && ok "summary lcd_drive: $(cat ldrive.txt)" || bad "summary lcd_drive: $(cat ldrive.txt)"
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1])]
frames = [l for l in lines if l.get("type") == "frame"]
d = lines[-1]["lcd_drive"]
ok = d["frames"] == len(frames) == 16 and d["calibrated"] is False
with_r = [l for l in frames if "readability" in l["lcd"]]
ok = ok and d["frames_with_figures"] == len(with_r)
ok = ok and d["frames_with_figures_at_most_2_old"] == sum(1 for l in with_r if l["frame"] - l["lcd"]["readability"]["frame"] <= 2)
out = []
for name, p in d["panels"].items():
    crs = [(l["lcd"]["readability"]["panels"][name]["contrast_ratio"], l["frame"], l["t"]) for l in with_r]
    lo = min(crs)
    below = sum(1 for c in crs if c[0] < d["cr_min"])
    ok = ok and p["contrast_ratio_min"] == lo[0] and p["contrast_ratio_min_frame"] == lo[1] \
        and abs(p["contrast_ratio_min_t"] - lo[2]) < 1e-9 and p["frames_below_cr_min"] == below \
        and 0 <= p["time_share_below_cr_min"] <= 1
    out.append("%s min CR %.6g at frame %d (t %.2f s) = the lines' min, %d frames below %g" % (
        name, p["contrast_ratio_min"], p["contrast_ratio_min_frame"], p["contrast_ratio_min_t"],
        p["frames_below_cr_min"], d["cr_min"]))
h = [json.loads(l) for l in open(sys.argv[2])][-1]
ok = ok and h["held_frames"] > 0 and h["lcd_drive"]["frames"] == 2
print("%d of %d frames with figures (%d at most 2 frames old); %s; --lcd-wait: %d held frames left out" % (
    d["frames_with_figures"], d["frames"], d["frames_with_figures_at_most_2_old"], "; ".join(out), h["held_frames"]))
sys.exit(0 if ok else 1)
PY

# --- a stopped gather rank does not stall the frames -----------------------
# (stopped 8 s: below --gather-timeout, so stalled, not dead; dead_gather.sh
# kills one)
timeout 600 "${MPI[@]}" -np 12 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --drive still.json --frames 0 \
  --timeout-ms 1500 --gather-timeout 20 -o stop >stop.txt 2>stoperr.txt &
job=$!
for i in $(seq 1 300); do [ -s stop/pids/rank11.pid ] && [ -s stop/metrics.jsonl ] && break; sleep 0.5; done
g=$(cat stop/pids/rank11.pid 2>/dev/null); m0=$(cat stop/pids/rank0.pid 2>/dev/null)
if [ -n "$g" ] && [ -n "$m0" ]; then
  kill -STOP "$g"
  n0=$(grep -c '"frame"' stop/metrics.jsonl)
  sleep 8
  n1=$(grep -c '"frame"' stop/metrics.jsonl)
  kill -CONT "$g"
  [ $((n1 - n0)) -ge 2 ] && ok "frames go on with a stopped gather rank ($((n1 - n0)) frames in 8 s)" || bad "stalled: $n0 -> $n1"
  # A stopped wall-eye: its report is skipped after the timeout (1.5 s) and
  # the previous state reused; the frames go on at about the timeout.
  w=$(cat stop/pids/rank3.pid)
  kill -STOP "$w"
  n0=$(grep -c '"frame"' stop/metrics.jsonl)
  sleep 8
  n1=$(grep -c '"frame"' stop/metrics.jsonl)
  kill -CONT "$w"
  late=$(tail -2 stop/metrics.jsonl | grep -o '"late_walleyes":[0-9]*' | tail -1 | grep -o '[0-9]*$')
  [ $((n1 - n0)) -ge 3 ] && [ $((n1 - n0)) -le 8 ] && [ "${late:-0}" -ge 1 ] \
    && ok "a stopped wall-eye is skipped after the timeout ($((n1 - n0)) frames in 8 s, $late late)" \
    || bad "stopped wall-eye: $n0 -> $n1 frames, late $late"
  kill -TERM "$m0"
  wait $job; rc=$?
  [ $rc -eq 0 ] && ok "SIGTERM to the master: clean exit" || bad "SIGTERM exit $rc: $(tail -3 stoperr.txt)"
  tail -1 stop/metrics.jsonl | grep -q '"summary"' && ok "summary written after SIGTERM" || bad "no summary"
  ls stop/*.tmp* 2>/dev/null | grep -q . && bad "temporary files left" || ok "no partial files"
else
  bad "service did not start: $(tail -3 stoperr.txt)"; kill $job 2>/dev/null; wait $job
fi

# --- SIGTERM to mpirun (forwarded to every rank; mpirun's SIGKILL follows
# after odls_base_sigkill_timeout, raised here as the docs advise) -----------
export OMPI_MCA_odls_base_sigkill_timeout=20
"${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --drive still.json --frames 0 -o term \
  >term.txt 2>termerr.txt &
mpid=$!
for i in $(seq 1 300); do [ -s term/metrics.jsonl ] && break; sleep 0.5; done
sleep 2
kill -TERM "$mpid"
wait "$mpid"; rc=$?
alive() { for f in term/pids/*.pid; do
  st=$(awk '/^State:/ {print $2}' "/proc/$(cat "$f")/status" 2>/dev/null); [ -n "$st" ] && [ "$st" != Z ] && echo x; done | wc -l; }
for i in $(seq 1 20); do left=$(alive); [ "$left" -eq 0 ] && break; sleep 0.5; done
# the LCD image is written when any round was summed (the idle LCD threads
# may get no core at all while ten renderers run flat out)
rounds=$(tail -1 term/metrics.jsonl | grep -o '"lcd_rounds":[0-9]*' | grep -o '[0-9]*$')
lcd_ok=1; [ "${rounds:-0}" -gt 0 ] && [ ! -s term/lcd.exr ] && lcd_ok=0
tail -1 term/metrics.jsonl | grep -q '"interrupted":true' && [ "$left" -eq 0 ] && [ $lcd_ok -eq 1 ] \
  && ok "SIGTERM to mpirun: every rank ended, summary written, LCD image for its ${rounds:-0} rounds (mpirun status $rc)" \
  || bad "SIGTERM to mpirun: rc $rc, $left ranks left, $(tail -c 200 term/metrics.jsonl)"

# --- a rank that dies: Open MPI 4 ends the job at once and names the rank ---
unset OMPI_MCA_odls_base_sigkill_timeout  # back to 1 s (the others get SIGTERM, then SIGKILL)
"${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --drive still.json --frames 0 -o death \
  >death.txt 2>deatherr.txt &
mpid=$!
for i in $(seq 1 300); do [ -s death/metrics.jsonl ] && break; sleep 0.5; done
t0=$(date +%s)
kill -9 "$(cat death/pids/rank5.pid)"
wait "$mpid"; rc=$?
dt=$(( $(date +%s) - t0 ))
[ $rc -ne 0 ] && [ $dt -le 30 ] && grep -q "rank 5" deatherr.txt \
  && ok "a killed rank ends the job in ${dt} s, naming it: $(grep -o 'process rank 5[^(]*' deatherr.txt | head -1)" \
  || bad "killed rank: rc $rc after ${dt} s: $(grep -i rank deatherr.txt | tail -2)"

# --- --size keeps each wall's aspect (as in cave render) ----------------------
sed 's/"res": \[720, 720\]/"res": [1440, 720]/g' "$SRC/configs/caves/two-sided-wall.json" > wide.json
timeout 300 "${MPI[@]}" -np 5 "$CAVE" run --http off wide.json --scene scene.prt --size 32 --frames 1 --no-compensation \
  --lcd-size 8x6 --quiet -o wide >/dev/null 2>wideerr.txt; rc=$?
"$CAVE" tonemap wide/frame00000_front_L.exr -o wide.png >/dev/null 2>&1
python3 - wide.png <<'PY' && [ $rc -eq 0 ] && ok "--size 32 on 1440x720 walls renders 32x16" || bad "--size aspect (rc $rc): $(tail -2 wideerr.txt)"
import struct, sys
b = open(sys.argv[1], "rb").read(24)
w, h = struct.unpack(">II", b[16:24])
assert (w, h) == (32, 16), (w, h)
PY

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
