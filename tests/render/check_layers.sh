#!/usr/bin/env bash
# The layers of src/render (issue 29, deliverable 5; docs/architecture.md):
# every file of src/render has a layer below; a file may include
# (`#include "render/..."`) only headers of a lower layer, or, for a .c
# file, its own header.  So no file includes one that calls back into it.
# Also fails on an include cycle (whatever the layers say), on a file of
# src/render that has no layer, and on an include of a header that does
# not exist.
# Usage: check_layers.sh [SRC_RENDER_DIR]   (default: the repository's src/render)
set -euo pipefail
DIR=${1:-$(cd "$(dirname "$0")/../../src/render" && pwd)}

# The declared order, bottom first: one line per layer; X stands for X.h
# and X.c.  Files on one line may not include each other.
LAYERS=(
  "renderer.h shaders window"                          # 0 platform: public API types, GLSL, X11
  "egl_context desktop"                                # 1 platform: EGL context, preview window
  "probe"                                              # 2 the pre-flight's GPU and display probe (on 1)
  "render_gl"                                          # 3 GL helpers and cvr_ctx (no feature)
  "render_edges"                                       # 4 edge sets, normals (no GL, no feature)
  "render_scene render_texture render_split render_post render_present" # 5 features on GL only
  "render_casters render_relight"                      # 6 features on the scene (+ split lights)
  "render_light"                                       # 7 lighting change, shadow map, background, panel
  "render_passes render_share"                         # 8 frame passes; shared lighting
  "renderer_internal.h renderer.c renderer_api"        # 9 top: create/destroy/upload, public entry points
)
# A .c file's own header (default: the same name).
declare -A OWN=([renderer.c]=renderer_internal.h [renderer_api.c]=renderer_internal.h)

declare -A RANK
for i in "${!LAYERS[@]}"; do
  for n in ${LAYERS[$i]}; do
    case $n in
      *.h | *.c) RANK[$n]=$i ;;
      *) RANK[$n.h]=$i RANK[$n.c]=$i ;;
    esac
  done
done

fail=0
declare -A EDGES
files=$(cd "$DIR" && ls -- *.c *.h 2>/dev/null | sort)
[ -n "$files" ] || { echo "FAIL: no sources in $DIR"; exit 1; }
for f in $files; do
  if [ -z "${RANK[$f]+x}" ]; then
    echo "FAIL: $f has no layer (add it to LAYERS in $0)"
    fail=1
    continue
  fi
  own=${OWN[$f]:-${f%.c}.h}
  EDGES[$f]=""
  while IFS= read -r inc; do
    [ -n "$inc" ] || continue
    if [ ! -f "$DIR/$inc" ]; then
      echo "FAIL: $f includes render/$inc, which is not in src/render"
      fail=1
      continue
    fi
    EDGES[$f]+=" $inc"
    if [ -z "${RANK[$inc]+x}" ]; then
      continue # reported above as a file without a layer
    fi
    if [[ $f == *.c && $inc == "$own" ]]; then
      continue
    fi
    if [ "${RANK[$inc]}" -ge "${RANK[$f]}" ]; then
      echo "FAIL: $f (layer ${RANK[$f]}) includes render/$inc (layer ${RANK[$inc]}): not below it"
      fail=1
    fi
  done < <(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"render\/\([^"]*\)".*/\1/p' "$DIR/$f")
done

# Include cycles, by depth-first search over the include graph.
declare -A STATE # 1 on the stack, 2 done
cycle() {
  local f=$1 path=$2 g
  STATE[$f]=1
  for g in ${EDGES[$f]:-}; do
    if [ "${STATE[$g]:-0}" = 1 ]; then
      echo "FAIL: include cycle: $path -> $g"
      fail=1
    elif [ "${STATE[$g]:-0}" = 0 ]; then
      cycle "$g" "$path -> $g"
    fi
  done
  STATE[$f]=2
}
for f in $files; do
  [ "${STATE[$f]:-0}" = 0 ] && cycle "$f" "$f"
done

n=$(echo "$files" | wc -l)
if [ $fail = 0 ]; then
  echo "layers OK: $n files of $DIR in ${#LAYERS[@]} layers, no include upwards or sideways, no cycle"
  for i in "${!LAYERS[@]}"; do echo "  $i: ${LAYERS[$i]}"; done
fi
exit $fail
