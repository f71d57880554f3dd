#!/usr/bin/env bash
# Fuzzes each harness for N minutes with libFuzzer (docs/fuzzing.md), one at
# a time.  Usage: tests/fuzz/run.sh [MINUTES] [HARNESS...]   (default 2, all)
# Needs clang and libomp-dev (Debian 12: clang-14).  Builds build-fuzz/ with
# CC=clang -DCAVE_FUZZ=ON; new inputs that add coverage go to
# build-fuzz/corpus/<name>/ (the seeds in tests/fuzz/<name>/ stay as they
# are); crashes, leaks and timeouts go to build-fuzz/crashes/<name>/: copy
# the ones you fix into tests/fuzz/<name>/ so the ctest replay keeps them.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
minutes=${1:-2}
shift || true
all=(prt scene cave display drive head brdf dtrack exr)
names=("${@:-${all[@]}}")
command -v clang >/dev/null || { echo "run.sh: clang is missing (apt-get install clang libomp-dev)" >&2; exit 2; }
b="$root/build-fuzz"
CC=clang cmake -S "$root" -B "$b" -DCAVE_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$b" -j"$(nproc)" --target "${names[@]/#/fuzz_}" >/dev/null
export ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=1"
export LSAN_OPTIONS="suppressions=$root/tests/lsan.supp"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
for n in "${names[@]}"; do
  mkdir -p "$b/corpus/$n" "$b/crashes/$n"
  echo "== fuzz_$n: $minutes min"
  # -rss_limit_mb: our readers must refuse, not allocate, what the file cannot hold.
  TMPDIR="$b" "$b/tests/fuzz/fuzz_$n" "$b/corpus/$n" "$root/tests/fuzz/$n" \
    -max_total_time=$((minutes * 60)) -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
    -artifact_prefix="$b/crashes/$n/" -print_final_stats=1 2>"$b/fuzz_$n.log" || true
  grep -E "^(#[0-9]+.*(DONE|pulse)|stat::|==[0-9]+==ERROR|SUMMARY)" "$b/fuzz_$n.log" | tail -8
  ls "$b/crashes/$n" | sed "s|^|  found: $b/crashes/$n/|"
done
