# Source this on the GPU machine from the repository root:
#   source tests/bench/gpu_env.sh PACK_DIR      (PACK_DIR: tests/bench/gpu_pack.sh's output)
# It unpacks devlibs.tar.xz into /tmp/d (devlibs/), Open MPI + PMIx
# (ompi.tar.xz, absolute paths) into / without replacing any existing file,
# forest.exr into Blender's studiolights path, and sets LD_LIBRARY_PATH, the
# NVIDIA EGL vendor file, PATH (mpirun, mpiexec) and Open MPI's settings for
# one host without high-speed networks.  A variable already set is kept.
# No `set -e` here: it would stay in the caller's shell.
_gp_main() {
  local pack="${1:-.devpack}" d=/tmp/d f
  pack="$(cd "$pack" && pwd)" || { echo "gpu_env: no pack dir ${1:-.devpack}"; return 1; }
  mkdir -p "$d/ompi-bin"
  # tar -J needs xz; else the pack's own xz (+ liblzma); else python3's tarfile
  _gp_untar() {   # ARCHIVE DEST [tar options]
    local a="$1" t="$2"; shift 2
    tar -xJf "$a" -C "$t" "$@" 2>/dev/null && return 0
    LD_LIBRARY_PATH="$pack" "$pack/xz" -dc "$a" 2>/dev/null | tar -xf - -C "$t" "$@" 2>/dev/null && return 0
    python3 - "$a" "$t" "$@" <<'EOF'
import os, sys, tarfile
a, t, keep = sys.argv[1], sys.argv[2], len(sys.argv) > 3
with tarfile.open(a) as tf:
    ms = [m for m in tf.getmembers() if not (keep and os.path.lexists(os.path.join(t, m.name)))]
    kw = {"filter": "fully_trusted"} if hasattr(tarfile, "data_filter") else {}
    tf.extractall(t, members=ms, **kw)
EOF
  }
  _gp_untar "$pack/devlibs.tar.xz" "$d" || { echo "gpu_env: devlibs.tar.xz not unpacked"; return 1; }
  _gp_untar "$pack/ompi.tar.xz" / --skip-old-files || { echo "gpu_env: ompi.tar.xz not unpacked"; return 1; }
  command -v ldconfig >/dev/null && ldconfig 2>/dev/null   # the carried libpmix, libmunge, ...
  f=/usr/share/blender/datafiles/studiolights/world
  mkdir -p "$f" && { [ -e "$f/forest.exr" ] || cp "$pack/forest.exr" "$f/"; }
  ln -sf /usr/bin/orterun "$d/ompi-bin/mpirun"; ln -sf /usr/bin/orterun "$d/ompi-bin/mpiexec"
  export PATH="$d/ompi-bin:$PATH"
  export LD_LIBRARY_PATH="$d/devlibs:/usr/local/nvidia/lib64:/usr/local/nvidia/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/*nvidia*.json \
           /usr/share/glvnd/egl_vendor.d/*nvidia*.json /etc/glvnd/egl_vendor.d/*nvidia*.json; do
    [ -f "$f" ] && { export __EGL_VENDOR_LIBRARY_FILENAMES="$f"; break; }
  done
  # Open MPI: root allowed; no messages for plugins that cannot load; shared
  # memory (vader) + self (+ tcp) with ob1, no MTL/UCX/OFI paths; vader copies
  # through its segment instead of CMA (process_vm_readv fails in many
  # containers); more ranks than cores allowed (16 CPUs may be 8 cores);
  # PMIx: in-process hash store and native security (no munge daemon).
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
  export OMPI_MCA_mca_base_component_show_load_errors="${OMPI_MCA_mca_base_component_show_load_errors:-0}"
  export OMPI_MCA_btl="${OMPI_MCA_btl:-self,vader,tcp}"
  export OMPI_MCA_pml="${OMPI_MCA_pml:-ob1}"
  export OMPI_MCA_mtl="${OMPI_MCA_mtl:-^ofi,psm,psm2}"
  export OMPI_MCA_osc="${OMPI_MCA_osc:-^ucx}"
  export OMPI_MCA_btl_vader_single_copy_mechanism="${OMPI_MCA_btl_vader_single_copy_mechanism:-none}"
  export OMPI_MCA_rmaps_base_oversubscribe="${OMPI_MCA_rmaps_base_oversubscribe:-1}"
  # no ssh/rsh (a bare image): mpirun's rsh launcher refuses to start even
  # for local ranks; the isolated launcher only starts ranks on this host
  command -v ssh >/dev/null || command -v rsh >/dev/null ||
    export OMPI_MCA_plm="${OMPI_MCA_plm:-isolated}"
  export PMIX_MCA_gds="${PMIX_MCA_gds:-hash}" PMIX_MCA_psec="${PMIX_MCA_psec:-native}"
  # a small /dev/shm (containers: 64 MB) cannot hold 11 ranks' segments
  f=$(df -Pk /dev/shm 2>/dev/null | awk 'NR==2 {print $4}')
  if [ "${f:-0}" -lt 524288 ] && [ -z "${OMPI_MCA_btl_vader_backing_directory:-}" ]; then
    export OMPI_MCA_btl_vader_backing_directory=/tmp
  fi
  echo "gpu_env: unpacked $pack into $d/devlibs and / (Open MPI $(ompi_info --version 2>/dev/null | head -1 | awk '{print $NF}'), $(command -v mpirun)); LD_LIBRARY_PATH=$LD_LIBRARY_PATH"
  echo "gpu_env: EGL vendor ${__EGL_VENDOR_LIBRARY_FILENAMES:-(none found)}; $(env | grep -E '^(OMPI|PMIX)_MCA_' | sort | tr '\n' ' ')"
  unset -f _gp_untar
}
_gp_main "$@"; _gp_rc=$?; unset -f _gp_main
[ "$_gp_rc" = 0 ]
