#!/usr/bin/env bash
# Opens a recorded run in the browser viewer (docs/viewer.md): starts syndds_viewer on the run
# directory and prints the URL to open; Ctrl-C stops it.
#
#   launch_scripts/view.sh RUN_DIR [--port P] [--bind ADDR]
#   launch_scripts/view.sh RUN_DIR --screenshot FILE.png [--time S] [--camera follow|orbit|top]
#       [--vehicle ID] [--size WxH]
#
# --port: 8080 unless given (0: any free port); --bind: 127.0.0.1 unless given (0.0.0.0 shows
# the run to the network). --screenshot draws the run at --time seconds (default: the end) in
# headless Chromium (Debian's chromium, driven by playwright-core) and saves the picture.
set -u
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
die() { echo "view: $*" >&2; exit "${2:-1}"; }
usage() { sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; }

[ $# -ge 1 ] || { usage >&2; exit 1; }
case "$1" in -h|--help) usage; exit 0 ;; esac
RUN_DIR=$1; shift
[ -d "$RUN_DIR" ] || die "run directory not found: $RUN_DIR"
[ -f "$RUN_DIR/scene.json" ] || die "$RUN_DIR/scene.json is missing: not a run directory written by the recorder"
PORT=8080; BIND=127.0.0.1; SHOT=""; SHOT_ARGS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --port) [ $# -ge 2 ] || die "--port needs a value"; PORT=$2; shift ;;
    --bind) [ $# -ge 2 ] || die "--bind needs a value"; BIND=$2; shift ;;
    --screenshot) [ $# -ge 2 ] || die "--screenshot needs a file"; SHOT=$2; shift ;;
    --time|--camera|--vehicle|--size)
      [ $# -ge 2 ] || die "$1 needs a value"; SHOT_ARGS+=("$1" "$2"); shift ;;
    -h|--help) usage; exit 0 ;;
    *) die "unknown option: $1 (see --help)" ;;
  esac
  shift
done
[ -x "$BIN/syndds_viewer" ] || die "$BIN/syndds_viewer is missing: run launch_scripts/setup.sh first"

if [ -z "$SHOT" ]; then
  exec "$BIN/syndds_viewer" --replay "$RUN_DIR" --port "$PORT" --bind "$BIND"
fi

# Screenshot: a viewer on a free port, the browser, then stop the viewer.
tmp=$(mktemp -d)
"$BIN/syndds_viewer" --replay "$RUN_DIR" --port 0 --bind 127.0.0.1 --url-file "$tmp/url" \
    > "$tmp/viewer.log" 2>&1 &
vpid=$!
trap 'kill $vpid 2>/dev/null; wait $vpid 2>/dev/null; rm -rf "$tmp"' EXIT
for _ in $(seq 100); do
  [ -s "$tmp/url" ] || ! kill -0 $vpid 2>/dev/null && break
  sleep 0.1
done
[ -s "$tmp/url" ] || die "the viewer did not start: $(tail -n1 "$tmp/viewer.log")"
node "$ROOT/tools/viewer_browser.mjs" "$(cat "$tmp/url")" --screenshot "$SHOT" "${SHOT_ARGS[@]}"
