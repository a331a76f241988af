#!/usr/bin/env bash
# The fixed costs of a bake (docs/benchmarks.md, "Fixed costs of a bake"): the M-lobe quadratures of the
# calibration's bound, the furnace and the fallback tables, and a small bake at the paper's map resolution,
# timed side by side for two builds of the CLI (e.g. a worktree of an earlier commit and this one), 2 threads.
# The output files of the two builds are compared too: the same but for their code version and timings, or
# the largest relative difference between them (a change in rounding).
#
#   bash scripts/bench_bake_fixed.sh OLD/cpp_core/neuralyarn build/cpp_core/neuralyarn
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [[ $# -ne 2 ]]; then
  echo "usage: $0 CLI_BEFORE CLI_AFTER" >&2
  exit 2
fi
OUT="$(mktemp -d)"
trap 'rm -rf "$OUT"' EXIT
seconds() {
  local t0
  t0=$(date +%s.%N)
  "$@" > "$OUT/log" 2>&1 || { cat "$OUT/log" >&2; exit 1; }
  python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$t0" "$(date +%s.%N)"
}
for which in before after; do
  cli=$1
  [[ $which == after ]] && cli=$2
  cp "$ROOT/models/silk.json" "$OUT/silk_$which.json"
  echo "$which: furnace silk --bound: $(seconds "$cli" furnace "$OUT/silk_$which.json" --bound --threads 2) s"
  echo "$which: furnace cotton --inside: $(seconds "$cli" furnace "$ROOT/models/cotton.json" --inside --threads 2) s"
  echo "$which: fallback cotton: $(seconds "$cli" fallback "$ROOT/models/cotton.json" --out "$OUT/fallback_$which.json" --threads 2) s"
  echo "$which: bake fleece 1e5 paths (check 1e5): $(seconds "$cli" bake --preset fleece --paths 1e5 --check-paths 1e5 --threads 2 --quiet --out "$OUT/bake_$which.json") s"
done
python3 - "$OUT" <<'PY'
import json, sys
out = sys.argv[1]
# Hashes (…fnv1a64) of arrays that are compared themselves are left out.
def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items()
                if k not in ("code_version", "created", "seconds", "gather_seconds") and not k.endswith("fnv1a64")}
    if isinstance(x, list):
        return [strip(v) for v in x]
    return x
def largest_relative_difference(a, b, path=""):
    """(difference, where) of the numbers that differ most; inf where the structure differs."""
    if isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys():
        return max((largest_relative_difference(a[k], b[k], f"{path}.{k}") for k in a), default=(0.0, path))
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return max((largest_relative_difference(x, y, f"{path}[{i}]") for i, (x, y) in enumerate(zip(a, b))),
                   default=(0.0, path))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return (0.0 if a == b else abs(a - b) / max(abs(a), abs(b)), path)
    return (0.0 if a == b else float("inf"), path)
for name in ("silk", "fallback", "bake"):
    a, b = (strip(json.load(open(f"{out}/{name}_{w}.json"))) for w in ("before", "after"))
    d, where = largest_relative_difference(a, b)
    print(f"{name}: " + ("same output" if d == 0 else f"outputs differ, most at {where}: relative {d:.2g}"))
PY
