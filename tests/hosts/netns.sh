# Simulated hosts on one machine (issue 35): network namespaces with their own
# hostname (UTS namespace), /tmp, /etc/hosts and Xvfb, connected by veth pairs
# to a bridge in a "switch" namespace of their own.  Sourced by
# tests/hosts/hosts.sh (the command) and the tests; docs/deploy.md,
# "Rehearsing on one machine".
#
# State folder DIR (absolute):
#   DIR/tag              the namespaces' prefix (cvh<pid>): <tag>-sw, <tag>-<host>
#   DIR/hosts            "name address" per host, in order (host 1 first)
#   DIR/etc-hosts        bind-mounted on /etc/hosts in every host
#   DIR/<host>/tmp       bind-mounted on /tmp in that host (X sockets, Open MPI
#                        session folders)
#   DIR/<host>/xvfb.pid  its Xvfb (display :0) when started
#   DIR/<host>/binds     optional "SRC DST" lines: SRC bind-mounted on DST for
#                        what starts on that host from then on (another build
#                        or scene at the same path, a folder hidden: hosts_bind)
# Addresses: 10.251.0.<i>/24 (host i), on the bridge of the switch namespace.
# No default route anywhere: nothing leaves the test's namespaces.

hosts_die() { echo "hosts: $*" >&2; return 1; }

# hosts_can: 0 when namespaces can be made here, else prints why (one line).
hosts_can() {
  [ "$(id -u)" -eq 0 ] || { echo "not root (network namespaces need root)"; return 1; }
  command -v ip >/dev/null || { echo "no 'ip' command (Debian package iproute2)"; return 1; }
  command -v unshare >/dev/null || { echo "no 'unshare' command (util-linux)"; return 1; }
  local t="cvhprobe$$"
  ip netns add "$t" 2>/dev/null || { echo "ip netns add fails here"; return 1; }
  ip netns del "$t"
  return 0
}

