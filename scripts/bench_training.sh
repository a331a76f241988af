#!/usr/bin/env bash
# Side-by-side training benchmark: our trainer vs PyTorch (CPU) on the same data, weights and schedule.
#   bash scripts/bench_training.sh MAPS.nyrdm [epochs] [widths]
# Needs python3-torch (`bash scripts/setup.sh --with-bench` installs it); not part of CI.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
MAPS="$1"; EPOCHS="${2:-5}"; WIDTHS="${3:-6-21-21-3}"
TMP="$(mktemp -d)"; trap 'rm -rf "$TMP"' EXIT
/usr/bin/python3 -c "import torch" 2>/dev/null || { echo "bench_training.sh: python3-torch is not installed (bash scripts/setup.sh --with-bench)" >&2; exit 1; }
"$BUILD/cpp_core/bench_train" --maps "$MAPS" --epochs "$EPOCHS" --widths "$WIDTHS" --threads 2 --export "$TMP"
/usr/bin/python3 "$ROOT/scripts/bench_torch_train.py" "$TMP" --threads 2
