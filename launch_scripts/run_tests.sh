#!/usr/bin/env bash
# Sets up syndds (Debian packages + Release build, see setup.sh) and runs the whole test suite:
# unit tests, in-process DDS tests and multi-process tests of the real programs (each in its own
# network namespace when run as root). Extra arguments go to ctest, e.g. -L unit or -R Barrier.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD_DIR=${SYNDDS_BUILD_DIR:-$ROOT/build}
"$ROOT/launch_scripts/setup.sh"
cd "$BUILD_DIR"
# Fast DDS leaves shared-memory files behind when a process is killed (tests kill some).
trap 'fastdds shm clean > /dev/null 2>&1 || true' EXIT
ctest --output-on-failure -j "${SYNDDS_TEST_JOBS:-2}" "$@"
