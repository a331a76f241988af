# SPDX-License-Identifier: Apache-2.0
"""The native closure's near field (cycles_patch 0005, decisions D68): light that a ply passes through itself
leaves it further along. Two touching cotton plies crossed at 84 degrees under the back light, rendered by the
patched standalone Cycles with the shipped model and with the same model without its "near_field": where the
front ply lies in the back ply's shadow, it must glow (the far field alone leaves it at 4 % of explicit fibers
there; with the near field 84 %, docs/benchmarks.md "Light along the ply"). A lone ply must render pixel for
pixel as without it (every ray that leaves a ply skips the piece of tube it starts on, cycles_patch 0006, and a
straight ply has no other: moving the origin along it changes nothing), and no pixel may be non-finite or
negative.

    .venv/bin/python tests/cycles/near_field.py OUT_DIR

Exits 1 with the reason otherwise."""
from __future__ import annotations

import json
import os
import sys
import types

import cycles_check  # first: it puts scripts/ (evaluate, garment, images) on the path

import numpy as np

import evaluate as ev
from garment import crossed_plies
from images import LUMINANCE

WIDTH, HEIGHT, SPP = 160, 80, 64
#: The front ply over the back one at the camera's 12 ply radii (rows, columns of the 160 x 80 frame).
OVERLAP = (slice(35, 45), slice(74, 86))
#: Overlap luminance with the near field over without: measured 0.0196 / 0.0009 (about 20); the far field's own
#: light there (its T lobe through the back ply) is what the ratio stands on, so 4 leaves room for its noise.
MIN_GAIN = 4.0


def plies_file(path: str, angles: list[float]) -> str:
    """Straight plies 48.7 ply radii long, each behind the one before and touching it (garment.crossed_plies)."""
    with open(path, "w") as f:
        json.dump(crossed_plies(angles, 48.7), f)
    return path


def main(out: str) -> int:
    os.makedirs(out, exist_ok=True)
    shipped = os.path.join(ev.MODELS, "cotton.json")
    model = json.load(open(shipped))
    if "near_field" not in model:
        print("near_field: the shipped cotton model has no 'near_field'", file=sys.stderr)
        return 1
    far = os.path.join(out, "cotton_far_field.json")
    with open(far, "w") as f:
        json.dump({k: v for k, v in model.items() if k != "near_field"}, f)
    a = types.SimpleNamespace(width=WIDTH, height=HEIGHT, threads=2, timeout=600.0)
    images = {}
    for scene, angles in (("crossed", [0.0, 84.0]), ("lone", [0.0])):
        plies = plies_file(os.path.join(out, f"{scene}.json"), angles)
        for name, path in (("near", shipped), ("far", far)):
            images[scene, name] = ev.render_image(
                a, ["--preset", "cotton", "--model", path, "--plies", plies, "--lights", "back", "--width", str(WIDTH),
                    "--height", str(HEIGHT), "--seed", "1"], os.path.join(out, f"{scene}_{name}"), SPP, finite=False)
    for key, img in images.items():
        if not np.isfinite(img).all() or (img < 0).any():
            print(f"near_field: non-finite or negative pixels in {key}", file=sys.stderr)
            return 1
    lum = {k: float((img[OVERLAP] @ LUMINANCE).mean()) for k, img in images.items() if k[0] == "crossed"}
    gain = lum["crossed", "near"] / max(lum["crossed", "far"], 1e-12)
    lone = float(np.abs(images["lone", "near"] - images["lone", "far"]).max())
    print(f"near_field: overlap luminance {lum['crossed', 'near']:.5f} with, {lum['crossed', 'far']:.5f} without "
          f"the near field (x{gain:.1f}); lone ply's largest pixel difference {lone:g}")
    if not gain >= MIN_GAIN:
        print(f"near_field: the shadowed ply gains x{gain:.2f} < x{MIN_GAIN}: the near field does not reach the "
              "renderer", file=sys.stderr)
        return 1
    if lone != 0.0:
        print("near_field: a lone ply renders differently with the near field", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    cycles_check.run(main, __doc__)
