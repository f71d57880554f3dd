#!/usr/bin/env bash
# The CAVE on two simulated hosts (issue 35, deliverables 1-3; ctest
# hosts_two): network namespaces cave1 and cave2 (tests/hosts/netns.sh), each
# with its own hostname, address, /tmp and Xvfb; cluster/launch.sh on cave1
# starts the 11 ranks of a test variant of configs/caves/cave5-2hosts.json
# (software GPUs, 48^2 windows) with Open MPI over TCP between the hosts,
# --present window,files, the sky drive (the light changes every frame),
# simulated clock.  Checks:
#  - every wall-eye on its output's host (each rank's ready line);
#  - one lighting leader per host, its importers on the same host;
#  - every frame (PNG and EXR of every wall-eye, the montages) the same
#    bytes as the one-host run (the variant with every output on cave1);
#  - the swap skew across hosts measured (summary p50/p99 finite);
#  - the pre-flight (cave cluster check, cluster/launch.sh --check): passes
#    on the two hosts; a wrong cave build, a missing scene, a dead X display
#    and a missing GPU on cave2 each give one line naming cave2, and nothing
#    starts;
#  - no namespace, Xvfb, orted, rank or mpirun left afterwards.
# Skips (exit 77, one line) without root or ip.
# Usage: test_two.sh CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
WORK="$2"; MPIEXEC="${4:-mpirun}"
source "$(dirname "${BASH_SOURCE[0]}")/hosts_common.sh"
S=48
variant two.json $S; variant one.json $S one
hosts_start "$((10 * S))x$S" cave1 cave2
COMMON=(--scene "$WORK/scene.prt" --size $S --no-lcd --present window,files --clock sim --frames 4
        --write-every 1 --drive "$SRC/configs/drives/sky.json" --dt 0.2 --patches 8 --timeout-ms 60000
        --no-compensation)
# (--timeout-ms: nothing late; no scattering compensation: its solve is
# time-sliced, so its images depend on the load)

# --- the 2-host run --------------------------------------------------------------
t0=$(date +%s.%N)
timeout 150 "$HOSTS_SH" launch "$H" two.json "${COMMON[@]}" -o "$WORK/two" >two.out 2>two.err; rc=$?
echo "2-host run: $(python3 -c "print('%.1f' % ($(date +%s.%N) - $t0))") s"
[ $rc -eq 0 ] && grep -q '"type":"summary"' two/metrics.jsonl && ok "2 hosts, 11 ranks: exit 0, the summary written" \
  || bad "2-host run: rc $rc: $(grep -v '^ ' two.err | tail -5)"
python3 - two/metrics.jsonl two.json > two_check.txt <<'PY' && ok "$(cat two_check.txt)" || bad "$(cat two_check.txt)"
import json, re, sys, math
lines = [json.loads(l) for l in open(sys.argv[1])]
cfg = json.load(open(sys.argv[2]))
ready, s = lines[0], lines[-1]
msg, good = [], True
ranks = ready["ranks"]
on = {}
for k, v in ranks.items():
    m = re.match(r"rank (\d+) on (\S+):", v)
    on[int(k)] = m.group(2) if m else None
want = {i + 1: o["host"] for i, o in enumerate(cfg["outputs"])}
wrong = [k for k in want if on.get(k) != want[k]]
good &= not wrong and ready["master_host"] == "cave1"
msg.append("wall-eyes on their hosts: %d of %d%s, master on %s" % (len(want) - len(wrong), len(want),
           " (wrong: %s)" % wrong if wrong else "", ready["master_host"]))
leaders = {}
for k, v in ranks.items():
    m = re.search(r"shared lighting: leader of (\d+) wall-eyes", v)
    if m: leaders.setdefault(on[int(k)], []).append((int(k), int(m.group(1))))
    m = re.search(r"importer \(leader rank (\d+)", v)
    if m and on[int(m.group(1))] != on[int(k)]:
        good = False; msg.append("rank %s imports from rank %s on another host" % (k, m.group(1)))
per_host = {h: sum(1 for x in want.values() if x == h) for h in set(want.values())}
good &= all(len(leaders.get(h, [])) == 1 and leaders[h][0][1] == n for h, n in per_host.items())
msg.append("lighting leaders: %s" % ", ".join("%s rank %d of %d" % (h, l[0][0], l[0][1]) for h, l in sorted(leaders.items())))
sl = s.get("shared_lighting", {})
msg.append("shared lighting led %s, imported %s" % (sl.get("led"), sl.get("imported")))
good &= sl.get("imported", 0) > 0
for k in ("swap_skew_us_p50", "swap_skew_us_p99"):
    good &= k in s and math.isfinite(s[k])
