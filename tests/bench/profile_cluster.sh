#!/usr/bin/env bash
# Where the time of a full CAVE frame goes (issue 16, target 3): `cave run`
# with 11 ranks (master + the 10 wall-eyes of configs/caves/cave5.json) on
# this machine, the car standing still under the forest map, every rank
# under `perf record` (Debian: linux-perf), then a table of CPU ms per CAVE
# frame per rank and its shares: llvmpipe's JIT-compiled shaders,
# llvmpipe itself (swrast_dri: vertex processing, set-up, rasterisation),
# the kernel (scheduling, the ranks' 0.5 ms polling naps), the program's
# own functions, MPI.  The window is from the first to the last shader
# sample of the render ranks (start-up and the last frame's files excluded).
# Usage: profile_cluster.sh BUILD_DIR SCENE.prt [FRAMES (30)] [SIZE (360)]
#   EXTRA: more `cave run` options, e.g. EXTRA="--drive configs/drives/sky.json
#   --dt 0.2 --share-lighting off" (the sky drive: a lighting change a frame).
#   SCENE: e.g. the bench_render cache $TMPDIR/cave_bench_render_t8.prt.
set -euo pipefail
BUILD="${1:?usage: profile_cluster.sh BUILD_DIR SCENE.prt [FRAMES] [SIZE]}"
SCENE="${2:?usage: profile_cluster.sh BUILD_DIR SCENE.prt [FRAMES] [SIZE]}"
FRAMES="${3:-30}"
SIZE="${4:-360}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
WORK="${BENCH_WORK:-/tmp/profile_cluster}"
command -v perf >/dev/null || { echo "profile_cluster.sh: perf not found (apt-get install linux-perf)" >&2; exit 1; }
mkdir -p "$WORK"
rm -f "$WORK"/perf.rank*.data
cat > "$WORK/wrap.sh" <<EOF
#!/bin/bash
exec perf record -q -F 499 -o "$WORK/perf.rank\${OMPI_COMM_WORLD_RANK:-x}.data" "\$@"
EOF
chmod +x "$WORK/wrap.sh"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1 LP_NUM_THREADS=1
mpirun --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS -np 11 "$WORK/wrap.sh" \
  "$BUILD/cave" run "$ROOT/configs/caves/cave5.json" --scene "$SCENE" --frames "$FRAMES" \
  --size "$SIZE" --write-every 0 --no-idle-lcd --quiet --gather-timeout 300 --timeout-ms 30000 ${EXTRA:-} \
  -o "$WORK/run" >/dev/null 2>"$WORK/stderr.log"
python3 - "$WORK" "$FRAMES" <<'EOF'
import collections, re, subprocess, sys
work, frames, hz = sys.argv[1], int(sys.argv[2]), 499.0
def load(r):
    out = subprocess.run(['perf', 'script', '-i', f'{work}/perf.rank{r}.data', '-F', 'time,ip,sym,dso'],
                         capture_output=True, text=True).stdout
    rows = []
    for l in out.splitlines():
        m = re.match(r'\s*([\d.]+):\s+\S+\s+(.*)\((.*)\)\s*$', l)
        if m: rows.append((float(m.group(1)), m.group(2).strip(), m.group(3).split('/')[-1]))
    return rows
def cat(sym, dso):
    if 'JIT' in dso or dso.startswith('perf-'): return 'shaders (JIT)'
    if 'swrast' in dso: return 'llvmpipe'
    if 'kernel' in dso: return 'kernel'
    if dso == 'cave': return 'cave:' + sym
    if any(k in dso for k in ('mpi', 'pal', 'vader', 'ob1', 'pmix', 'event')): return 'MPI'
    return 'other'
data = {r: load(r) for r in range(11)}
js = [t for r in range(1, 11) for (t, s, d) in data[r] if cat(s, d) == 'shaders (JIT)']
t0, t1 = min(js), max(js)
names = ['master'] + [f'{w} {e}' for w in ('front', 'left', 'right', 'floor', 'ceiling') for e in 'LR']
cols = ['shaders (JIT)', 'llvmpipe', 'kernel', 'cave', 'MPI', 'other']
print(f'window {t1 - t0:.1f} s, {frames} frames, CPU ms = samples / {hz:.0f} Hz / frames')
print('| rank | CPU ms per CAVE frame | ' + ' | '.join(cols) + ' | top functions of the program |')
print('|' + '---|' * (len(cols) + 3))
tot, topc = collections.Counter(), collections.Counter()
for r in range(11):
    c, cs = collections.Counter(), collections.Counter()
    for t, s, d in data[r]:
        if not t0 <= t <= t1: continue
        k = cat(s, d)
        if k.startswith('cave:'): cs[k[5:]] += 1; k = 'cave'
        c[k] += 1
    n = sum(c.values()) or 1
    tot.update(c); topc.update(cs)
    top = ', '.join(f'{s} {100 * v / n:.0f}%' for s, v in cs.most_common(3))
    print(f'| {r} {names[r]} | {n / hz * 1000 / frames:.0f} | ' + ' | '.join(f'{100 * c[k] / n:.0f}%' for k in cols) + f' | {top} |')
n = sum(tot.values())
print(f'| all | {n / hz * 1000 / frames:.0f} | ' + ' | '.join(f'{100 * tot[k] / n:.0f}%' for k in cols) + ' | ' +
      ', '.join(f'{s} {100 * v / n:.1f}%' for s, v in topc.most_common(5)) + ' |')
EOF
python3 -c "
import json,sys
s=[json.loads(l) for l in open(sys.argv[1]) if '\"summary\"' in l][-1]
print('CAVE frames/s (wall, whatever else loads the machine):', round(s['fps'],3), '; frame ms p50', round(s['frame_ms_p50'],1))" "$WORK/run/metrics.jsonl"
