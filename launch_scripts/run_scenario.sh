#!/usr/bin/env bash
# Runs a scenario: one process per vehicle, controller, sensor and recorder plus the coordinator,
# watched until the run ends; prints a short summary, or a one-line reason on failure.
#
#   launch_scripts/run_scenario.sh SCENARIO.yaml [--output DIR] [--duration S] [--realtime]
#       [--single-process] [--processes per_member|per_vehicle|N] [--print-commands]
#       [--domain D] [--run-id ID] [--transport default|udp|udp_redundant] [--discovery-server ADDR:PORT]
#       [--log-level LEVEL] [--security-dir DIR] [--view [--view-port P] [--view-bind ADDR]]
#   launch_scripts/run_scenario.sh [SCENARIO.yaml] --resume RUN_DIR [--from-frame K] [options]
#
# The launcher is the program syndds_launch (services/launch/, docs/deployment.md, "The
# launcher"): --help there says what each option does. Exit status: 0 completed, 1 bad scenario
# or command line or more than this host can start, 2 run aborted, a process failed, or the run
# completed without its recorder, 130 interrupted. Logs of every process: OUTPUT/logs/.
# Programs: build/bin (or $SYNDDS_BUILD_DIR/bin; run launch_scripts/setup.sh first).
set -u
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
if [ ! -x "$BIN/syndds_launch" ]; then
  echo "run_scenario: $BIN/syndds_launch is missing: run launch_scripts/setup.sh first" >&2
  exit 1
fi
SYNDDS_LAUNCH_NAME=run_scenario exec "$BIN/syndds_launch" "$@"
