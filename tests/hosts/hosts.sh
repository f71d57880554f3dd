#!/usr/bin/env bash
# Simulated CAVE hosts on one machine (issue 35, docs/deploy.md "Rehearsing on
# one machine"): network namespaces with their own hostname, address, /tmp,
# /etc/hosts and Xvfb, joined by a bridge in a namespace of their own; mpirun
# reaches them through tests/hosts/rsh-netns in place of ssh.
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
source "$HERE/netns.sh"

usage() {
  cat <<'EOF2'
usage: tests/hosts/hosts.sh COMMAND DIR [...]

  up DIR HOST... [--screens WxH[,WxH...]]
                        brings up one simulated host per name (2-8): network
                        namespace <tag>-HOST, hostname HOST, address 10.251.0.i/24
                        on a bridge in namespace <tag>-sw, no route out, its own
                        /tmp (DIR/HOST/tmp) and /etc/hosts (DIR/etc-hosts: every
                        host's name); with --screens, Xvfb :0 on each host with
                        those screens (:0.0, :0.1, ...)
  down DIR              ends every process in the hosts (Xvfb, orted, ranks) and
                        removes the namespaces, veths and bridge
  exec DIR HOST CMD...  runs CMD on HOST (what ssh HOST CMD does on a cluster)
  link DIR HOST up|down HOST's link on the switch (a pulled cable: no error,
                        packets lost)
  bind DIR HOST [SRC DST]
                        from now on HOST sees SRC at DST (another cave build or
                        scene at the same path; an empty folder hides a folder);
                        without SRC DST: HOST's binds cleared
  env DIR               prints the exports that make cluster/launch.sh use the
                        hosts: CAVE_HOSTS_DIR, CAVE_RSH, CAVE_MPI_ARGS (TCP
                        between hosts on the bridge's subnet)
  launch DIR CONFIG [launch.sh options...]
                        runs cluster/launch.sh CONFIG ... on the first host (the
                        launching host) with those exports
  pids DIR              every process inside the hosts
DIR must be an absolute path outside /tmp (each host sees its own /tmp).
Needs root, ip (iproute2), unshare (util-linux), Xvfb (xvfb) for --screens.
example:
  tests/hosts/hosts.sh up $PWD/lab cave1 cave2 --screens 2880x720,1440x720
  eval "$(tests/hosts/hosts.sh env $PWD/lab)"
  tests/hosts/hosts.sh launch $PWD/lab configs/caves/cave5-2hosts.json --check --scene s.prt
  tests/hosts/hosts.sh down $PWD/lab
EOF2
}

hosts_env() {
  echo "export CAVE_HOSTS_DIR='$1'"
  echo "export CAVE_RSH='$HERE/rsh-netns'"
  echo "export CAVE_MPI_ARGS='--mca btl tcp,self,vader --mca oob_tcp_if_include 10.251.0.0/24 --mca btl_tcp_if_include 10.251.0.0/24 --mca plm_rsh_no_tree_spawn 1 --mca oob_tcp_keepalive_time 5 --mca oob_tcp_keepalive_intvl 1 --mca oob_tcp_keepalive_probes 5'"
}

[ $# -ge 1 ] || { usage >&2; exit 2; }
cmd="$1"; shift
case "$cmd" in -h|--help) usage; exit 0 ;; esac
[ $# -ge 1 ] || { usage >&2; exit 2; }
dir="$1"; shift
case "$dir" in /tmp/*|/tmp) echo "hosts: $dir: DIR must be outside /tmp" >&2; exit 2 ;; /*) ;;
  *) echo "hosts: $dir: DIR must be an absolute path" >&2; exit 2 ;; esac
case "$cmd" in
  up)
    names=(); screens=""
    while [ $# -gt 0 ]; do
      case "$1" in --screens) screens="${2:-}"; shift 2 || { usage >&2; exit 2; } ;; *) names+=("$1"); shift ;; esac
    done
    why=$(hosts_can) || { echo "hosts: cannot make namespaces here: $why" >&2; exit 1; }
    hosts_up "$dir" "${names[@]}" || { hosts_down "$dir"; exit 1; }
    if [ -n "$screens" ]; then
      for h in "${names[@]}"; do hosts_xvfb "$dir" "$h" ${screens//,/ } || { hosts_down "$dir"; exit 1; }; done
    fi
    cat "$dir/hosts" ;;
  down) hosts_down "$dir" ;;
  exec) [ $# -ge 2 ] || { usage >&2; exit 2; }; hosts_exec "$dir" "$@" ;;
  link) [ $# -eq 2 ] && [[ "$2" =~ ^(up|down)$ ]] || { usage >&2; exit 2; }; hosts_link "$dir" "$1" "$2" ;;
  env) hosts_env "$dir" ;;
  bind) [ $# -eq 1 ] || [ $# -eq 3 ] || { usage >&2; exit 2; }; hosts_bind "$dir" "$@" ;;
  launch)
    first=$(head -1 "$dir/hosts" | cut -d' ' -f1)
    eval "$(hosts_env "$dir")"
    hosts_exec "$dir" "$first" env CAVE_HOSTS_DIR="$CAVE_HOSTS_DIR" CAVE_RSH="$CAVE_RSH" \
      CAVE_MPI_ARGS="$CAVE_MPI_ARGS${CAVE_MPI_EXTRA:+ $CAVE_MPI_EXTRA}" bash "$ROOT/cluster/launch.sh" "$@" ;;
  pids) hosts_pids "$dir" ;;
  *) usage >&2; exit 2 ;;
esac
