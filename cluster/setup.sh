#!/usr/bin/env bash
# Installs the Debian 12 packages the project needs (only those missing) and
# builds it.  Sourced by cluster/main-job.sh and tests/run-all.sh; run it on
# every node of a cluster.  Usage: cluster/setup.sh [BUILD_DIR [CMAKE_ARGS...]]
set -euo pipefail

CAVE_PACKAGES=(
  build-essential cmake pkg-config git
  libembree-dev libopenexr-dev zlib1g-dev libcglm-dev libcjson-dev libassimp-dev
  libpng-dev libjpeg62-turbo-dev libmeshoptimizer-dev libcmocka-dev libopenmpi-dev openmpi-bin
  libegl-dev libgl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri libx11-dev
  xvfb xauth xdotool x11-utils python3
  gnuplot-nox linux-perf
  blender-data assimp-testmodels python3-jsonschema
  libmicrohttpd-dev chromium python3-websocket python3-prometheus-client curl iproute2
)

cave_install_packages() {
  local missing=() p
  for p in "${CAVE_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    echo "setup: all ${#CAVE_PACKAGES[@]} Debian packages present"
    return 0
  fi
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  echo "setup: installing ${missing[*]}"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
}

# cave_build DIR [CMAKE_ARGS...]: configures (Release unless given) and builds.
cave_build() {
  local dir="$1"; shift
  cmake -S "$CAVE_ROOT" -B "$dir" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
  cmake --build "$dir" -j"$(nproc)"
}

CAVE_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
  cave_install_packages
  cave_build "${1:-$CAVE_ROOT/build}" "${@:2}"
fi