msg.append("swap skew across hosts p50/p99 %.0f / %.0f us (offset uncertainty %.0f us)" % (
    s.get("swap_skew_us_p50", -1), s.get("swap_skew_us_p99", -1), s.get("offset_uncertainty_us", -1)))
print("; ".join(msg))
sys.exit(0 if good else 1)
PY

# --- the one-host run: the same frames ------------------------------------------
timeout 150 "$HOSTS_SH" launch "$H" one.json "${COMMON[@]}" -o "$WORK/one" >one.out 2>one.err; rc=$?
[ $rc -eq 0 ] && grep -q "rank 10 on cave1" one/metrics.jsonl && ok "one host (cave1), 11 ranks: exit 0" \
  || bad "one-host run: rc $rc: $(grep -v '^ ' one.err | tail -5)"
n=0; differ=0
for f in one/*.png one/*.exr; do
  [ -e "$f" ] || continue
  n=$((n + 1)); cmp -s "$f" "two/${f#one/}" || { differ=$((differ + 1)); echo "  differs: ${f#one/}"; }
done
n2=$(ls two/*.png two/*.exr 2>/dev/null | wc -l)
[ $n -ge 80 ] && [ $n -eq "$n2" ] && [ $differ -eq 0 ] \
  && ok "$n images (every wall-eye's PNG and EXR, the montages) the same bytes on 2 hosts and on 1" \
  || bad "2 hosts vs 1: $differ of $n images differ ($n2 on 2 hosts)"

grep -q "cave cluster check: 2 hosts ready" two.out && ok "the pre-flight passed before the 2-host run: $(grep -c '^cave cluster check: cave[12]: build' two.out) host lines" \
  || bad "no pre-flight before the 2-host run: $(grep 'cluster check' two.out two.err | head -3)"

# --- the pre-flight: one problem on cave2 at a time, one line naming it ----------
mkdir -p sc empty && cp scene.prt sc/scene.prt
cp "$CAVE" cave.other && printf 'x' >> cave.other   # another build: other bytes, still runs
python3 - two.json > nogpu.json <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
for o in c["outputs"]:
    if o["host"] == "cave2": o["gpu"] = 0
print(json.dumps(c))
PY
PF=(--scene "$WORK/sc/scene.prt" --size $S --no-lcd --present window,files --frames 2)
# preflight NAME CONFIG WHAT [--check]: the launch refuses, one line names cave2 and what
preflight() {
  local name=$1 cfg=$2 what=$3; shift 3
  rm -rf "pf_$name"
  timeout 120 "$HOSTS_SH" launch "$H" "$cfg" "$@" "${PF[@]}" -o "$WORK/pf_$name" >"pf_$name.out" 2>"pf_$name.err"; local rc=$?
  local lines; lines=$(grep -c "^cave cluster check: cave" "pf_$name.err")
  [ $rc -eq 1 ] && [ "$lines" = 1 ] && grep -q "^cave cluster check: cave2.*$what" "pf_$name.err" \
    && grep -q "nothing started" "pf_$name.err" && [ ! -e "pf_$name/logs" ] && [ ! -e "pf_$name/metrics.jsonl" ] \
    && ok "pre-flight, $name on cave2: rc 1, nothing started: '$(grep '^cave cluster check: cave' "pf_$name.err" | cut -c1-230)'" \
    || bad "pre-flight $name: rc $rc, $lines problem lines: $(grep -v '^ ' "pf_$name.err" | head -4)"
}
hosts_bind "$H" cave2 cave.other "$CAVE"
preflight build two.json "another cave build"
hosts_bind "$H" cave2
hosts_bind "$H" cave2 empty sc
preflight scene two.json "scene .*sc/scene.prt: cannot read: No such file" --check
hosts_bind "$H" cave2
kill "$(cat "$H/cave2/xvfb.pid")"
for _ in $(seq 50); do [ -S "$H/cave2/tmp/.X11-unix/X0" ] || break; sleep 0.1; done
preflight display two.json "X display ':0.0' (rank 7 floor L, rank 8 floor R, rank 9 ceiling L, rank 10 ceiling R): cannot open X display" --check
hosts_xvfb "$H" cave2 "$((10 * S))x$S" || bad "Xvfb on cave2 again"
preflight gpu nogpu.json "GPU 0 (rank 7 floor L, rank 8 floor R, rank 9 ceiling L, rank 10 ceiling R): .*no hardware EGL device 0" --check
timeout 60 "$HOSTS_SH" launch "$H" two.json --check "${PF[@]}" -o "$WORK/pf_ok" >pf_ok.out 2>pf_ok.err \
  && grep -q "launch: --check: ready to start" pf_ok.out && ok "pre-flight passes again with the problems gone" \
  || bad "pre-flight after the problems: $(grep -v '^ ' pf_ok.err | head -3)"

hosts_stop
hosts_clean
echo "$pass passed, $fail failed"
[ $fail -eq 0 ]
