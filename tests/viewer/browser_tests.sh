#!/usr/bin/env bash
# The viewer as a user meets it, in headless Chromium: one case per call (CTest runs each in its
# own network namespace through tests/netns_exec.sh). Exit 77 (skipped) without chromium or the
# npm packages (launch_scripts/setup.sh installs both).
#   browser_tests.sh replay|ruts|contact|radar|live|kill|origin OUT_DIR
#     replay  the default scenario recorded: loads, the slider moves the vehicles, screenshot
#     ruts    scm_crossing recorded: the ruts are replayed and change the picture, screenshot
#     contact two vehicles head-on recorded: a contact mark per vehicle, from the contact on
#     radar   tests/viewer/radar_scene.yaml recorded: the newest radar scan's detections drawn,
#             approaching blue and receding red; a malformed radar.csv named by line; the same
#             run distributed with a live viewer: the page's detections are the newest scan
#             radar.csv records
#     live    scm_crossing live with --view: ruts appear while it runs; vehicles.csv is
#             byte-identical to the single-process run
#     kill    the default scenario live: the viewer is killed (SIGKILL) while a browser watches;
#             the run completes with vehicles.csv byte-identical to the single-process run
#     origin  a replay viewer and a live one (no run): pages of another site (another port) and
#             of a name rebound to this machine open neither the WebSocket nor a run file; the
#             viewers' own pages work
set -euo pipefail
CASE=$1; OUT=$2
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BIN_DIR:-$ROOT/build/bin}
CHROMIUM=${SYNDDS_CHROMIUM:-/usr/bin/chromium}
[ -x "$CHROMIUM" ] || { echo "skipped: $CHROMIUM not installed"; exit 77; }
[ -d "$ROOT/services/viewer/web/node_modules/playwright-core" ] ||
  { echo "skipped: npm packages missing (launch_scripts/setup.sh)"; exit 77; }
