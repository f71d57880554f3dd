#!/usr/bin/env bash
# Shared lighting (`cave run --share-lighting`, docs/service.md "Shared
# lighting"): 11 ranks on one host under the sky drive, the light changing
# every frame (--dt 0.2).  With sharing (the default, host) one wall-eye
# leads, computing each next lighting ahead (prefetch), and nine import;
# host-now shares without the prefetch; with it off all ten compute.  Every written image
# (EXR and PNG of every wall-eye, the montages) is byte-identical between the
# two runs; the metrics count the changes per kind (no silent fallback); the
# ready lines name each rank's part (and the transfer storage: half floats by
# default on llvmpipe, floats with --transfer float in the late-leader run);
# a bad value is refused before starting.
# The leader stopped (SIGSTOP) for 3 s: the importers stop waiting for it
# after --timeout-ms / 4 and compute, counted as late_leader.
# Usage: test_lighting_share.sh CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"; MPIEXEC="${4:-mpirun}"
source "$(dirname "${BASH_SOURCE[0]}")/mpi_common.sh"
COMMON=(--scene scene.prt --size 48 --drive "$SRC/configs/drives/sky.json" --dt 0.2 --frames 5
        --write-every 1 --no-lcd --patches 8 --timeout-ms 60000 --compensation-ms 60000 --quiet)
# (--compensation-ms: no time slot, so the solves and images do not depend on the load)

"$CAVE" run --http off --check --ranks 11 "$CFG" --scene scene.prt --share-lighting 2 >out.txt 2>err.txt; rc=$?
[ $rc -eq 2 ] && grep -q "share-lighting: expected auto, host, host-now, background or off, got '2'" err.txt \
  && ok "bad --share-lighting refused: $(head -1 err.txt)" || bad "bad value: rc $rc $(cat err.txt)"

for mode in host host-now off background auto; do
  timeout 600 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" "${COMMON[@]}" --share-lighting $mode -o $mode \
    >out_$mode.txt 2>err_$mode.txt; rc=$?
  [ $rc -eq 0 ] && ok "11 ranks, --share-lighting $mode" || bad "run $mode rc $rc: $(tail -5 err_$mode.txt)"
done

