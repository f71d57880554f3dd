#!/usr/bin/env bash
# Model corpus test (docs/fuzzing.md): bakes a fixed sample of assimp's test
# models (Debian package assimp-testmodels) at the cheapest settings and
# classifies each run: ok (exit 0), clean error (exit 1 or 2 with exactly one
# stderr line naming the file), unclear (anything else without a signal),
# crash (a signal or a sanitizer abort), hang (the per-model time limit).
# Passes when there is no unclear, crash or hang.  Usage:
#   test_corpus.sh CAVE WORKDIR [EVERY_NTH] [MAX_KB]
set -u
CAVE=$(realpath "$1") W=$2 NTH=${3:-8} MAXKB=${4:-300}
M=/usr/share/assimp/models
if [ ! -d $M ]; then
  echo "test_corpus: $M missing (apt-get install assimp-testmodels; cluster/setup.sh does)"
  exit 1
fi
rm -rf "$W" && mkdir -p "$W" && cd "$W" || exit 1
# Model files only (no textures, notes or sources), small ones, every NTH in name order.
mapfile -t files < <(cd $M && find . -type f -size -"${MAXKB}"k |
  grep -v -iE 'ReferenceImages|SourceFiles|\.(png|jpg|jpeg|bmp|tga|dds|txt|md|mtl|bin|mat|gif|pcx|tif|tiff|shader|skin|xml|material|program|ini|zip)$' |
  LC_ALL=C sort | awk -v n="$NTH" '(NR - 1) % n == 0')
# and always assimp's own hostile file (a header claiming 353535235358 vertices)
if [ -f $M/invalid/OutOfMemory.off ] && [[ " ${files[*]} " != *" ./invalid/OutOfMemory.off "* ]]; then
  files+=(./invalid/OutOfMemory.off)
fi
export CAVE_IMPORT_TIMEOUT=10 CAVE_IMPORT_MEMORY_MB=2048
declare -A count
for k in ok clean unclear crash hang; do count[$k]=0; done
for f in "${files[@]}"; do
  p="$M/${f#./}"
  timeout -s KILL 40 "$CAVE" bake "$p" -o out.prt --bands 2 --rays 1 --bounces 0 --quiet --force \
    >out.txt 2>err.txt
  rc=$?
  lines=$(wc -l <err.txt)
  if [ $rc -eq 0 ]; then k=ok
  elif [ $rc -eq 137 ]; then k=hang
  elif [ $rc -gt 2 ]; then k=crash
  elif [ "$lines" -eq 1 ] && grep -qF "$(basename "$p")" err.txt; then k=clean
  elif grep -q "import (.*) crashed\|Sanitizer" err.txt; then k=crash
  else k=unclear
  fi
  count[$k]=$((count[$k] + 1))
  printf '%-7s %s: %s\n' "$k" "${f#./}" "$(tail -n 1 err.txt | cut -c1-200)"
  [ "$k" = ok ] || [ "$k" = clean ] || sed 's/^/    /' err.txt | head -30
  rm -f out.prt
done
echo "corpus: ${#files[@]} models: ok ${count[ok]}, clean error ${count[clean]}, unclear ${count[unclear]}, crash ${count[crash]}, hang ${count[hang]}"
[ "${#files[@]}" -gt 0 ] && [ $((count[unclear] + count[crash] + count[hang])) -eq 0 ]
