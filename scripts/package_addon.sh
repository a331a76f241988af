#!/usr/bin/env bash
# Builds the installable add-on: addon/ plus the shipped models (models/*.json: ply and yarn level and the surface
# level's knit material, three per preset)
# and the preset list (cpp_core/data/presets.json), which live outside addon/, staged as one package, validated
# with Blender's own extension tool (what `blender --command extension validate|build` runs) and zipped.
#
#   bash scripts/package_addon.sh [OUT_DIR]     # default: build/addon
#
# Writes OUT_DIR/neural_yarn-0.1.0.zip (extension: files at the zip's top) and
# OUT_DIR/neural_yarn-0.1.0-legacy.zip (the same files in a neural_yarn/ folder, as legacy add-ons are zipped).
# Install: Blender 4.2+: Edit > Preferences > Get Extensions > Install from Disk (the extension zip);
#          Blender 3.4-4.1: Preferences > Add-ons > Install (the legacy zip; bl_info is read).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:-$ROOT/build/addon}"
PY="$ROOT/.venv/bin/python"
[[ -x "$PY" ]] || { echo "package_addon: $PY is missing; run scripts/setup.sh first" >&2; exit 1; }
BLENDER_EXT="$("$PY" - <<'PYEOF'
import os, bpy  # the bpy wheel ships Blender's scripts, including the extension tool
path = os.path.join(bpy.utils.system_resource("SCRIPTS"), "addons_core", "bl_pkg", "cli", "blender_ext.py")
print(path if os.path.isfile(path) else "")
PYEOF
)"
[[ -n "$BLENDER_EXT" ]] || { echo "package_addon: blender_ext.py not found in the bpy wheel" >&2; exit 1; }

STAGE="$OUT/neural_yarn"
rm -rf "$STAGE"
mkdir -p "$STAGE/models"
# Sources only: no caches, no test output.
tar -C "$ROOT/addon" --exclude='__pycache__' --exclude='*.pyc' -cf - . | tar -C "$STAGE" -xf -
cp "$ROOT/cpp_core/data/presets.json" "$STAGE/"
mapfile -t PRESETS < <("$PY" -c 'import json, sys; print("\n".join(json.load(open(sys.argv[1]))["presets"]))' \
                       "$ROOT/cpp_core/data/presets.json")
for p in "${PRESETS[@]}"; do
  cp "$ROOT/models/$p.json" "$ROOT/models/${p}_yarn.json" "$ROOT/models/${p}_surface_knit.json" "$STAGE/models/"
done
cp "$ROOT/LICENSE" "$STAGE/" 2>/dev/null || true

"$PY" "$BLENDER_EXT" validate "$STAGE"
"$PY" "$BLENDER_EXT" build --source-dir "$STAGE" --output-dir "$OUT"
VERSION="$(sed -n 's/^version = "\(.*\)"/\1/p' "$STAGE/blender_manifest.toml")"
"$PY" - "$STAGE" "$OUT/neural_yarn-$VERSION-legacy.zip" <<'PYEOF'
import os, sys, zipfile
stage, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
    for d, _, files in sorted(os.walk(stage)):
        for f in sorted(files):
            path = os.path.join(d, f)
            z.write(path, os.path.join("neural_yarn", os.path.relpath(path, stage)))
PYEOF
ls -l "$OUT"/neural_yarn-*.zip
