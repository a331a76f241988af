#!/usr/bin/env bash
# The evaluation harness (scripts/evaluate.py): renders the close-up per preset, light rig and method
# (explicit fibers, native neural closure) with the patched standalone Cycles and measures each against an
# explicit-fiber reference (mean colour error, HDR-FLIP, relMSE, SSIM, noise floor; time and memory).
#
#   bash scripts/evaluate.sh --quick --out build/eval_quick     # fleece, key-rim + grazing, 96x48 (~20 s)
#   bash scripts/evaluate.sh --out build/eval                   # all presets x rigs, 160x80, 64 spp vs 1024
#   bash scripts/evaluate.sh --help
#
# Writes DIR/results.json, DIR/summary.md, DIR/strips/*.png. Needs the build and .venv of scripts/setup.sh.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
PY="$ROOT/.venv/bin/python"
for tool in "$BUILD/cpp_core/neuralyarn" "$BUILD/cycles/bin/cycles"; do
  [ -x "$tool" ] || { echo "evaluate: error: $tool is not built (scripts/setup.sh builds it)" >&2; exit 1; }
done
[ -x /usr/bin/time ] || { echo "evaluate: error: /usr/bin/time is missing (apt-get install time)" >&2; exit 1; }
[ -x "$PY" ] || { echo "evaluate: error: $PY is missing (scripts/setup.sh makes .venv)" >&2; exit 1; }
"$PY" -c "import numpy, OpenEXR, flip_evaluator, skimage, matplotlib" 2>/dev/null || {
  echo "evaluate: error: .venv lacks numpy, OpenEXR, flip-evaluator, scikit-image or matplotlib (run scripts/setup.sh)" >&2
  exit 1
}
export NY_BUILD_DIR="$BUILD"
exec "$PY" "$ROOT/scripts/evaluate.py" "$@"
