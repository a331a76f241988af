#!/usr/bin/env bash
# Fidelity of the stock-Blender fallbacks (issue 6): the single-ply close-up of each preset rendered by the
# patched standalone Cycles with the native neural yarn closure, and by Blender (the bpy 4.5 wheel) with the
# add-on's OSL fallback and its stock-node fallback on the same scene (one `cycles-scene` call writes it as
# Cycles XML and as the description that the add-on's Blender builder reads: scripts/fallback_render.py); SSIM of each fallback against the native image (scripts/bench_render.py:
# display images, reference exposure). First a scene-equivalence check: the same curve with a grey diffuse
# BSDF in both renderers must agree (mean within a few %, SSIM ~1), else the comparison means nothing.
#
#   bash scripts/bench_fallback.sh                    # all presets, 320x160, 256 spp
#   NY_SPP=64 bash scripts/bench_fallback.sh silk
#
# Not part of CI. Writes build/bench_fallback/*.exr and a compare PNG per preset (native | OSL | nodes).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
CLI="$BUILD/cpp_core/neuralyarn"
CYCLES="$BUILD/cycles/bin/cycles"
PY="$ROOT/.venv/bin/python"
OUT="$BUILD/bench_fallback"
W="${NY_WIDTH:-320}"; H="${NY_HEIGHT:-160}"; SPP="${NY_SPP:-256}"
for tool in "$CLI" "$CYCLES" "$PY"; do
  [ -x "$tool" ] || { echo "bench_fallback.sh: $tool missing (scripts/setup.sh makes it)" >&2; exit 1; }
done
"$PY" -c "import skimage, OpenEXR" 2>/dev/null || "$PY" -m pip install -q scikit-image "OpenEXR>=3.3"
PRESETS=("$@")
[ ${#PRESETS[@]} -gt 0 ] || mapfile -t PRESETS < <("$CLI" presets | cut -d" " -f1)  # the core's preset list
mkdir -p "$OUT"
native() { "$CYCLES" --background --quiet --samples "$SPP" --threads 0 --width "$W" --height "$H" --output "$2" "$1" > /dev/null; }
blender() { "$PY" "$ROOT/scripts/fallback_render.py" "$1" "$2" --body "$3" --samples "$SPP" > /dev/null; }

# Scene equivalence: a grey diffuse curve in both renderers.
"$CLI" cycles-scene --preset fleece --diffuse --width "$W" --height "$H" --out "$OUT/diffuse.xml" \
  --out "$OUT/diffuse.json" > /dev/null
native "$OUT/diffuse.xml" "$OUT/diffuse_native.exr"
blender "$OUT/diffuse.json" "$OUT/diffuse_blender.exr" nodes
read -r s_d _ d_d < <("$PY" "$ROOT/scripts/bench_render.py" "$OUT/diffuse_native.exr" "$OUT/diffuse_blender.exr" \
  "$OUT/diffuse_blender.exr")
echo "# scene equivalence (grey diffuse curve): SSIM Blender vs standalone $s_d, mean colour difference $d_d"
echo "# ${W}x${H}, $SPP spp, $(nproc) cores: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
echo "| preset | SSIM OSL | SSIM nodes | mean diff. OSL | mean diff. nodes |"
echo "|---|---|---|---|---|"
for p in "${PRESETS[@]}"; do
  "$CLI" cycles-scene --preset "$p" --model "$ROOT/models/$p.json" --width "$W" --height "$H" \
    --out "$OUT/${p}.xml" --out "$OUT/${p}.json" > /dev/null
  native "$OUT/${p}.xml" "$OUT/${p}_native.exr"
  blender "$OUT/${p}.json" "$OUT/${p}_osl.exr" osl
  blender "$OUT/${p}.json" "$OUT/${p}_nodes.exr" nodes
  read -r s_o s_n d_n < <("$PY" "$ROOT/scripts/bench_render.py" "$OUT/${p}_native.exr" "$OUT/${p}_osl.exr" \
    "$OUT/${p}_nodes.exr" --png "$OUT/${p}_compare.png")
  read -r _ _ d_o < <("$PY" "$ROOT/scripts/bench_render.py" "$OUT/${p}_native.exr" "$OUT/${p}_nodes.exr" \
    "$OUT/${p}_osl.exr")
  echo "| $p | $s_o | $s_n | $d_o | $d_n |"
done