# hosts_up DIR NAME...: one simulated host per NAME (2-8), all up.
hosts_up() {
  local dir="$1"; shift
  [ $# -ge 1 ] && [ $# -le 8 ] || { hosts_die "2-8 host names expected"; return 1; }
  mkdir -p "$dir" || return 1
  local tag="cvh$$" sw i=0 h ns
  [ -e "$dir/tag" ] && { hosts_die "$dir already holds hosts ($(cat "$dir/tag")): hosts_down first"; return 1; }
  echo "$tag" > "$dir/tag"
  sw="$tag-sw"
  : > "$dir/hosts"
  printf '127.0.0.1 localhost\n' > "$dir/etc-hosts"
  ip netns add "$sw" || return 1
  ip -n "$sw" link set lo up
  ip -n "$sw" link add br0 type bridge || return 1
  ip -n "$sw" link set br0 up
  for h in "$@"; do
    i=$((i + 1)); ns="$tag-$h"
    mkdir -p "$dir/$h/tmp" && chmod 1777 "$dir/$h/tmp"
    ip netns add "$ns" || return 1
    ip -n "$sw" link add "p$i" type veth peer name eth0 netns "$ns" || return 1
    ip -n "$sw" link set "p$i" master br0 up
    ip -n "$ns" link set lo up
    ip -n "$ns" addr add "10.251.0.$i/24" dev eth0
    ip -n "$ns" link set eth0 up
    # a connection with data in flight to a host that vanished fails after ~13 s
    # (6 retransmissions) instead of ~15 min (the default 15): mpirun's orders to
    # an unreachable daemon (docs/deploy.md, "A host's link down")
    ip netns exec "$ns" sysctl -qw net.ipv4.tcp_retries2=5
    echo "$h 10.251.0.$i" >> "$dir/hosts"
    echo "10.251.0.$i $h" >> "$dir/etc-hosts"
  done
  return 0
}

hosts_ns() { echo "$(cat "$1/tag")-$2"; }
hosts_names() { cut -d' ' -f1 "$1/hosts"; }
hosts_addr() { awk -v h="$2" '$1 == h {print $2}' "$1/hosts"; }
# hosts_port DIR HOST: the switch-side end of HOST's link (p<i>)
hosts_port() { awk -v h="$2" '$1 == h {print "p" NR}' "$1/hosts"; }

# hosts_exec DIR HOST CMD...: runs CMD on HOST (its netns, hostname, /tmp,
# /etc/hosts), in the foreground.
hosts_exec() {
  local dir="$1" h="$2"; shift 2
  [ -d "$dir/$h/tmp" ] || { hosts_die "no host $h in $dir"; return 1; }
  ip netns exec "$(hosts_ns "$dir" "$h")" unshare -u -- sh -c \
    'hostname "$1" && mount --bind "$2/etc-hosts" /etc/hosts || exit 1
     if [ -s "$2/$1/binds" ]; then while read -r s d; do mount --bind "$s" "$d" || exit 1; done < "$2/$1/binds"; fi
     mount --bind "$2/$1/tmp" /tmp || exit 1; shift 2; exec "$@"' \
    sh "$h" "$dir" "$@"
}

# hosts_pids DIR: every process inside the hosts' namespaces
hosts_pids() {
  local tag h
  tag=$(cat "$1/tag" 2>/dev/null) || return 0
  for ns in $(ip netns list | awk '{print $1}' | grep "^$tag-"); do ip netns pids "$ns" 2>/dev/null; done
}

# hosts_down DIR: ends every process in the hosts (TERM, 2 s, KILL), removes
# the namespaces (their veths and the bridge go with them) and DIR/tag.  Safe
# to call twice and on a half-made set.
hosts_down() {
  local dir="$1" tag p n
  tag=$(cat "$dir/tag" 2>/dev/null) || return 0
  p=$(hosts_pids "$dir")
  if [ -n "$p" ]; then
    kill -TERM $p 2>/dev/null
    for n in $(seq 20); do [ -z "$(hosts_pids "$dir")" ] && break; sleep 0.1; done
    p=$(hosts_pids "$dir"); [ -n "$p" ] && kill -KILL $p 2>/dev/null && sleep 0.2
  fi
  for ns in $(ip netns list | awk '{print $1}' | grep "^$tag-"); do ip netns del "$ns"; done
  rm -f "$dir/tag"
  [ -z "$(ip netns list | awk '{print $1}' | grep "^$tag-")" ]
}

# hosts_xvfb DIR HOST GEOMETRY...: starts Xvfb :0 on HOST with one screen per
# GEOMETRY (WxH: screen 0, 1, ...), no TCP; waits for its socket (10 s).
hosts_xvfb() {
  local dir="$1" h="$2" s=() i=0 g n; shift 2
  for g in "$@"; do s+=(-screen "$i" "${g}x24"); i=$((i + 1)); done
  command -v Xvfb >/dev/null || { hosts_die "no Xvfb (Debian package xvfb)"; return 1; }
  rm -f "$dir/$h/xvfb.pid"
  hosts_exec "$dir" "$h" sh -c 'echo $$ > "$0"; exec "$@"' "$dir/$h/xvfb.pid" \
    Xvfb :0 "${s[@]}" -nolisten tcp -noreset >"$dir/$h/xvfb.log" 2>&1 &
  for n in $(seq 100); do [ -S "$dir/$h/tmp/.X11-unix/X0" ] && [ -s "$dir/$h/xvfb.pid" ] && return 0; sleep 0.1; done
  hosts_die "$h: Xvfb :0 did not start: $(tail -2 "$dir/$h/xvfb.log")"
}

# hosts_link DIR HOST up|down: HOST's network link (its port on the switch)
hosts_link() {
  ip -n "$(cat "$1/tag")-sw" link set "$(hosts_port "$1" "$2")" "$3"
}

# hosts_guard DIR PID [S]: a watcher outside the hosts that calls hosts_down
# DIR once process PID is gone (even SIGKILLed, e.g. by ctest's timeout) or
# after S seconds (default 3600); ends after that.
hosts_guard() {
  local dir="$1" pid="$2" lim="${3:-3600}" lib
  lib="$(readlink -f "${BASH_SOURCE[0]}")"
  setsid bash -c 'source "$1"; t=0; while kill -0 "$3" 2>/dev/null && [ $t -lt "$4" ]; do sleep 1; t=$((t + 1)); done
    [ -e "$2/tag" ] && hosts_down "$2"' guard "$lib" "$dir" "$pid" "$lim" </dev/null >/dev/null 2>&1 &
  echo $! > "$dir/guard.pid"
}

# hosts_bind DIR HOST SRC DST: from now on HOST sees SRC at DST (a file or a
# folder; SRC an empty folder hides DST's folder); hosts_bind DIR HOST alone
# clears HOST's binds.
hosts_bind() {
  if [ $# -eq 2 ]; then rm -f "$1/$2/binds"; return 0; fi
  [ -e "$3" ] && [ -e "$4" ] || { hosts_die "bind: $3 and $4 must exist"; return 1; }
  echo "$(readlink -f "$3") $(readlink -f "$4")" >> "$1/$2/binds"
}
