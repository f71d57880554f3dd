#!/usr/bin/env bash
# The live console (issue 33, deliverables 2 and 3; docs/service.md "Live
# console", docs/metrics.md "Prometheus"), one part per ctest test:
#  browser   11 ranks (two-sided-wall.json: master, 4 wall-eyes, 6 gather
#            ranks) under mpirun --enable-recovery; headless Chromium under
#            Xvfb (xvfb-run), driven by its DevTools protocol
#            (console_cdp.py), loads the console: 11 rank rows, live; a
#            montage on the page; a gather rank SIGKILLed turns its row red;
#            "pause drive" clicked pauses the drive's clock; screenshots
#            console.png (looked at). /metrics parsed by prometheus_client's
#            parser, frame counters rising between two scrapes, the dead rank
#            down; head and sky controls reach the frame state; quit ends the
#            job by itself with the summary's stop_reason.
#  security  the service in a network namespace of its own with a veth
#            pair (10.33.0.1: not loopback; nothing leaves this machine):
#            --check refuses that address without --http-token; with a token
#            a request without it (or with a wrong one) gets 401, with it 200.
#  abuse     1000 concurrent connections, slowloris, 1 MiB headers, bad
#            methods and garbage (console_abuse.py) while the frames run:
#            no malformed request gets a 200; the server ends every slow,
#            oversized and malformed connection, and at least its connection
#            limit's worth of the flood (idle ones after 3 s; the rest wait in
#            the kernel's accept queue), all within the script's bound (its 12 s
#            plus 20 s); the server answers again afterwards, and the
#            master's p99 (master_ms) during the abuse is within 0.5 ms of
#            its p99 before, both measured in this run.
# Usage: test_console.sh PART CAVE WORKDIR SOURCE_DIR [MPIEXEC]
set -uo pipefail
PART="$1"; CAVE=$(realpath "$2"); WORK="$3"; SRC="$(realpath "$4")"; MPIEXEC="${5:-mpirun}"
HERE="$(cd "$(dirname "$0")" && pwd)"
. "$HERE/mpi_common.sh"
CFG2="$SRC/configs/caves/two-sided-wall.json"
# Debian's python3 (python3-websocket, python3-prometheus-client), not another on PATH
PY3=/usr/bin/python3; [ -x "$PY3" ] || PY3=python3
cat > sky.json <<'JSON'
{"description": "a still car under a still sky", "sky": true,
 "keyframes": [{"t": 0, "yaw": 0, "sun_elevation": 35, "sun_azimuth": 0, "turbidity": 3}]}
JSON
SMALL=(--scene scene.prt --size 32 --lcd-size 40x30 --lcd-spp 4 --lcd-budget 32 --patches 8 --quiet
       --timeout-ms 1500 --write-every 5)

