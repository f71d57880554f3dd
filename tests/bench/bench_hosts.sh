#!/usr/bin/env bash
# One host against two (issue 35, docs/benchmarks.md "One host against two"):
# the 2-host test variant of configs/caves/cave5-2hosts.json (software GPUs,
# one X screen a host) on simulated hosts (tests/hosts/netns.sh), windows
# (--present window: swap lock, skew measured), simulated clock, a fixed
# light, SIZE^2 wall-eyes (default 240), 11 ranks:
#   1 host:  every output on cave1;
#   2 hosts: cave1 and cave2, twice (F1 and F2 frames) so that the bytes per
#            frame between the hosts (cave2's switch port, both ways) come
#            without the start-up: (bytes(F2) - bytes(F1)) / (F2 - F1).
# Prints a markdown table: CAVE frames/s, master ms p99, swap skew p50/p99,
# bytes per frame between hosts.  Root only.  The machine's load average is
# printed with it: the hosts share its cores.
# Usage: tests/bench/bench_hosts.sh [BUILD_DIR] [SIZE] [F1] [F2]
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="$(realpath "${1:-$ROOT/build}")"; SIZE="${2:-240}"; F1="${3:-20}"; F2="${4:-60}"
source "$ROOT/tests/hosts/netns.sh"
why=$(hosts_can) || { echo "bench_hosts: $why"; exit 1; }
WORK="$BUILD/bench-hosts"; rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK" || exit 1
H="$WORK/hosts"
trap 'hosts_down "$H"' EXIT
trap 'exit 130' INT TERM
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export CAVE="$BUILD/cave" CAVE_PREFLIGHT=0
"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null || exit 1
for v in two one; do
  python3 - "$ROOT/configs/caves/cave5-2hosts.json" "$SIZE" "$v" > $v.json <<'PY'
import json, sys
c = json.load(open(sys.argv[1])); S = int(sys.argv[2]); one = sys.argv[3] == "one"
n = {}
for o in c["outputs"]:
    if one: o["host"] = "cave1"
    i = n.get(o["host"], 0); n[o["host"]] = i + 1
    o["display"] = ":0.0"; o["geometry"] = [i * S, 0, S, S]; o["gpu"] = "software"
print(json.dumps(c))
PY
done
hosts_up "$H" cave1 cave2 || exit 1
for h in cave1 cave2; do hosts_xvfb "$H" $h "$((10 * SIZE))x$SIZE" || exit 1; done
eval "$(bash "$ROOT/tests/hosts/hosts.sh" env "$H")"
SW="$(cat "$H/tag")-sw"
port_bytes() { ip -s -j -n "$SW" link show p2 | python3 -c 'import json,sys; s=json.load(sys.stdin)[0]["stats64"]; print(s["rx"]["bytes"] + s["tx"]["bytes"])'; }
# run NAME CONFIG FRAMES: one launch; the port's bytes in NAME.bytes
run() {
  local b0; b0=$(port_bytes)
  timeout 600 bash "$ROOT/tests/hosts/hosts.sh" launch "$H" "$2" --scene "$WORK/scene.prt" --size "$SIZE" --no-lcd \
    --present window --clock sim --frames "$3" --drive "$ROOT/configs/drives/default.json" --quiet \
    -o "$WORK/$1" >"$1.out" 2>"$1.err" || { echo "bench_hosts: $1 failed: $(grep -v '^ ' "$1.err" | tail -3)"; exit 1; }
  echo $(( $(port_bytes) - b0 )) > "$1.bytes"
}
run one one.json "$F2"; run two1 two.json "$F1"; run two two.json "$F2"
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg) ($(nproc) cores), $(date -u +%F)"
python3 - "$F1" "$F2" "$SIZE" <<'PY'
import json, sys
f1, f2, size = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
def summ(d): return [json.loads(l) for l in open(d + "/metrics.jsonl")][-1]
b1, b2 = int(open("two1.bytes").read()), int(open("two.bytes").read())
print("| %d^2, %d frames, windows, simulated clock | CAVE frames/s | master ms p99 | swap skew us p50 / p99 | bytes/frame between hosts |" % (size, f2))
print("|---|---|---|---|---|")
for name, d, per in (("1 host (cave1, 11 ranks)", "one", "0 (one host)"),
                     ("2 hosts (cave1 7 ranks, cave2 4)", "two", "%.0f" % ((b2 - b1) / (f2 - f1)))):
    s = summ(d)
    print("| %s | %.1f | %.1f | %.0f / %.0f | %s |" % (name, s["fps"], s["master_ms_p99"], s.get("swap_skew_us_p50", -1),
          s.get("swap_skew_us_p99", -1), per))
PY
