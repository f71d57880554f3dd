# Shared set-up of the simulated-host tests (test_two.sh, test_faults.sh),
# sourced after CAVE, WORK, SRC and MPIEXEC are set: skips (exit 77, one line)
# where network namespaces cannot be made; a fresh work folder, ok/bad
# counters, Open MPI as root with one thread per rank, a small bake, the
# teardown of every namespace, veth, Xvfb and mpirun on exit, fault, signal
# or timeout (a guard process outside the hosts does it even when this script
# is SIGKILLed), and hosts_clean to check it.
source "$(dirname "${BASH_SOURCE[0]}")/netns.sh"
HOSTS_SH="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/hosts.sh"
if ! why=$(hosts_can); then echo "SKIP: simulated hosts need network namespaces: $why"; exit 77; fi
command -v Xvfb >/dev/null || { echo "SKIP: simulated hosts need Xvfb (Debian package xvfb)"; exit 77; }
CAVE=$(realpath "$1"); SRC=$(realpath "$3")
rm -rf "$WORK"; mkdir -p "$WORK"; WORK=$(realpath "$WORK"); cd "$WORK" || exit 1
case "$WORK" in /tmp/*) echo "FAIL: the work folder $WORK must be outside /tmp (each host has its own)"; exit 1 ;; esac
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_mca_base_component_disable_dlclose=1
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
export CAVE MPIRUN="$MPIEXEC" CAVE_EXPORT="OMPI_MCA_mca_base_component_disable_dlclose"
H="$WORK/hosts"
SEEN_PIDS=""
# hosts_stop: every process of the hosts ended, the namespaces removed
hosts_stop() {
  SEEN_PIDS="$SEEN_PIDS $(hosts_pids "$H" | tr '\n' ' ')"
  hosts_down "$H"
}
trap 'hosts_stop' EXIT
trap 'exit 130' INT TERM
# hosts_start S HOST...: the hosts up, Xvfb :0 (one screen of S) on each,
# a guard for the case this script dies without its trap
hosts_start() {
  local s="$1"; shift
  hosts_up "$H" "$@" || { bad "hosts_up $*"; exit 1; }
  TAG=$(cat "$H/tag")
  hosts_guard "$H" $$ 1800
  for h in "$@"; do hosts_xvfb "$H" "$h" "$s" || { bad "Xvfb on $h"; exit 1; }; done
  eval "$("$HOSTS_SH" env "$H")"
  echo "hosts: $(tr '\n' ' ' < "$H/hosts")(namespaces $TAG-*)"
}
# on HOST CMD...: CMD on HOST (foreground)
on() { hosts_exec "$H" "$@"; }
# hosts_clean: after hosts_stop, no namespace of the test and none of the
# processes seen in the hosts (Xvfb, orted, ranks) nor mpirun is left
hosts_clean() {
  local left=() p
  # (a zombie, ended but not yet reaped by its parent here, does not run)
  for p in $SEEN_PIDS $*; do
    kill -0 "$p" 2>/dev/null && [ "$(awk '{print $3}' "/proc/$p/stat" 2>/dev/null)" != Z ] \
      && left+=("$p($(cat /proc/$p/comm 2>/dev/null))")
  done
  local ns; ns=$(ip netns list | awk '{print $1}' | grep "^$TAG-" | tr '\n' ' ')
  [ -z "$ns" ] && [ ${#left[@]} -eq 0 ] \
    && ok "teardown: no namespace $TAG-* left, none of the $(echo $SEEN_PIDS $* | wc -w) processes seen in the hosts running" \
    || bad "teardown: namespaces left: '$ns', processes left: ${left[*]}"
}
"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null \
  || { echo "FAIL: bake"; exit 1; }
# variant OUT S [one]: cave5-2hosts.json with software GPUs, every output on
# its host's X screen :0.0 as S x S windows side by side (one software GPU a
# host: one X screen); "one": every output on host cave1 (the one-host run)
variant() {
  python3 - "$SRC/configs/caves/cave5-2hosts.json" "$2" "${3:-}" > "$1" <<'PY'
import json, sys
c = json.load(open(sys.argv[1])); S = int(sys.argv[2]); one = sys.argv[3] == "one"
c["description"] = "test variant of cave5-2hosts.json: software GPUs, %dx%d windows, one X screen a host%s" % (
    S, S, ", all on cave1" if one else "")
n = {}
for o in c["outputs"]:
    if one: o["host"] = "cave1"
    i = n.get(o["host"], 0); n[o["host"]] = i + 1
    o["display"] = ":0.0"; o["geometry"] = [i * S, 0, S, S]; o["gpu"] = "software"
print(json.dumps(c, indent=1))
PY
}
