#!/usr/bin/env bash
# Starts the CAVE render service on the hosts its config names: writes the
# Open MPI rankfile with `cave cluster rankfile` (each render rank on its
# output's host), checks the whole configuration with `cave run --check`,
# then runs mpirun with that rankfile, one log folder per rank and the
# environment the ranks need.  Works on one machine (outputs without a host
# run on localhost) as well as on several (docs/deploy.md).
set -euo pipefail

usage() {
  cat <<'EOF'
usage: cluster/launch.sh CONFIG [--check] [cave run options...]

--check: only the checks below (rankfile, cave run --check, the pre-flight on
every host), then exit: 0 ready, 1 a host's problem, 2 an option's problem.

Runs  mpirun --rankfile OUT/rankfile -np N --output-filename OUT/logs
             -x DISPLAY -x ... cave run CONFIG -o OUT [cave run options...]
after `cave cluster rankfile CONFIG` wrote OUT/rankfile (its table goes to
OUT/ranks.txt and the terminal) and `cave run --check --ranks N` accepted the
options and the pre-flight `cave cluster check` (the same cave build and scene
on every host, each output's X display and GPU, clocks, the out folder; one
line per problem naming the host and output) passed.  OUT is the cave run -o among the options, else $CAVE_OUT, else
out/launch.  Per-rank output: OUT/logs/1/rank.K/{stdout,stderr}.

Variables read (all optional):
  CAVE              the cave program (default: build/cave of this checkout if it
                    exists, else `cave` on PATH); the same path on every host
  MPIRUN            mpirun program (default mpirun)
  CAVE_OUT          output folder when no -o is given (default out/launch)
  CAVE_GATHER       gather-only ranks over the CAVE's hosts (cave cluster --gather)
  CAVE_FARM         farm hostfile for gather ranks (cave cluster --farm)
  CAVE_MASTER_HOST  host of rank 0 (cave cluster --master-host)
  CAVE_CORES        cores per host for the rankfile's slot= lists (cave cluster
                    --cores; default: this machine's `nproc`; "none": slot = the
                    rank's index on its host, one core each)
  CAVE_OVERSUBSCRIBE 1 (default): pass --oversubscribe (more ranks than cores
                    on a host); 0: do not
  CAVE_MPI_ARGS     further mpirun options, split on blanks (e.g. "--mca
                    btl_tcp_if_include eth1")
  CAVE_RSH          the remote shell mpirun starts its daemons with (--mca
                    plm_rsh_agent; default: Open MPI's, ssh); the pre-flight
                    reaches the hosts with it too (tests/hosts/rsh-netns for
                    simulated hosts)
  CAVE_MAX_OFFSET_MS clock offset allowed between a host and the master's
                    host in the pre-flight (default 100)
  CAVE_PREFLIGHT    1 (default): the pre-flight before mpirun; 0: skip it
  CAVE_EXPORT       further environment variable names to forward with -x
  DISPLAY XAUTHORITY OMP_NUM_THREADS LP_NUM_THREADS ASAN_OPTIONS UBSAN_OPTIONS
  LSAN_OPTIONS      forwarded to every rank with -x when set (an output's
                    "display" in the config overrides DISPLAY for its window);
                    OMPI_MCA_* settings reach the ranks through mpirun itself
Run as root, --allow-run-as-root is added.

examples:
  cluster/launch.sh configs/caves/cave5.json --scene s.prt --frames 60 --size 240
  CAVE_GATHER=2 cluster/launch.sh configs/caves/cave5-2hosts.json --scene s.prt \
      --present window --gpu auto -o out/cave
EOF
}

if [ $# -lt 1 ] || [ "$1" = "--help" ] || [ "$1" = "-h" ]; then
  if [ $# -lt 1 ]; then usage >&2; exit 2; fi
  usage
  exit 0
fi
CONFIG="$1"; shift
CHECK_ONLY=0
if [ "${1:-}" = "--check" ]; then CHECK_ONLY=1; shift; fi
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ -z "${CAVE:-}" ]; then
  if [ -x "$ROOT/build/cave" ]; then CAVE="$ROOT/build/cave"; else CAVE="$(command -v cave || true)"; fi
fi
[ -n "$CAVE" ] && [ -x "$CAVE" ] || { echo "launch: no cave program (set CAVE=/path/to/cave)" >&2; exit 1; }
case "$CAVE" in /*) ;; *) CAVE="$(cd "$(dirname "$CAVE")" && pwd)/$(basename "$CAVE")" ;; esac
MPIRUN="${MPIRUN:-mpirun}"
[ -r "$CONFIG" ] || { echo "launch: $CONFIG: cannot read the CAVE config" >&2; exit 1; }

# The output folder: cave run's -o when given (the last one wins, as in cave run);
# --scene, --present and --gpu for the pre-flight likewise.
OUT=""; SCENE=""; PRESENT=""; GPU=""
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do
  [ $((i + 1)) -lt ${#args[@]} ] || continue
  case "${args[$i]}" in
    -o) OUT="${args[$((i + 1))]}" ;; --scene) SCENE="${args[$((i + 1))]}" ;;
    --present) PRESENT="${args[$((i + 1))]}" ;; --gpu) GPU="${args[$((i + 1))]}" ;;
  esac
done
if [ -z "$OUT" ]; then OUT="${CAVE_OUT:-out/launch}"; args=(-o "$OUT" "${args[@]}"); fi
mkdir -p "$OUT"

# 1. The rankfile and its table.
cl=(cluster rankfile "$CONFIG" -o "$OUT/rankfile")
[ -n "${CAVE_GATHER:-}" ] && cl+=(--gather "$CAVE_GATHER")
[ -n "${CAVE_FARM:-}" ] && cl+=(--farm "$CAVE_FARM")
[ -n "${CAVE_MASTER_HOST:-}" ] && cl+=(--master-host "$CAVE_MASTER_HOST")
cores="${CAVE_CORES:-$(nproc)}"
[ "$cores" != "none" ] && cl+=(--cores "$cores")
"$CAVE" "${cl[@]}" > "$OUT/ranks.txt" || { echo "launch: cave cluster failed" >&2; exit 1; }
cat "$OUT/ranks.txt"
N=$(grep -c '^rank ' "$OUT/rankfile")

# 2. Every problem of the configuration before anything starts.
"$CAVE" run --check --ranks "$N" "$CONFIG" "${args[@]}" > "$OUT/check.txt" \
  || { echo "launch: cave run --check --ranks $N found problems (above)" >&2; exit 2; }

# 3. The pre-flight on every host (cave cluster check): nothing starts unless it passes.
if [ "${CAVE_PREFLIGHT:-1}" = "1" ] || [ $CHECK_ONLY = 1 ]; then
  pf=(cluster check "$CONFIG" -o "$OUT" --max-offset-ms "${CAVE_MAX_OFFSET_MS:-100}")
  [ -n "$SCENE" ] && pf+=(--scene "$SCENE")
  [ -n "$PRESENT" ] && pf+=(--present "$PRESENT")
  [ -n "$GPU" ] && pf+=(--gpu "$GPU")
  [ -n "${CAVE_RSH:-}" ] && pf+=(--rsh "$CAVE_RSH")
  [ -n "${CAVE_GATHER:-}" ] && pf+=(--gather "$CAVE_GATHER")
  [ -n "${CAVE_FARM:-}" ] && pf+=(--farm "$CAVE_FARM")
  [ -n "${CAVE_MASTER_HOST:-}" ] && pf+=(--master-host "$CAVE_MASTER_HOST")
  "$CAVE" "${pf[@]}" || { echo "launch: the pre-flight found problems (above): nothing started" >&2; exit 1; }
fi
[ $CHECK_ONLY = 1 ] && { echo "launch: --check: ready to start"; exit 0; }

# 4. mpirun.
mpi=("$MPIRUN" --rankfile "$OUT/rankfile" -np "$N" --output-filename "$OUT/logs")
[ "${CAVE_OVERSUBSCRIBE:-1}" = "1" ] && mpi+=(--oversubscribe)
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
for v in DISPLAY XAUTHORITY OMP_NUM_THREADS LP_NUM_THREADS ASAN_OPTIONS UBSAN_OPTIONS LSAN_OPTIONS \
         ${CAVE_EXPORT:-}; do
  [ -n "${!v:-}" ] && mpi+=(-x "$v")
done
# shellcheck disable=SC2206  # split on purpose
[ -n "${CAVE_MPI_ARGS:-}" ] && mpi+=(${CAVE_MPI_ARGS})
[ -n "${CAVE_RSH:-}" ] && mpi+=(--mca plm_rsh_agent "$CAVE_RSH")
mpi+=("$CAVE" run "$CONFIG" "${args[@]}")
echo "launch: ${mpi[*]}"
echo "launch: per-rank logs in $OUT/logs/1/rank.K/"
exec "${mpi[@]}"