for mode in host host-now background auto; do
  n=0; differ=0
  for f in $mode/*.exr $mode/*.png; do
    [ -e "$f" ] || continue
    n=$((n + 1))
    cmp -s "$f" "off/${f#$mode/}" || { differ=$((differ + 1)); echo "  differs: ${f#$mode/}"; }
  done
  nb=$(ls off/*.exr off/*.png 2>/dev/null | wc -l)
  [ $n -ge 100 ] && [ $n -eq "$nb" ] && [ $differ -eq 0 ] \
    && ok "$n images byte-identical with --share-lighting $mode and off" || bad "$mode: $differ of $n images differ ($nb without sharing)"
done

python3 - host off host-now <<'PY' && ok "metrics: every change counted, the leader led, the others imported or said why not" || bad "metrics"
import json, sys
def load(d):
    lines = [json.loads(l) for l in open(d + "/metrics.jsonl")]
    return lines[0], [l for l in lines if l["type"] == "frame"], lines[-1]
ready, frames, summ = load(sys.argv[1])
assert ready["share_lighting"] == "host", ready
roles = ready["ranks"]
# llvmpipe relights on the CPU, from half floats by default (--transfer auto)
assert all("relight on the CPU from half-float transfer" in t for r, t in roles.items() if r != "0"), roles
leaders = [r for r, t in roles.items() if "shared lighting: leader of 10" in t]
assert len(leaders) == 1, roles
importers = [r for r, t in roles.items() if f"shared lighting: importer (leader rank {leaders[0]}," in t]
assert len(importers) == 9, roles
print("leader: rank", leaders[0], roles[leaders[0]].split(";")[0])
sl = summ["shared_lighting"]
changes = sum(sl[k] for k in ("computed", "led", "imported", "late_leader", "dead_leader", "torn"))
print("host:", sl)
assert sl["mode"] == "host" and sl["computed"] == 0 and sl["led"] >= 5, sl
assert sl["imported"] + sl["late_leader"] + sl["torn"] == 9 * sl["led"] and sl["dead_leader"] == 0, sl
assert sl["imported"] >= 1, sl
# sim clock: the leader's prediction of every next lighting comes true
assert sl["prefetched"] >= sl["led"] - 2 and sl["prefetch_missed"] == 0, sl
_, _, now = load(sys.argv[3])
sn = now["shared_lighting"]
print("host-now:", sn)
assert sn["mode"] == "host-now" and sn["prefetched"] == 0 and sn["led"] == sl["led"], sn
kinds = set()
for f in frames:
    for r, v in f["ranks"].items():
        if "light" in v:
            kinds.add(v["light"])
            assert v["light_ms"] >= 0 and v["light_cpu_ms"] >= 0 and v["light_wait_ms"] >= 0, v
assert "led" in kinds and "imported" in kinds, kinds
_, _, off = load(sys.argv[2])
so = off["shared_lighting"]
print("off:", so)
assert so["mode"] == "off" and so["computed"] == 10 * sl["led"] and so["imported"] == 0, so
PY
python3 - background auto <<'PY' && ok "background: each wall-eye relit itself, the background image shared; auto picked host on llvmpipe with 0.2 cores per wall-eye" || bad "background / auto metrics"
import json, sys
def load(d):
    lines = [json.loads(l) for l in open(d + "/metrics.jsonl")]
    return lines[0], lines[-1]
ready, summ = load(sys.argv[1])
roles = ready["ranks"]
assert ready["share_lighting"] == "background", ready
assert sum("shared lighting: leader of the background image of 10" in t for r, t in roles.items()) == 1, roles
assert sum("shared lighting: importer of the background image" in t for r, t in roles.items()) == 9, roles
sb = summ["shared_lighting"]
print("background:", sb)
assert sb["mode"] == "background" and sb["led"] >= 5 and sb["imported"] + sb["late_leader"] == 9 * sb["led"], sb
ready, summ = load(sys.argv[2])
assert ready["share_lighting"] == "auto", ready
picked = [t.split("shared lighting: ")[1] for r, t in ready["ranks"].items() if r != "0"]
print("auto:", picked[0])
assert all("[auto: host (a software GL" in p for p in picked), picked
PY
# --- a late leader: the leader (named in the ready line) stopped for 3 s ----
# (with --transfer float: the option reaches every wall-eye, said in its ready line)
timeout 600 "${MPI[@]}" -np 11 "$CAVE" run --http off "$CFG" --scene scene.prt --size 48 \
  --drive "$SRC/configs/drives/sky.json" --dt 0.2 --frames 40 --write-every 0 --no-lcd --patches 8 \
  --timeout-ms 800 --gather-timeout 60 --transfer float --quiet -o late >out_late.txt 2>err_late.txt &
job=$!
for i in $(seq 1 600); do
  [ -s late/metrics.jsonl ] && [ "$(grep -c '"type":"frame"' late/metrics.jsonl)" -ge 3 ] && break
  sleep 0.2
done
leader=$(python3 -c "
import json, sys
r = json.loads(open('late/metrics.jsonl').readline())['ranks']
print([k for k, t in r.items() if 'shared lighting: leader' in t][0])")
pid=$(cat late/pids/rank$leader.pid 2>/dev/null)
echo "stopping the leader, rank $leader (pid $pid), for 3 s"
if [ -n "$pid" ]; then kill -STOP "$pid"; sleep 3; kill -CONT "$pid"; fi
wait $job; rc=$?
[ $rc -eq 0 ] && ok "run with the leader stopped 3 s ends (rc 0)" || bad "late leader run rc $rc: $(tail -3 err_late.txt)"
python3 - late <<'PY' && ok "late leader: the importers computed themselves, counted" || bad "late leader metrics"
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1] + "/metrics.jsonl")]
sl = lines[-1]["shared_lighting"]
print("late leader:", sl)
ranks = lines[0]["ranks"]
assert all("relight on the CPU from float transfer" in t for r, t in ranks.items() if r != "0"), ranks
# (the frame lines show a rank's newest lighting step when it is of their
# frame: best effort; the summary's counts are the ranks' own)
late = [v["light"] for f in lines if f["type"] == "frame" for r, v in f["ranks"].items() if v.get("light") == "late_leader"]
print("frame lines naming late_leader:", len(late))
assert sl["late_leader"] >= 1 and sl["dead_leader"] == 0, sl
PY

echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