mkdir -p "$OUT"
work=$(mktemp -d)
vpid=""; lvpid=""; bvpid=""
cleanup() {
  for p in $vpid $lvpid $bvpid; do kill "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
export SYNDDS_BUILD_DIR=$(dirname "$BIN")

# Waits (bounded) until file $1 is not empty.
wait_file() {
  for _ in $(seq 600); do [ -s "$1" ] && return 0; sleep 0.1; done
  echo "browser_tests: $1 never appeared" >&2; return 1
}
replay_viewer() {  # $1 run directory
  "$BIN/syndds_viewer" --replay "$1" --port 0 --url-file "$work/url" > "$work/viewer.log" 2>&1 &
  vpid=$!
  wait_file "$work/url"
}
single() {  # $1 scenario, $2 duration, $3 output
  "$BIN/syndds_sim" "$ROOT/config/scenarios/$1.yaml" --output "$3" --duration "$2" --quiet --log-level warn
}

case "$CASE" in
  replay)
    single default 10 "$work/run"
    replay_viewer "$work/run"
    node "$ROOT/tests/viewer/browser_tests.mjs" replay "$(cat "$work/url")" "$OUT/viewer_default.png"
    ;;
  contact)
    "$BIN/syndds_sim" "$ROOT/tests/multiprocess/scenarios/vehicle_contact_head_on.yaml" \
        --output "$work/run" --quiet --log-level warn
    replay_viewer "$work/run"
    node "$ROOT/tests/viewer/browser_tests.mjs" contact "$(cat "$work/url")" "$OUT/viewer_contact.png"
    ;;
  radar)
    "$BIN/syndds_sim" "$ROOT/tests/viewer/radar_scene.yaml" --output "$work/run" --quiet \
        --log-level warn
    replay_viewer "$work/run"
    # The same run with line 3 of radar.csv (its second detection) spoilt in world_y.
    cp -r "$work/run" "$work/bad"
    awk -F, -v OFS=, 'NR == 1 { for (k = 1; k <= NF; ++k) if ($k == "world_y") c = k }
                      NR == 3 { $c = "north" } { print }' "$work/run/radar.csv" > "$work/bad/radar.csv"
    "$BIN/syndds_viewer" --replay "$work/bad" --port 0 --url-file "$work/bad_url" \
        > "$work/bad_viewer.log" 2>&1 &
    bvpid=$!
    wait_file "$work/bad_url"
    node "$ROOT/tests/viewer/browser_tests.mjs" radar "$(cat "$work/url")" "$OUT/viewer_radar.png" \
        "$(cat "$work/bad_url")"
    # Live: a live viewer started before the run (it keeps serving after the run ended, so the
    # page may load at any time: no wall-clock race), the distributed run to its end, then the
    # page: the newest scan it draws is the one radar.csv records last.
    "$BIN/syndds_viewer" "$ROOT/tests/viewer/radar_scene.yaml" --run-id radar-live --port 0 \
        --url-file "$work/live_url" > "$work/live_viewer.log" 2>&1 &
    bvpid="$bvpid $!"
    wait_file "$work/live_url"
    "$ROOT/launch_scripts/run_scenario.sh" "$ROOT/tests/viewer/radar_scene.yaml" \
        --run-id radar-live --output "$work/live" > "$work/launcher.log" 2>&1 \
      || { cat "$work/launcher.log" >&2; exit 1; }
    node "$ROOT/tests/viewer/browser_tests.mjs" radarlive "$(cat "$work/live_url")" \
        "$work/live/radar.csv"
    ;;
  ruts)
    single scm_crossing 8 "$work/run"
    replay_viewer "$work/run"
    node "$ROOT/tests/viewer/browser_tests.mjs" ruts "$(cat "$work/url")" "$OUT/viewer_scm_crossing.png"
    ;;
  live)
    # The browser first (it opens the page once the launcher has written the viewer's address),
    # then the run.
    node "$ROOT/tests/viewer/browser_tests.mjs" live "$work/live/logs/viewer.url" \
        "$work/browser.ready" &
    bpid=$!
    wait_file "$work/browser.ready" || { wait "$bpid"; exit 1; }
    "$ROOT/launch_scripts/run_scenario.sh" "$ROOT/config/scenarios/scm_crossing.yaml" --duration 20 \
        --realtime --view --view-port 0 --output "$work/live" > "$work/launcher.log" 2>&1 &
    lpid=$!
    wait "$bpid" || { cat "$work/launcher.log" >&2; exit 1; }
    wait "$lpid" || { cat "$work/launcher.log" >&2; exit 1; }
    single scm_crossing 20 "$work/single"
    cmp "$work/live/vehicles.csv" "$work/single/vehicles.csv"
    cmp "$work/live/terrain_changes.csv" "$work/single/terrain_changes.csv"
    echo "browser_tests live: vehicles.csv and terrain_changes.csv byte-identical with the viewer watching"
    ;;
  kill)
    "$ROOT/launch_scripts/run_scenario.sh" "$ROOT/config/scenarios/default.yaml" --duration 12 \
        --realtime --view --view-port 0 --output "$work/live" > "$work/launcher.log" 2>&1 &
    lpid=$!
    wait_file "$work/live/logs/viewer.url"
    # In a session of its own: killing its process group kills this test's Chromium only.
    setsid node "$ROOT/tests/viewer/browser_tests.mjs" watch "$(cat "$work/live/logs/viewer.url")" sensors > "$work/browser.log" 2>&1 &
    bpid=$!
    for _ in $(seq 600); do grep -q watching "$work/browser.log" && break; sleep 0.1; done
    grep -q watching "$work/browser.log" || { cat "$work/browser.log" >&2; exit 1; }
    # Mid-run: the browser and then the viewer die without a word.
    kill -KILL -- "-$bpid"
    pkill -KILL -f "syndds_viewer .*$work/live" || true
    wait "$lpid" || { cat "$work/launcher.log" >&2; exit 1; }
    single default 12 "$work/single"
    cmp "$work/live/vehicles.csv" "$work/single/vehicles.csv"
    cmp "$work/live/commands.csv" "$work/single/commands.csv"
    echo "browser_tests kill: the run completed byte-identical after its viewer and browser were killed"
    ;;
  origin)
    single default 2 "$work/run"
    replay_viewer "$work/run"
    # Live without a run: it serves the page and the stream (the scene, an empty world).
    "$BIN/syndds_viewer" "$ROOT/config/scenarios/default.yaml" --run-id "origin-$$" --port 0 \
        --url-file "$work/live_url" > "$work/live_viewer.log" 2>&1 &
    lvpid=$!
    wait_file "$work/live_url"
    node "$ROOT/tests/viewer/browser_tests.mjs" origin "$(cat "$work/url")" "$(cat "$work/live_url")"
    # Refused by the viewers themselves (not only by the browser), and said so in their logs.
    grep -q "refused GET /run/vehicles.csv" "$work/viewer.log" ||
      { cat "$work/viewer.log" >&2; exit 1; }
    grep -q "refused GET /live" "$work/live_viewer.log" || { cat "$work/live_viewer.log" >&2; exit 1; }
    ;;
  *) echo "unknown case $CASE" >&2; exit 1 ;;
esac
echo "browser_tests $CASE: passed"