# start DIR NP ARGS...: the service in the background (mpid); PRE may hold a
# command prefix (ip netns exec NS)
PRE=()
start() {
  local dir=$1 np=$2; shift 2
  rm -rf "$dir"
  timeout 300 "${PRE[@]}" "${MPI[@]}" --enable-recovery -np "$np" "$CAVE" run "$CFG2" "${SMALL[@]}" "$@" -o "$dir" \
    >"$dir.out" 2>"$dir.err" &
  mpid=$!
}
nframes() { local n; n=$(grep -c '"type":"frame"' "$1/metrics.jsonl" 2>/dev/null); echo "${n:-0}"; }
# wait_url DIR: the console's URL from the ready line of the metrics (url)
wait_url() {
  url=""
  for i in $(seq 1 600); do
    url=$(head -1 "$1/metrics.jsonl" 2>/dev/null | python3 -c 'import json,sys
try: print(json.loads(sys.stdin.read()).get("console", ""))
except Exception: pass')
    [ -n "$url" ] && [ "$(nframes "$1")" -ge "${2:-3}" ] && return 0
    kill -0 $mpid 2>/dev/null || return 1
    sleep 0.25
  done
  return 1
}
# finish DIR S: waits at most S s for the job to end by itself (ended=1)
finish() {
  local n=0
  while kill -0 $mpid 2>/dev/null && [ $n -lt $(($2 * 10)) ]; do sleep 0.1; n=$((n + 1)); done
  ended=1
  if kill -0 $mpid 2>/dev/null; then ended=0; kill -TERM $mpid; sleep 3; kill -KILL $mpid 2>/dev/null; fi
  wait $mpid; rc=$?
}
summary() { tail -1 "$1/metrics.jsonl" | python3 -c 'import json,sys
l = json.loads(sys.stdin.read()); v = l
for k in sys.argv[1].split("."): v = v.get(k, {}) if isinstance(v, dict) else {}
print(l.get("type"), json.dumps(v))' "$2"; }
post() { curl -s -m 5 -X POST "${@:2}" "${1}control"; }
done_() { echo "$pass passed, $fail failed"; [ $fail -eq 0 ]; exit $?; }

# --- browser -----------------------------------------------------------------------
if [ "$PART" = browser ]; then
  start run 11 --frames 0 --max-fps 8 --gather-timeout 6 --drive sky.json --http 127.0.0.1:0
  wait_url run 3 || { bad "no console URL in the ready line: $(tail -3 run.err)"; done_; }
  ok "ready line: console $url"
  mkdir -p chrome shots
  # Chromium: headless, under Xvfb as the CAVE's hosts have it; root needs --no-sandbox
  xvfb-run -a -s "-screen 0 1600x1200x24" chromium --headless --no-sandbox --disable-gpu --no-first-run \
    --remote-debugging-port=0 --remote-allow-origins='*' --user-data-dir="$WORK/chrome" about:blank \
    >chrome.out 2>chrome.err &
  cpid=$!
  KILL=10
  "$PY3" "$HERE/console_cdp.py" "$WORK/chrome" "$url" 11 $KILL run/pids/rank$KILL.pid "$WORK/shots" >cdp.txt 2>&1
  crc=$?
  # Browser.close ended chromium, and xvfb-run its Xvfb; else they are ended by id
  for i in $(seq 1 150); do kill -0 $cpid 2>/dev/null || break; sleep 0.1; done
  if kill -0 $cpid 2>/dev/null; then
    echo "NOTE: chromium did not close: ended"
    kill -TERM $(pgrep -f -- "--user-data-dir=$WORK/chrome") $(pgrep -P $cpid -x Xvfb) $cpid 2>/dev/null
  fi
  wait $cpid 2>/dev/null
  while read -r l; do case "$l" in ok:*) ok "${l#ok: }" ;; FAIL:*) bad "${l#FAIL: }" ;; *) echo "$l" ;; esac; done <cdp.txt
  [ $crc -eq 0 ] || bad "the browser part failed (status $crc)"
  [ -s shots/console.png ] && ok "screenshot $WORK/shots/console.png" || bad "no screenshot"
  # Prometheus: two scrapes parsed by prometheus_client's parser
  curl -s -m 5 "${url}metrics" >m1.txt; sleep 2; curl -s -m 5 "${url}metrics" >m2.txt
  "$PY3" - m1.txt m2.txt $KILL <<'PY' >prom.txt 2>&1 && ok "$(cat prom.txt)" || bad "$(cat prom.txt)"
import sys
from prometheus_client.parser import text_string_to_metric_families
def scrape(p):
    fam = {f.name: f for f in text_string_to_metric_families(open(p).read())}
    return fam
a, b = scrape(sys.argv[1]), scrape(sys.argv[2])
kill = sys.argv[3]
def val(f, name, **labels):
    for s in f.samples:
        if s.name == name and all(s.labels.get(k) == v for k, v in labels.items()):
            return s.value
    raise KeyError(name)
fa, fb = val(a["cave_frames"], "cave_frames_total"), val(b["cave_frames"], "cave_frames_total")
ha, hb = val(a["cave_frame_seconds"], "cave_frame_seconds_count"), val(b["cave_frame_seconds"], "cave_frame_seconds_count")
up = {s.labels["rank"]: s.value for s in b["cave_rank_up"].samples}
types = {f.type for f in b.values()}
cr = [s for s in b["cave_lcd_contrast_ratio"].samples] if "cave_lcd_contrast_ratio" in b else []
msg = "metrics parsed: %d families (%s); cave_frames_total %d -> %d, histogram count %d -> %d; cave_rank_up of %d ranks, rank %s: %s; %d CR samples" % (
    len(b), ", ".join(sorted(types)), fa, fb, ha, hb, len(up), kill, up.get(kill), len(cr))
print(msg)
ok = fb > fa and hb > ha and len(up) == 11 and up.get(kill) == 0 and sum(up.values()) == 10 and {"counter", "gauge", "histogram"} <= types
sys.exit(0 if ok else 1)
PY
  # controls through the master's state: a head pose, a sky
  post "$url" -d 'action=head&x=0.2&y=1.4&z=0.1' >/dev/null
  post "$url" -d 'action=sky&elevation=20&turbidity=4' >/dev/null
  post "$url" -d 'action=resume' >/dev/null
  sleep 3
  curl -s -m 5 "${url}state.json" >state.json
  python3 - state.json run/metrics.jsonl <<'PY' >ctl.txt 2>&1 && ok "$(cat ctl.txt)" || bad "$(cat ctl.txt)"
