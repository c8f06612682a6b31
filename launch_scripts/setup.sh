#!/usr/bin/env bash
# Installs the Debian 12 packages syndds needs (only when something is missing) and builds it
# (Release) into build/ (or $SYNDDS_BUILD_DIR). Safe to run again: it only does what is left.
#   launch_scripts/setup.sh [--no-install] [--jobs N]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD_DIR=${SYNDDS_BUILD_DIR:-$ROOT/build}
JOBS=$(nproc 2>/dev/null || echo 2)
INSTALL=1
while [ $# -gt 0 ]; do
  case "$1" in
    --no-install) INSTALL=0 ;;
    --jobs) JOBS=$2; shift ;;
    -h|--help) sed -n '2,5p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown option $1" >&2; exit 1 ;;
  esac
  shift
done

PACKAGES=(
  build-essential cmake pkg-config git
  libfastrtps-dev libfastcdr-dev fastddsgen fastdds-tools
  libeigen3-dev libode-dev libembree-dev
  libopencv-dev libyaml-cpp-dev libspdlog-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libtorch-dev pybind11-dev python3-dev
  libopenblas0-serial  # BLAS for libtorch: 3x the reference BLAS in learning, single-threaded (docs/learning.md)
  cyclonedds-dev cyclonedds-tools
  python3 python3-matplotlib python3-numpy
  iproute2 util-linux procps nftables openssl bc
  libcivetweb-dev chromium libassimp-dev
  slurm-wlm munge
)

if [ "$INSTALL" = 1 ]; then
  missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -q
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
  fi
fi

# The viewer's page (docs/viewer.md): three.js, and playwright-core for its browser tests, from
# npm at the versions package-lock.json pins. Node.js from Debian when there is none.
if [ "$INSTALL" = 1 ] && ! command -v npm > /dev/null; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends nodejs npm
fi
WEB="$ROOT/services/viewer/web"
if [ ! -f "$WEB/node_modules/.package-lock.json" ] || [ "$WEB/package-lock.json" -nt "$WEB/node_modules/.package-lock.json" ]; then
  echo "setup: installing the viewer's npm packages in services/viewer/web"
  (cd "$WEB" && npm ci --no-audit --no-fund --loglevel=error)
fi

echo "setup: building syndds (Release) in $BUILD_DIR with $JOBS jobs"
cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release --log-level=WARNING
cmake --build "$BUILD_DIR" -j "$JOBS"
echo "setup: done; programs are in $BUILD_DIR/bin"
