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
# the shared checks; several cases here print a usage before the error line
EXPECT_ONE_LINE=0
. "$HERE/expect.sh"

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
