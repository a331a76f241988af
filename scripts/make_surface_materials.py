#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The add-on's surface level (docs/decisions.md D44): for each preset, the far field of the add-on's Knitted Swatch
at its default shape (scripts/garment.py's flat knit: Crane's knit, yarn radius 0.5, 3 plies at ply twist 0.5)
measured with the preset's yarn-level model and fitted with stock closures, written as the material renderers
draw it: models/<preset>_surface_knit.json ("neuralyarn-cloth-surface 1", docs/file_formats.md), the patch's
pattern in it. The same fit as the evaluation harness's method `surface` (scripts/evaluate.py SURFACE_FIT).

    .venv/bin/python scripts/make_surface_materials.py [--presets fleece silk ...] [--out models]

About 8 s a preset on two cores. Deterministic (fixed seed; any thread count).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

from evaluate import CLI, PRESETS, SURFACE_FIT, yarn_model_path
from garment import ALPHA_YARN, PLIES_PER_YARN, flat_knit_plies

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
sys.path.insert(0, os.path.join(ROOT, "addon"))
import geometry  # noqa: E402  (addon/geometry: pure numpy)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--presets", nargs="+", default=PRESETS, choices=PRESETS)
    ap.add_argument("--out", default=os.path.join(ROOT, "models"))
    a = ap.parse_args()
    pattern = {**geometry.knit_pattern(), "plies": PLIES_PER_YARN, "ply_twist": ALPHA_YARN}
    # The files' "source" names the model and the patch relative to the checkout, as they are run from its root.
    work = os.path.join("build", "surface_materials")
    os.makedirs(os.path.join(ROOT, work), exist_ok=True)
    flat = os.path.join(work, "flat_knit.json")
    with open(os.path.join(ROOT, flat), "w") as f:
        json.dump(flat_knit_plies(SURFACE_FIT["rows"], SURFACE_FIT["stitches"]), f, separators=(",", ":"))
    with tempfile.TemporaryDirectory() as tmp:
        for preset in a.presets:
            out = os.path.abspath(os.path.join(a.out, f"{preset}_surface_knit.json"))
            model = os.path.relpath(yarn_model_path(preset), ROOT)
            r = subprocess.run([CLI, "surface", "--plies", flat, "--model", model, "--paths", SURFACE_FIT["paths"],
                                "--seed", str(SURFACE_FIT["seed"]), "--quiet", "--out", os.path.join(tmp, f"{preset}.json"),
                                "--material-out", out, "--pattern", json.dumps(pattern)],
                               capture_output=True, text=True, cwd=ROOT)
            if r.returncode != 0:
                print(f"make_surface_materials: {preset}: {r.stderr.strip()}", file=sys.stderr)
                return 1
            print(f"{preset}: wrote {out} ({r.stdout.splitlines()[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
