#!/usr/bin/env bash
# The shipped models' lobes against two independent maps per preset (the 4D lobe measure of
# `neuralyarn check --maps-b`, model/lobe_fidelity.h): one summary row per preset, and the full per-theta_i
# tables in build/bench_lobes/<preset>.txt.
#
#   bash scripts/bench_lobes.sh                          # all five, maps of 2e7 paths (seeds 3001, 3002)
#   NY_MODELS=/path/to/old/models bash scripts/bench_lobes.sh silk
#
# Not part of CI (the maps take ~1 min per preset and seed; they are kept in build/bench_lobes/).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${NY_BUILD_DIR:-$ROOT/build}"
CLI="$BUILD/cpp_core/neuralyarn"
MODELS="${NY_MODELS:-$ROOT/models}"
PATHS="${NY_PATHS:-2e7}"
OUT="$BUILD/bench_lobes"
[ -x "$CLI" ] || { echo "bench_lobes.sh: $CLI not built; run scripts/setup.sh --no-run first" >&2; exit 1; }
PRESETS=("$@")
[ ${#PRESETS[@]} -gt 0 ] || mapfile -t PRESETS < <("$CLI" presets | cut -d" " -f1)  # the core's preset list
mkdir -p "$OUT"
model_layouts() { python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["provenance"]["maps"].get("layouts", 1))' "$1"; }
echo "# models: $MODELS; maps: $PATHS paths, seeds 3001 and 3002, each model's own cross-sections, paper resolution; $(nproc) cores: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
echo "# L1: energy-weighted relative L1 per 12-degree (w_i, w_o) cell with the maps' noise removed, in %;"
echo "# 'mean' over the theta_i bins, 'worst' over all but the grazing one, then the grazing bin;"
echo "# band ratios model/maps at theta_i = 2 deg: R exits 0-30 deg from the normal, M exits 150-180 deg"
echo "# preset | R L1 mean | R L1 worst | R L1 grazing | M L1 mean | M L1 worst | M L1 grazing | noise floor R / M (mean) | R 0-30 | M 150-180"
for p in "${PRESETS[@]}"; do
  # The model's own cross-sections (its provenance; D42): the maps are independent draws of the ply it was baked on.
  LAYOUTS=$(model_layouts "$MODELS/$p.json")
  for s in 3001 3002; do
    [ -f "$OUT/${p}_${s}_L$LAYOUTS.nyrdm" ] || "$CLI" gather --preset "$p" --paths "$PATHS" --seed "$s" \
      --layouts "$LAYOUTS" --quiet --out "$OUT/${p}_${s}_L$LAYOUTS.nyrdm" > /dev/null
  done
  "$CLI" check "$MODELS/$p.json" --maps "$OUT/${p}_3001_L$LAYOUTS.nyrdm" --maps-b "$OUT/${p}_3002_L$LAYOUTS.nyrdm" \
    > "$OUT/$p.txt"
  # Rows of the lobe table: "theta | R l1 % (raw, floor) | M l1 % (raw, floor) | R bands | M bands".
  awk -v p="$p" -F'|' '
    /^  +[0-9.]+ +\|/ {
      n++; split($2, r, /[ (),%]+/); split($3, m, /[ (),%]+/); split($4, rb, " "); split($5, mb, " ");
      rl[n] = r[2]; rf += r[4]; ml[n] = m[2]; mf += m[4];
      if (n == 1) { r030 = rb[1]; m150 = mb[6] }
    }
    END {
      for (i = 1; i <= n; i++) { rs += rl[i]; ms += ml[i]; if (i < n) { if (rl[i] > rw) rw = rl[i]; if (ml[i] > mw) mw = ml[i] } }
      printf "| %s | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f / %.1f | %s | %s |\n", p, rs / n, rw, rl[n], ms / n, mw, ml[n], rf / n, mf / n, r030, m150
    }' "$OUT/$p.txt"
done
