#!/usr/bin/env bash
# The hostile-input campaign of docs/fuzzing.md: runs CAVE on every input of
# make_campaign.py (and, with a third argument, every assimp test model) and
# prints one table row per input kind: cases, ok, clean error, unclear,
# crash, hang.  ok = exit 0 (for the crafted prt/JSON inputs, all invalid,
# an exit 0 counts as unclear: bad data accepted); clean = exit 1 or 2 and
# every stderr line names the file (a display config lists every problem,
# one a line), a JSON syntax error with its line and column; crash = a
# signal or a sanitizer report; hang = 30 s.
# Usage: campaign.sh CAVE WORKDIR [models]
set -u
CAVE=$(realpath "$1") W=$2 ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
rm -rf "$W" && mkdir -p "$W" && cd "$W" || exit 1
python3 "$ROOT/tests/fuzz/make_campaign.py" "$ROOT" in
run() { # run KIND FILE: classify one run of the command for KIND
  local kind=$1 f=$2 rc
  case $kind in
    prt) timeout -s KILL 30 "$CAVE" shade "$f" --env-constant 1,1,1 -o x.ply ;;
    scene) timeout -s KILL 30 "$CAVE" bake "$f" -o x.prt --bands 2 --rays 1 --bounces 0 --quiet ;;
    cave) timeout -s KILL 30 "$CAVE" render "$f" --scene none.prt --env-constant 1,1,1 -o d ;;
    display) timeout -s KILL 30 "$CAVE" compensate --display "$f" --image none.exr -o x.exr ;;
  esac >out.txt 2>err.txt
  rc=$?
  rm -rf x.ply x.prt d x.exr
  local b; b=$(basename "$f")
  if [ $rc -eq 137 ]; then echo hang
  elif [ $rc -gt 2 ] || grep -q "Sanitizer\|runtime error" err.txt; then echo crash
  elif [ $rc -eq 0 ]; then echo unclear
  elif [ -s err.txt ] && ! grep -vqF "$b" err.txt &&
       { ! grep -qi "json syntax\|not valid json" err.txt || grep -q "column\|:[0-9]*:[0-9]*:" err.txt; }; then
    echo clean
  else echo unclear
  fi
}
printf '| input kind | cases | ok | clean error | unclear | crash | hang |\n|---|---|---|---|---|---|---|\n'
for kind in prt scene cave display; do
  declare -A c=([ok]=0 [clean]=0 [unclear]=0 [crash]=0 [hang]=0)
  n=0
  for f in in/$kind/*; do
    k=$(run $kind "$f")
    c[$k]=$((c[$k] + 1)); n=$((n + 1))
    [ "$k" = clean ] || echo "$kind $k $(basename "$f"): $(head -c 300 err.txt | tr '\n' ' ')" >>details.txt
  done
  printf '| %s | %d | %d | %d | %d | %d | %d |\n' $kind $n ${c[ok]} ${c[clean]} ${c[unclear]} ${c[crash]} ${c[hang]}
done
if [ "${3:-}" = models ]; then
  "$ROOT/tests/corpus/test_corpus.sh" "$CAVE" models 1 1000000 >models.txt 2>&1
  tail -n 1 models.txt | sed -E 's/corpus: ([0-9]+) models: ok ([0-9]+), clean error ([0-9]+), unclear ([0-9]+), crash ([0-9]+), hang ([0-9]+)/| assimp test models | \1 | \2 | \3 | \4 | \5 | \6 |/'
fi
