#!/usr/bin/env bash
# The stability suite (scripts/stability.py, issue 19): every method swept over light directions, scale,
# scene units, samples, stacked cloth layers and fiber parameters, against explicit fibers; NaN/Inf/negative
# pixels, fireflies, furnace, bias and variance per cell, and a stability map.
#
#   bash scripts/stability.sh --quick --out build/stability_quick   # fleece, 64x32 (CI)
#   bash scripts/stability.sh --out build/stability                 # all presets and methods
#
# Writes DIR/results.json, DIR/summary.md and DIR/stability_map.png. Needs the build and .venv of scripts/setup.sh.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
PY="$ROOT/.venv/bin/python"
[ -x "$PY" ] || { echo "stability: error: $PY is missing (scripts/setup.sh makes .venv)" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "stability: error: /usr/bin/time is missing (apt-get install time)" >&2; exit 1; }
export NY_BUILD_DIR="$BUILD"
exec "$PY" "$ROOT/scripts/stability.py" "$@"
