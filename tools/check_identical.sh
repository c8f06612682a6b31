#!/usr/bin/env bash
# Hashes the recorded outputs of every shipped scenario (config/scenarios/**.yaml), run in one
# process for a short duration, so that two builds can be compared file by file:
#
#   tools/check_identical.sh BIN_DIR OUT.txt [--duration S] [--only PATTERN]
#   diff before.txt after.txt      # empty: the refactor changed no result
#
# Hashed: every file of the run directory that docs/outputs.md calls byte-identical (CSV files,
# terrain images and their scale, convoy.json, metrics.json, videos); summary.json/txt hold
# wall times and are left out. A file's copy of the run directory's path is not part of its hash.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
[ $# -ge 2 ] || { sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 1; }
BIN=$1; OUT=$2; shift 2
DURATION=10; ONLY=""
while [ $# -gt 0 ]; do
  case "$1" in
    --duration) DURATION=$2; shift ;;
    --only) ONLY=$2; shift ;;
    *) echo "check_identical: unknown option $1" >&2; exit 1 ;;
  esac
  shift
done
[ -x "$BIN/syndds_sim" ] || { echo "check_identical: $BIN/syndds_sim not found" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
: > "$OUT"
while IFS= read -r scenario; do
  rel=${scenario#"$ROOT"/}
  [ -z "$ONLY" ] || [[ "$rel" == *$ONLY* ]] || continue
  dir="$work/$(echo "$rel" | tr '/' '_')"
  if ! "$BIN/syndds_sim" "$scenario" --output "$dir" --run-id check --duration "$DURATION" \
        --config-dir "$ROOT/config" --quiet --log-level warn > "$dir.log" 2>&1; then
    echo "check_identical: $rel failed (log below)" >&2; cat "$dir.log" >&2; exit 2
  fi
  (cd "$dir" && find . -type f \( -name '*.csv' -o -name '*.png' -o -name 'terrain_images.json' -o -name 'scene.json' \
      -o -name 'convoy.json' -o -name 'metrics.json' -o -name '*.avi' \) | LC_ALL=C sort | while IFS= read -r f; do
     # terrain_images.json names its images by path: the run directory's own path is not a result
     echo "$rel ${f#./} $(sed "s#$dir/##g" "$f" | sha256sum | cut -c1-16)"; done) >> "$OUT"
  echo "check_identical: $rel done" >&2
done < <(find "$ROOT/config/scenarios" -name '*.yaml' | LC_ALL=C sort)
