#!/usr/bin/env bash
# Packs what a GPU machine without Debian's libraries or Open MPI needs to run
# cave, bench_render and img_diff (tests/bench/gpu_check.sh), bench_shadow,
# the renderer's tests (test_render, test_render_share, test_render_texture:
# run there they test the hardware device's paths) and
# `mpirun -np 11 cave run ...`; tests/bench/gpu_env.sh unpacks it there.
#
# Usage: gpu_pack.sh BUILD_DIR [OUT_DIR (.devpack in the repository root)]
# Writes into OUT_DIR:
#   cave, bench_render, img_diff, bench_shadow, test_render,
#   test_render_share, test_render_texture   the binaries, flat
#   devlibs.tar.xz   devlibs/: every `ldd` library of the binaries but
#                    libc, libm, libstdc++, libgcc_s, ld-linux, linux-vdso
#   ompi.tar.xz      Debian 12's Open MPI 4.1 + PMIx runtime with ABSOLUTE
#                    paths (their install paths are compiled in): orterun,
#                    orted, ompi_info, the MCA plugins whose libraries are
#                    carried (not ucx/ofi/psm/verbs/netlink/oshmem), PMIx and
#                    its plugins, help and data files, /etc/openmpi, and the
#                    libraries these need but libc/libm/libstdc++/libgcc_s.
#                    Extract with `tar -xJf ompi.tar.xz -C / --skip-old-files`.
#   forest.exr       the default scene's environment map (Blender's)
#   xz, liblzma.so.5 an xz for targets without xz-utils (gpu_env.sh's fallback)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;; esac
BUILD="$(realpath "${1:?usage: gpu_pack.sh BUILD_DIR [OUT_DIR]}")"
OUT="${2:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)/.devpack}"
XZ="${XZ:-xz -9 -T0}"
EXR=/usr/share/blender/datafiles/studiolights/world/forest.exr
ML=/usr/lib/x86_64-linux-gnu
PKGLIB=$ML/openmpi/lib/openmpi3   # ompi_info --path pkglibdir
PMIX=$ML/pmix2                    # libpmix's compiled-in prefix
mkdir -p "$OUT"; OUT="$(realpath "$OUT")"
W="$(mktemp -d)"; trap 'rm -rf "$W"' EXIT

pick() { if [ -x "$BUILD/$1" ]; then echo "$BUILD/$1"; else echo "$BUILD/$(basename "$1")"; fi; }
BINS=("$(pick cave)" "$(pick tests/bench/bench_render)" "$(pick tests/bench/img_diff)"
      "$(pick tests/bench/bench_shadow)" "$(pick tests/render/test_render)"
      "$(pick tests/render/test_render_share)" "$(pick tests/render/test_render_texture)")
for b in "${BINS[@]}"; do cp -f "$b" "$OUT/"; done
cp -f "$EXR" "$OUT/forest.exr"
cp -f "$(command -v xz)" "$OUT/xz"; cp -fL $ML/liblzma.so.5 "$OUT/liblzma.so.5"

# Libraries the target's base system is assumed to have (same as devlibs').
BASE='^(linux-vdso|ld-linux|libc|libm|libstdc\+\+|libgcc_s|libdl|libpthread|librt)\.so'
deps() { ldd "$@" 2>/dev/null | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}' | sort -u; }

# --- devlibs: the binaries' libraries, flat.
mkdir -p "$W/devlibs"
deps "${BINS[@]}" | while read -r name path; do
  [[ "$name" =~ $BASE ]] || cp -L "$path" "$W/devlibs/$name"
done
ldd "${BINS[@]}" | grep -q "not found" && { echo "gpu_pack: a library is not found"; exit 1; }
tar -C "$W" -cf - devlibs | $XZ > "$OUT/devlibs.tar.xz"

# --- Open MPI + PMIx.  Plugins needing a high-speed-network or OpenSHMEM
# library (or anything ldd cannot find) are left out: Open MPI skips a
# framework's absent components without a word.
SKIP='^lib(uc[ptsm]|ibverbs|rdmacm|fabric|psm|infinipath|nl-|efa|oshmem|mca_common_(ofi|ucx|verbs)|mpi_java|jvm|gfortran|mpi_mpifh|pciaccess)'
: > "$W/files"
add() { for f in "$@"; do
  [ -e "$f" ] || [ -L "$f" ] || { echo "gpu_pack: missing $f"; exit 1; }
  f="${f/#\/lib\//\/usr\/lib\/}"; echo "$f" >> "$W/files"
  [ -L "$f" ] && add "$(realpath "$f")"; done; return 0; }
ok_deps() { ! ldd "$1" 2>/dev/null | grep -q "not found" &&
            ! deps "$1" | awk '{print $1}' | grep -Eq "$SKIP"; }
bins=(/usr/bin/orterun /usr/bin/orted /usr/bin/ompi_info)
add "${bins[@]}" /usr/bin/mpirun.openmpi /usr/bin/mpiexec.openmpi
skipped=()
for p in "$PKGLIB"/*.so "$PMIX"/lib/pmix/*.so; do
  if ok_deps "$p"; then add "$p"; bins+=("$p"); else skipped+=("$(basename "$p" .so)"); fi
done
add "$PMIX/lib/libpmix.so.2" "$ML/libpmix.so.2"
# help texts, data and parameter files (pkgdatadir, sysconfdir, PMIx's share)
while IFS= read -r f; do add "$f"; done < <(find /usr/share/openmpi /etc/openmpi $PMIX/share \
  \( -type f -o -type l \) | sort)
[ -d /etc/pmix ] && while IFS= read -r f; do add "$f"; done < <(find /etc/pmix -type f)
# every library of the carried binaries and plugins (libmpi, libopen-rte,
# libopen-pal, libpmix, libhwloc, libevent*, libudev, libz, libmunge, ...)
deps "${bins[@]}" | while read -r name path; do
  [[ "$name" =~ $BASE ]] && continue
  [[ "$name" =~ $SKIP ]] && { echo "gpu_pack: unexpected $name"; exit 1; }
  echo "${path/#\/lib\//\/usr\/lib\/}"
done > "$W/libs"
while IFS= read -r f; do add "$f"; done < "$W/libs"
sort -u "$W/files" | sed 's#^/##' > "$W/list"
tar -C / --no-recursion --numeric-owner -cf - -T "$W/list" | $XZ > "$OUT/ompi.tar.xz"
echo "gpu_pack: ompi.tar.xz: $(wc -l < "$W/list") paths; left out: ${skipped[*]}"

echo "gpu_pack: $OUT"
( cd "$OUT" && ls -la cave bench_render img_diff bench_shadow test_render test_render_share test_render_texture devlibs.tar.xz ompi.tar.xz forest.exr xz liblzma.so.5 | awk '{printf "  %10d  %s\n", $5, $9}' )
echo "  total $(du -sh "$OUT" | cut -f1)"
