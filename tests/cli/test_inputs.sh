#!/usr/bin/env bash
# Wrong input to every `cave` command, as a user would give it (the audit of
# 2026-11-28): crashes, exit 0 on an error, files left behind, late checks.
# Usage: test_inputs.sh CAVE WORKDIR SOURCE_ROOT
# Each part (inputs_*.sh) holds the cases of one group of commands; they
# share a small baked scene, a.prt, and the helpers below.
set -u
CAVE=$1 W=$2 ROOT=$3
HERE=$(cd "$(dirname "$0")" && pwd)
rm -rf "$W" && mkdir -p "$W" && cd "$W" || exit 1
pass=0 fail=0
ok() { echo "ok: $1"; pass=$((pass + 1)); }
bad() { echo "FAIL: $1"; fail=$((fail + 1)); }

# expect_error NAME PATTERN CMD...: a clean failure (exit 1 or 2, no
# signal) whose last stderr line matches PATTERN (grep regex).
expect_error() {
  local name=$1 pat=$2
  shift 2
  "$@" >out.txt 2>err.txt
  local rc=$?
  if [ $rc -eq 0 ] || [ $rc -gt 2 ]; then
    bad "$name: exit status $rc (expected 1 or 2)"; tail -n 5 err.txt; return
  fi
  if ! tail -n 1 err.txt | grep -q -- "$pat"; then
    bad "$name: last error line lacks '$pat'"; tail -n 5 err.txt; return
  fi
  ok "$name: $(tail -n 1 err.txt)"
}

expect_ok() {
  local name=$1
  shift
  if "$@" >out.txt 2>err.txt; then ok "$name"; else bad "$name: exit $?"; tail -n 5 err.txt; fi
}

# expect_absent NAME FILE...: none of the files exists (nothing left behind).
expect_absent() {
  local name=$1 f
  shift
  for f in "$@"; do
    if [ -e "$f" ]; then bad "$name: $f was left behind"; return; fi
  done
  ok "$name: nothing left behind"
}

# a small scene every part may use
"$CAVE" bake default --bands 2 --rays 16 --bounces 0 -o a.prt >/dev/null 2>&1 || { bad "bake a.prt"; }

for part in "$HERE"/inputs_*.sh; do
  [ -f "$part" ] || continue
  echo "--- $(basename "$part")"
  # shellcheck source=/dev/null
  . "$part"
done

echo "passed $pass, failed $fail"
[ "$fail" -eq 0 ]
