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
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK"
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
# One thread per rank: 11+ ranks share 2 cores.
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
# Keep Open MPI's plugins loaded so sanitizer reports name them (lsan.supp).
export OMPI_MCA_mca_base_component_disable_dlclose=1
MPI=("$MPIEXEC" --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS
     -x OMPI_MCA_mca_base_component_disable_dlclose)
# Under the sanitizers, LeakSanitizer is off for the MPI runs (AddressSanitizer
# and UBSan stay on): Open MPI and Mesa free nothing at exit from plugins they
# have unloaded, so those stacks cannot be attributed or suppressed, and full
# unwinding (fast_unwind_on_malloc=0) deadlocks in libgcc's unwinder against
# llvmpipe's threads.  The roles' own allocations are freed on every path.
[ -n "${ASAN_OPTIONS:-}" ] && export ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0"
for v in ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS; do [ -n "${!v:-}" ] && MPI+=(-x "$v"); done
CFG="$SRC/configs/caves/cave5.json"

# A small bake: few rays (transfer accuracy does not matter here).
"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null \
  || { echo "FAIL: bake"; exit 1; }
cat > still.json <<'JSON'
{"description": "standing still under forest", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 30, "weights": [1]}, {"t": 10, "yaw": 30}]}
JSON
COMMON=(--scene scene.prt --size 48 --lcd-size 40x30 --lcd-spp 4 --patches 8 --quiet)

# --- configuration errors before launch ------------------------------------
"$CAVE" run --check --ranks 3 "$CFG" --scene scene.prt >out.txt 2>err.txt; rc=$?
[ $rc -ne 0 ] && grep -q "at least 1 + 10 = 11 ranks" err.txt && ok "too few ranks (check): $(head -1 err.txt)" || bad "too few ranks: rc $rc $(cat err.txt)"
"$CAVE" run --check --ranks 11 "$CFG" --scene scene.prt >out.txt 2>err.txt \
  && grep -q "rank 10: wall ceiling, right eye" out.txt && ok "layout: $(cat out.txt)" || bad "layout $(cat out.txt err.txt)"
sed 's/"name": "left"/"name": "front"/' "$CFG" > dup.json
"$CAVE" run --check --ranks 11 dup.json --scene missing.prt --drive nodrive.json >out.txt 2>err.txt; rc=$?
n=$(grep -c "" err.txt)
[ $rc -ne 0 ] && grep -q "front" err.txt && grep -q "missing.prt" err.txt && grep -q "nodrive.json" err.txt \
  && ok "every problem listed ($n lines)" || bad "problem list: $(cat err.txt)"
timeout 120 "${MPI[@]}" -np 3 "$CAVE" run "$CFG" "${COMMON[@]}" -o r3 >out.txt 2>err.txt; rc=$?
[ $rc -ne 0 ] && [ $rc -ne 124 ] && grep -q "11 ranks" err.txt && ok "mpirun with too few ranks ends at once (rc $rc)" || bad "mpirun too few ranks: rc $rc $(tail -3 err.txt)"

# --- 11 ranks, a few frames ------------------------------------------------
timeout 600 "${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" --drive still.json --frames 4 \
  --write-every 2 --lcd-budget 20 -o r11 >out11.txt 2>err11.txt; rc=$?
if [ $rc -eq 0 ]; then ok "11-rank run"; else bad "11-rank run rc $rc: $(tail -5 err11.txt)"; fi
nexr=$(ls r11/frame00003_*.exr 2>/dev/null | wc -l)
[ "$nexr" -eq 10 ] && ok "10 wall-eye EXRs for the last frame" || bad "wall-eye EXRs: $nexr"
[ -s r11/montage00003_L.png ] && ok "montage written" || bad "no montage"
python3 - r11 <<'PY' && ok "metrics: every frame on time, one adaptation state, finite" || bad "metrics"
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
print("lwa per frame:", [round(f["adaptation"]["lwa"], 4) for f in frames],
      "master p99 ms:", summary[0].get("master_ms_p99"))
PY
"$CAVE" tonemap r11/frame00003_front_L.exr -o front.png >tm.txt 2>&1 && grep -q "invalid 0\|0 invalid" tm.txt \
  && ok "front wall EXR finite" || bad "front EXR: $(cat tm.txt)"

# --- LCD: bit-identical for 11 and 13 ranks at one budget -------------------
L=(--drive still.json --frames 2 --lcd-budget 12 --lcd-wait --no-compensation)
timeout 600 "${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" "${L[@]}" -o l11 >/dev/null 2>l11.txt; rc1=$?
timeout 600 "${MPI[@]}" -np 13 "$CAVE" run "$CFG" "${COMMON[@]}" "${L[@]}" -o l13 >/dev/null 2>l13.txt; rc2=$?
r11=$(grep -o '"lcd_rounds":[0-9]*' l11/metrics.jsonl | tail -1 | grep -o '[0-9]*$')
r13=$(grep -o '"lcd_rounds":[0-9]*' l13/metrics.jsonl | tail -1 | grep -o '[0-9]*$')
if [ $rc1 -eq 0 ] && [ $rc2 -eq 0 ] && [ "$r11" = 12 ] && [ "$r13" = 12 ] && cmp -s l11/lcd.exr l13/lcd.exr; then
  ok "LCD image bit-identical for 11 and 13 ranks (12 rounds from 10 and 12 contributors)"
else
  bad "LCD 11 vs 13: rc $rc1 $rc2, rounds $r11 $r13 $(tail -2 l11.txt l13.txt)"
fi

# --- a stopped gather rank does not stall the frames -----------------------
timeout 600 "${MPI[@]}" -np 12 "$CAVE" run "$CFG" "${COMMON[@]}" --drive still.json --frames 0 \
  --timeout-ms 1500 -o stop >stop.txt 2>stoperr.txt &
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
"${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" --drive still.json --frames 0 -o term \
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
"${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" --drive still.json --frames 0 -o death \
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

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
