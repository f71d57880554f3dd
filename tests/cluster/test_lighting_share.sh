#!/usr/bin/env bash
# Shared lighting (`cave run --share-lighting`, docs/service.md "Shared
# lighting"): 11 ranks on one host under the sky drive, the light changing
# every frame (--dt 0.2).  With sharing (the default, host) one wall-eye
# leads and nine import; with it off all ten compute.  Every written image
# (EXR and PNG of every wall-eye, the montages) is byte-identical between the
# two runs; the metrics count the changes per kind (no silent fallback); the
# ready lines name each rank's part; a bad value is refused before starting.
# Usage: test_lighting_share.sh CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
CAVE="$1"; WORK="$2"; SRC="$3"; MPIEXEC="${4:-mpirun}"
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK"
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_mca_base_component_disable_dlclose=1
MPI=("$MPIEXEC" --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS
     -x OMPI_MCA_mca_base_component_disable_dlclose)
[ -n "${ASAN_OPTIONS:-}" ] && export ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0"
for v in ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS; do [ -n "${!v:-}" ] && MPI+=(-x "$v"); done
CFG="$SRC/configs/caves/cave5.json"

"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null \
  || { echo "FAIL: bake"; exit 1; }
COMMON=(--scene scene.prt --size 48 --drive "$SRC/configs/drives/sky.json" --dt 0.2 --frames 5
        --write-every 1 --no-lcd --patches 8 --timeout-ms 60000 --quiet)

"$CAVE" run --check --ranks 11 "$CFG" --scene scene.prt --share-lighting 2 >out.txt 2>err.txt; rc=$?
[ $rc -eq 2 ] && grep -q "share-lighting: expected host or off, got '2'" err.txt \
  && ok "bad --share-lighting refused: $(head -1 err.txt)" || bad "bad value: rc $rc $(cat err.txt)"

for mode in host off; do
  timeout 600 "${MPI[@]}" -np 11 "$CAVE" run "$CFG" "${COMMON[@]}" --share-lighting $mode -o $mode \
    >out_$mode.txt 2>err_$mode.txt; rc=$?
  [ $rc -eq 0 ] && ok "11 ranks, --share-lighting $mode" || bad "run $mode rc $rc: $(tail -5 err_$mode.txt)"
done

n=0; differ=0
for f in host/*.exr host/*.png; do
  [ -e "$f" ] || continue
  n=$((n + 1))
  cmp -s "$f" "off/${f#host/}" || { differ=$((differ + 1)); echo "  differs: ${f#host/}"; }
done
nb=$(ls off/*.exr off/*.png 2>/dev/null | wc -l)
[ $n -ge 100 ] && [ $n -eq "$nb" ] && [ $differ -eq 0 ] \
  && ok "$n images byte-identical with sharing on and off" || bad "$differ of $n images differ ($nb without sharing)"

python3 - host off <<'PY' && ok "metrics: every change counted, the leader led, the others imported or said why not" || bad "metrics"
import json, sys
def load(d):
    lines = [json.loads(l) for l in open(d + "/metrics.jsonl")]
    return lines[0], [l for l in lines if l["type"] == "frame"], lines[-1]
ready, frames, summ = load(sys.argv[1])
assert ready["share_lighting"] == "host", ready
roles = ready["ranks"]
leaders = [r for r, t in roles.items() if "shared lighting: leader of 10" in t]
importers = [r for r, t in roles.items() if "shared lighting: importer (leader rank 1" in t]
assert leaders == ["1"] and len(importers) == 9, roles
sl = summ["shared_lighting"]
changes = sum(sl[k] for k in ("computed", "led", "imported", "late_leader", "dead_leader", "torn"))
print("host:", sl)
assert sl["mode"] == "host" and sl["computed"] == 0 and sl["led"] >= 5, sl
assert sl["imported"] + sl["late_leader"] + sl["torn"] == 9 * sl["led"] and sl["dead_leader"] == 0, sl
assert sl["imported"] >= 1, sl
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
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