import json, sys
st = json.load(open(sys.argv[1]))["state"]
fr = [json.loads(l) for l in open(sys.argv[2]) if '"type":"frame"' in l]
heads = [f for f in fr if f["tracker"]["head"] == [0.2, 1.4, 0.1]]
newl = [f["frame"] for f in fr if f["drive"]["new_light"]]
print("head %s (%s) in %d frame lines from frame %s; sun elevation %s, turbidity %s, console sky %s; lighting changes at frames %s; controls applied %d, last '%s'" % (
    st["head"], st["head_source"], len(heads), heads[0]["frame"] if heads else None, st["sun_elevation"], st["turbidity"],
    st["override_sky"], newl, st["controls_applied"], st["last_control"]))
ok = heads and st["head_source"] == "console" and st["sun_elevation"] == 20 and st["turbidity"] == 4 and len(newl) >= 2 \
     and newl[-1] >= heads[0]["frame"] - 2 and st["controls_applied"] >= 3 and not st["paused"]
sys.exit(0 if ok else 1)
PY
  post "$url" -d 'action=quit' >/dev/null
  finish run 60
  s=$(summary run stop_reason)
  [ "$ended" = 1 ] && [ "$s" = 'summary "console: quit requested"' ] \
    && ok "quit from the console: the job ended by itself (status $rc): $s" || bad "quit: ended $ended, status $rc, $s"
  done_
fi

# --- security --------------------------------------------------------------------------
if [ "$PART" = security ]; then
  TOK=$(python3 -c 'import secrets; print(secrets.token_urlsafe(24))')
  echo "$TOK" >token.txt
  NS=cave33_$$
  if ! ip netns add $NS 2>netns.err; then bad "cannot create a network namespace: $(cat netns.err)"; done_; fi
  trap 'ip netns del $NS 2>/dev/null' EXIT
  ip netns exec $NS ip link set lo up
  ip netns exec $NS ip link add v0 type veth peer name v1
  ip netns exec $NS ip addr add 10.33.0.1/24 dev v0
  ip netns exec $NS ip link set v0 up; ip netns exec $NS ip link set v1 up
  ip netns exec $NS "$CAVE" run --check --ranks 5 "$CFG2" --scene scene.prt --http 10.33.0.1:0 >chk.out 2>chk.err
  c=$?
  [ $c -eq 2 ] && grep -q 'not a loopback address.*--http-token' chk.err \
    && ok "--check without a token on 10.33.0.1: status 2: $(head -1 chk.err)" || bad "--check: status $c: $(cat chk.err)"
  PRE=(ip netns exec $NS)
  start run 5 --frames 0 --max-fps 10 --no-lcd --http 10.33.0.1:0 --http-token token.txt
  wait_url run 2 || { bad "no console URL in the ready line: $(tail -3 run.err)"; done_; }
  case "$url" in http://10.33.0.1:*) ok "console on a non-loopback address: $url" ;; *) bad "console at $url" ;; esac
  code() { ip netns exec $NS curl -s -o /dev/null -m 5 -w '%{http_code}' "$@"; }
  a=$(code "${url}metrics"); b=$(code "${url}metrics?token=x${TOK}"); c=$(code -H "Authorization: Bearer $TOK" "${url}metrics")
  d=$(code "${url}?token=$TOK"); e=$(code -X POST -d action=quit "${url}control")
  [ "$a" = 401 ] && [ "$b" = 401 ] && [ "$c" = 200 ] && [ "$d" = 200 ] && [ "$e" = 401 ] \
    && ok "without the token 401, a wrong one 401, a quit without it 401; with it 200 (header and ?token=)" \
    || bad "codes: none $a, wrong $b, bearer $c, query $d, quit without token $e"
  [ "$(nframes run)" -ge 2 ] && kill -0 $mpid 2>/dev/null && ok "the run went on after the refused quit" || bad "the run stopped"
  ev=$(ip netns exec $NS curl -s -N -m 3 "${url}events?token=$TOK" | head -c 15)
  [ "$ev" = 'data: {"state":' ] && ok "the event stream with the token: '$ev...'" || bad "events with the token: '$ev'"
  code -X POST -H "Authorization: Bearer $TOK" -d action=quit "${url}control" >/dev/null
  finish run 60
  s=$(summary run console.unauthorized)
  [ "$ended" = 1 ] && [ "$s" = "summary 3" ] && ok "quit with the token ended the job; summary console.unauthorized: 3" \
    || bad "ended $ended, summary: $s"
  # a port in use stops the start-up, naming it (no other port)
  PRE=()
  "$PY3" -c 'import socket, sys, time
