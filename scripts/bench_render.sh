#!/usr/bin/env bash
# Render benchmark of the patched Cycles: the single-ply close-up of each preset, explicit fibers
# (khungurn_fiber_bsdf on every fiber curve) against the aggregated model (one thick curve, neural_yarn_bsdf),
# at equal samples: wall time and peak RSS of the `cycles` process, curve geometry size, and SSIM of both
# against a converged explicit-fiber reference (scripts/bench_render.py with .venv).
#
#   bash scripts/bench_render.sh                       # all presets, 320x160, 64 spp, reference 1024 spp
#   NY_SPP=16 NY_REF_SPP=256 bash scripts/bench_render.sh fleece
#
# Not part of CI (the references take minutes per preset). Writes build/bench_render/<preset>_*.exr|png and
# prints one table row per preset.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
CLI="$BUILD/cpp_core/neuralyarn"
CYCLES="$BUILD/cycles/bin/cycles"
OUT="$BUILD/bench_render"
W="${NY_WIDTH:-320}"; H="${NY_HEIGHT:-160}"; SPP="${NY_SPP:-64}"; REF_SPP="${NY_REF_SPP:-1024}"
THREADS="${NY_THREADS:-2}"
for tool in "$CLI" "$CYCLES"; do
  [ -x "$tool" ] || { echo "bench_render.sh: $tool not built (scripts/setup.sh builds both)" >&2; exit 1; }
done
command -v oiiotool > /dev/null || { echo "bench_render.sh: oiiotool missing (apt-get install openimageio-tools)" >&2; exit 1; }
VENV="$ROOT/.venv" # scikit-image and OpenEXR come from scripts/setup.sh
"$VENV/bin/python" -c "import skimage, OpenEXR" 2>/dev/null || \
  { echo "bench_render.sh: $VENV lacks scikit-image or OpenEXR; run scripts/setup.sh" >&2; exit 1; }
PRESETS=("$@")
[ ${#PRESETS[@]} -gt 0 ] || mapfile -t PRESETS < <("$CLI" presets | cut -d" " -f1)  # the core's preset list
mkdir -p "$OUT"

render() { # scene spp image -> prints "seconds peak_kb"
  /usr/bin/time -f "%e %M" -o "$OUT/time.txt" \
    "$CYCLES" --background --quiet --samples "$2" --threads "$THREADS" --width "$W" --height "$H" \
    --output "$3" "$1" > /dev/null
  cat "$OUT/time.txt"
}

echo "# ${W}x${H}, $SPP spp (reference: explicit fibers, $REF_SPP spp), $THREADS threads, $(nproc) cores: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
echo "# preset | explicit s | aggregated s | speed-up | explicit peak MB | aggregated peak MB | explicit curve keys | aggregated curve keys | SSIM explicit@spp | SSIM aggregated@spp | mean rel. difference aggregated/reference"
for p in "${PRESETS[@]}"; do
  "$CLI" cycles-scene --preset "$p" --width "$W" --height "$H" --out "$OUT/${p}_fibers.xml" > /dev/null
  "$CLI" cycles-scene --preset "$p" --model "$ROOT/models/$p.json" --width "$W" --height "$H" \
    --out "$OUT/${p}_yarn.xml" > /dev/null
  ref="$OUT/${p}_reference.exr"
  [ -f "$ref" ] || render "$OUT/${p}_fibers.xml" "$REF_SPP" "$ref" > /dev/null
  read -r t_f m_f < <(render "$OUT/${p}_fibers.xml" "$SPP" "$OUT/${p}_fibers.exr")
  read -r t_y m_y < <(render "$OUT/${p}_yarn.xml" "$SPP" "$OUT/${p}_yarn.exr")
  keys_f=$(grep -o 'P="[^"]*"' "$OUT/${p}_fibers.xml" | wc -w)
  keys_y=$(grep -o 'P="[^"]*"' "$OUT/${p}_yarn.xml" | wc -w)
  read -r s_f s_y d_y < <("$VENV/bin/python" "$ROOT/scripts/bench_render.py" "$ref" "$OUT/${p}_fibers.exr" \
    "$OUT/${p}_yarn.exr" --png "$OUT/${p}_compare.png")
  awk -v p="$p" -v tf="$t_f" -v ty="$t_y" -v mf="$m_f" -v my="$m_y" -v kf="$keys_f" -v ky="$keys_y" \
      -v sf="$s_f" -v sy="$s_y" -v dy="$d_y" \
      'BEGIN { printf "| %s | %.1f | %.1f | %.1fx | %.0f | %.0f | %d | %d | %s | %s | %s |\n", p, tf, ty, tf / ty, mf / 1024, my / 1024, kf / 3, ky / 3, sf, sy, dy }'
done

# The neural closure against Cycles' Principled Hair (Chiang) on the same curve, same samples: render time.
echo
HAIR_SPP="${NY_HAIR_SPP:-1024}"  # enough samples that start-up (~0.3 s) does not dominate
echo "# neural yarn closure vs Principled Hair (Chiang, direct colouring) on the aggregated curve, ${W}x${H}, $HAIR_SPP spp"
echo "# preset | neural s | Chiang s | ratio"
for p in "${PRESETS[@]}"; do
  sed 's|<neural_yarn_bsdf name="y" model="[^"]*" />|<principled_hair_bsdf name="y" model="Chiang" parametrization="Direct coloring" color="0.6 0.3 0.2" />|' \
    "$OUT/${p}_yarn.xml" > "$OUT/${p}_chiang.xml"
  grep -q principled_hair_bsdf "$OUT/${p}_chiang.xml" || { echo "bench_render.sh: could not make the Chiang scene" >&2; exit 1; }
  read -r t_y _ < <(render "$OUT/${p}_yarn.xml" "$HAIR_SPP" "$OUT/${p}_yarn2.exr")
  read -r t_c _ < <(render "$OUT/${p}_chiang.xml" "$HAIR_SPP" "$OUT/${p}_chiang.exr")
  awk -v p="$p" -v ty="$t_y" -v tc="$t_c" 'BEGIN { printf "| %s | %.2f | %.2f | %.2f |\n", p, ty, tc, ty / tc }'
done
