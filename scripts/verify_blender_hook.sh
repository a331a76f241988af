#!/usr/bin/env bash
# End-to-end check of the Blender-side hook (cycles_patch 0003) with the full patched Blender
# (scripts/build_blender.sh): one .blend, made with the add-on's Neural Yarn BSDF node, renders with the
# native closure in the patched Blender and with the node's fallback in stock Blender (the bpy 4.5 wheel).
#
#   bash scripts/verify_blender_hook.sh [preset]      # default silk; NY_SPP (default 128)
#
# Per preset: the close-up XML scene rendered by the patched standalone Cycles (native closure: the
# reference); the same scene (its description) built in the patched Blender by scripts/fallback_render.py and saved as a
# .blend (models packed), rendered there; the .blend reopened and rendered by the bpy 4.5 wheel. Prints
# SSIM and mean colour difference of both Blender renders against the standalone one: the patched Blender
# must match it (same closure code; goal SSIM >= 0.98, mean within 2 %), the stock one shows the fallback.
# The scene is also built with Blender's built-in Neural Yarn BSDF node instead of the add-on's
# (fallback_render.py --node builtin): the same closure from the same packed model, so its render must
# equal the add-on node's to float rounding (largest pixel difference <= 1e-5).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
BLENDER="${NY_PATCHED_BLENDER:-$BUILD/blender-full/blender}"
CLI="$BUILD/cpp_core/neuralyarn"; CYCLES="$BUILD/cycles/bin/cycles"; PY="$ROOT/.venv/bin/python"
P="${1:-silk}"; SPP="${NY_SPP:-128}"; W=320; H=160
OUT="$BUILD/verify_hook"; mkdir -p "$OUT"
for tool in "$BLENDER" "$CLI" "$CYCLES" "$PY"; do
  [ -x "$tool" ] || { echo "verify_blender_hook: $tool missing (build_blender.sh / setup.sh)" >&2; exit 1; }
done
"$PY" -c "import skimage, OpenEXR" 2>/dev/null || "$PY" -m pip install -q scikit-image "OpenEXR>=3.3"
"$CLI" cycles-scene --preset "$P" --model "$ROOT/models/$P.json" --width $W --height $H --out "$OUT/$P.xml" \
  --out "$OUT/$P.json" > /dev/null
"$CYCLES" --background --quiet --samples "$SPP" --threads 0 --width $W --height $H --output "$OUT/${P}_standalone.exr" \
  "$OUT/$P.xml" > /dev/null
rm -f "$OUT/$P.blend"
"$BLENDER" -b --factory-startup --python-exit-code 1 -P "$ROOT/scripts/fallback_render.py" -- "$OUT/$P.json" \
  "$OUT/${P}_patched.exr" --body nodes --samples "$SPP" --save-blend "$OUT/$P.blend" \
  > "$OUT/${P}_patched.log" 2>&1 || { cat "$OUT/${P}_patched.log" >&2; exit 1; }
grep "fallback_render: Blender" "$OUT/${P}_patched.log"
"$BLENDER" -b --factory-startup --python-exit-code 1 -P "$ROOT/scripts/fallback_render.py" -- "$OUT/$P.json" \
  "$OUT/${P}_builtin.exr" --node builtin --samples "$SPP" > "$OUT/${P}_builtin.log" 2>&1 ||
  { cat "$OUT/${P}_builtin.log" >&2; exit 1; }
if grep -i "neural yarn model.*:" "$OUT/${P}_patched.log" "$OUT/${P}_builtin.log"; then
  echo "verify_blender_hook: the closure reported a model problem" >&2; exit 1
fi
"$PY" "$ROOT/scripts/fallback_render.py" "$OUT/$P.blend" "$OUT/${P}_stock.exr" --open-blend \
  > "$OUT/${P}_stock.log" 2>&1 || { cat "$OUT/${P}_stock.log" >&2; exit 1; }
grep "fallback_render: Blender" "$OUT/${P}_stock.log"
read -r s_p s_s d_s < <("$PY" "$ROOT/scripts/bench_render.py" "$OUT/${P}_standalone.exr" "$OUT/${P}_patched.exr" \
  "$OUT/${P}_stock.exr" --png "$OUT/${P}_compare.png")
read -r _ _ d_p < <("$PY" "$ROOT/scripts/bench_render.py" "$OUT/${P}_standalone.exr" "$OUT/${P}_stock.exr" \
  "$OUT/${P}_patched.exr")
echo "| $P | patched Blender: SSIM $s_p, mean diff $d_p | stock Blender 4.5 (fallback): SSIM $s_s, mean diff $d_s |"
read -r _ _ _ d_max < <("$PY" "$ROOT/scripts/bench_render.py" "$OUT/${P}_standalone.exr" "$OUT/${P}_patched.exr" \
  "$OUT/${P}_builtin.exr" --largest-difference)
echo "built-in node vs add-on node, patched Blender: largest pixel difference $d_max"
awk -v d="$d_max" 'BEGIN { exit !(d <= 1e-5) }' ||
  { echo "verify_blender_hook: the built-in node does not render as the add-on's node" >&2; exit 1; }
awk -v s="$s_p" -v d="$d_p" 'BEGIN { exit !(s >= 0.98 && d <= 0.02) }' ||
  { echo "verify_blender_hook: the patched Blender does not render the native closure" >&2; exit 1; }
echo "verify_blender_hook: ok"
