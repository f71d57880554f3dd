# Shared set-up of the MPI service tests without windows (test_cluster.sh,
# test_lighting_share.sh, test_frame_path.sh), sourced after CAVE, WORK, SRC
# and MPIEXEC are set: a fresh work folder, ok/bad counters, Open MPI on one
# machine as root, the sanitizers' options passed to every rank, CFG, and a
# small bake in scene.prt (few rays: transfer accuracy does not matter here).
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK" || exit 1
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
# One thread per rank: 11+ ranks share 2 cores.
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
# Keep Open MPI's plugins loaded so sanitizer reports name them (lsan.supp).
export OMPI_MCA_mca_base_component_disable_dlclose=1
MPI=("$MPIEXEC" --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS
     -x OMPI_MCA_mca_base_component_disable_dlclose)
# Under the sanitizers, LeakSanitizer is off for the MPI runs (AddressSanitizer
# and UBSan stay on): Open MPI and Mesa free nothing at exit from plugins they
# have unloaded, so those stacks cannot be attributed or suppressed, and full
# unwinding (fast_unwind_on_malloc=0) deadlocks in libgcc's unwinder against
# llvmpipe's threads.  The roles' own allocations are freed on every path.
[ -n "${ASAN_OPTIONS:-}" ] && export ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0"
for v in ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS; do [ -n "${!v:-}" ] && MPI+=(-x "$v"); done
CFG="$SRC/configs/caves/cave5.json"
"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null \
  || { echo "FAIL: bake"; exit 1; }
