# Shared set-up of the window tests (test_present.sh, test_desktop.sh), sourced
# once the script runs under Xvfb: a fresh work folder, ok/bad counters, Open
# MPI on one machine as root with the X display passed to every rank
# (LeakSanitizer off for mpirun runs: Open MPI's own allocations), a quickly
# baked default scene, a still drive, and the common `cave run` options.
# Expects CAVE, WORK, SRC and MPIEXEC to be set.
rm -rf "$WORK"; mkdir -p "$WORK"; cd "$WORK" || exit 1
pass=0; fail=0
ok()  { echo "ok: $*"; pass=$((pass + 1)); }
bad() { echo "FAIL: $*"; fail=$((fail + 1)); }
export OMP_NUM_THREADS=1 LP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1 OMPI_MCA_mca_base_component_disable_dlclose=1
MPI=("$MPIEXEC" --oversubscribe -x OMP_NUM_THREADS -x LP_NUM_THREADS -x DISPLAY -x XAUTHORITY
     -x OMPI_MCA_mca_base_component_disable_dlclose)
[ -n "${ASAN_OPTIONS:-}" ] && export ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0"
for v in ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS; do [ -n "${!v:-}" ] && MPI+=(-x "$v"); done
CFG="$SRC/configs/caves/cave5.json"
echo "X display $DISPLAY"

"$CAVE" bake default -o scene.prt --tess 1 --bands 3 --rays 32 --bounces 1 --quiet >/dev/null || { echo "FAIL: bake"; exit 1; }
cat > still.json <<'JSON'
{"description": "standing still under forest", "loop": true, "maps": ["forest.exr"],
 "keyframes": [{"t": 0, "yaw": 30, "weights": [1]}, {"t": 10, "yaw": 30}]}
JSON
S=64
COMMON=(--scene scene.prt --size $S --patches 8 --no-lcd --drive still.json --quiet)