s = socket.socket(); s.bind(("127.0.0.1", 0)); s.listen(1)
open("busy.port", "w").write(str(s.getsockname()[1])); sys.stdout.close(); time.sleep(120)' &
hold=$!
  for i in $(seq 1 50); do [ -s busy.port ] && break; sleep 0.1; done
  start busy 5 --frames 0 --no-lcd --http 127.0.0.1:$(cat busy.port)
  finish busy 60
  kill $hold 2>/dev/null; wait $hold 2>/dev/null
  grep -q "rank 0 (master): --http 127.0.0.1:$(cat busy.port): cannot listen: Address already in use" busy.err && [ "$ended" = 1 ] \
    && [ "$(nframes busy)" = 0 ] && ok "a port in use: the start-up stops: $(grep -o 'set-up failed.*in use' busy.err)" \
    || bad "port in use: ended $ended, frames $(nframes busy): $(grep -v PMIX busy.err | head -3)"
  done_
fi

# --- abuse ------------------------------------------------------------------------------
if [ "$PART" = abuse ]; then
  start run 5 --frames 0 --max-fps 20 --no-lcd --http 127.0.0.1:0
  wait_url run 20 || { bad "no console URL: $(tail -3 run.err)"; done_; }
  hostport=${url#http://}; hostport=${hostport%/}
  sleep 12
  f0=$(nframes run); t0=$(date +%s.%N)
  python3 "$HERE/console_abuse.py" "${hostport%:*}" "${hostport#*:}" 12 abuse.json >abuse.txt 2>&1
  f1=$(nframes run); ta=$(python3 -c "print($(date +%s.%N) - $t0)")
  sleep 1
  f2=$(nframes run)
  sleep 11
  f3=$(nframes run)
  load=$(cut -d' ' -f1-3 /proc/loadavg)
  post "$url" -d 'action=quit' >/dev/null
  finish run 60
  [ "$ended" = 1 ] && ok "the job ended by the console's quit" || bad "the job did not end: $(tail -3 run.err)"
  python3 - abuse.json <<'PY' >ab.txt 2>&1 && ok "$(cat ab.txt)" || bad "$(cat ab.txt)"
import json, sys
a = json.load(open(sys.argv[1]))
msg, ok = [], True
for k in ("flood", "slowloris", "oversize", "malformed"):
    s = a[k]
    msg.append("%s: %d connections, %d closed by the server, codes %s, closed %s s after the last byte at most" % (
        k, s["connections"], s["closed"], s["codes"], s["close_after_last_byte_max_s"]))
    if k == "flood":  # 256 at a time (the connection limit), the rest in the kernel's accept queue
        ok &= s["closed"] >= 256
    else:
        ok &= s["closed"] == s["connections"]  # every one ended by the server within the bound
    ok &= "200" not in s["codes"]
ok &= a["after"]["status"] == 200
msg.append("all in %s s; afterwards GET /metrics: %s in %s s" % (a["seconds"], a["after"]["status"], a["after"]["seconds"]))
print("; ".join(msg))
sys.exit(0 if ok else 1)
PY
  python3 - run/metrics.jsonl "$f0" "$f1" "$f2" "$f3" "$load" "$ta" <<'PY' >p99.txt 2>&1 && ok "$(cat p99.txt)" || bad "$(cat p99.txt)"
import json, sys
fr = [json.loads(l) for l in open(sys.argv[1]) if '"type":"frame"' in l]
f0, f1, f2, f3 = map(int, sys.argv[2:6])
def p99(v):
    v = sorted(v); return v[min(len(v) - 1, int(round(0.99 * (len(v) - 1))))]
quiet = fr[max(1, f0 - 200):f0] + fr[f2:f3]
abuse = fr[f0:f1]
q, b = [f["master_ms"] for f in quiet], [f["master_ms"] for f in abuse]
qc, bc = [f["master_cpu_ms"] for f in quiet], [f["master_cpu_ms"] for f in abuse]
d = p99(b) - p99(q)
print("master_ms p99 %.3f ms during the abuse (%d frames) vs %.3f ms without (%d frames, before and after): %+.3f ms; "
      "master_cpu_ms p99 %.3f vs %.3f; frames %.1f/s vs %.1f/s; load average %s" % (
      p99(b), len(b), p99(q), len(q), d, p99(bc), p99(qc), len(b) / float(sys.argv[7]), (f3 - f2) / 11.0, sys.argv[6]))
sys.exit(0 if d <= 0.5 and len(b) >= 20 else 1)
PY
  su=$(summary run console)
  echo "summary: $su"
  done_
fi
echo "unknown part '$PART' (browser, security, abuse)"; exit 2
