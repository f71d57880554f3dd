#!/usr/bin/env bash
# The whole test suite: installs what is missing, builds, runs every ctest
# test in a Release build, then the unit tests again under AddressSanitizer +
# UndefinedBehaviorSanitizer (label `slow` excluded there to keep CI short).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../cluster/setup.sh"
cave_install_packages
jobs="$(nproc)"

echo "== Release build (-Wall -Wextra, warnings are errors) =="
cave_build "$CAVE_ROOT/build" -DCAVE_WERROR=ON
(cd "$CAVE_ROOT/build" && ctest --output-on-failure -j"$jobs")

echo "== AddressSanitizer + UBSan build =="
cave_build "$CAVE_ROOT/build-asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCAVE_SANITIZE=ON -DCAVE_WERROR=ON
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$CAVE_ROOT/tests/lsan.supp"
(cd "$CAVE_ROOT/build-asan" && ctest --output-on-failure -j"$jobs" -LE slow)
