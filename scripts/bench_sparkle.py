# SPDX-License-Identifier: Apache-2.0
"""Garment-scale sparkle of a preset (issue 20, C11; issue 17's "no sparkle on garments"): a knit of 3-ply
yarns at 256 x 256 rendered with the native closure (patched Cycles, examples/make_examples.py's 4 x 4 knit)
and with both stock-Blender fallbacks (stock nodes and OSL, addon/batch.py's 6 x 6 knit), at 16 and 64 spp,
and the number of sparkle pixels in each: luminance above 10x the median of its 3 x 3 neighbourhood.

    .venv/bin/python scripts/bench_sparkle.py [--preset cotton] [--out build/sparkle]
        [--image docs/images/cotton_garment_scale.png]

The two scene builders differ (their knits and cameras): the counts compare rates, not pixels; an exact
per-pixel comparison needs one scene for both renderers (issue 16). A benchmark: prints, never a test.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from images import LUMINANCE, display, exposure_of, read_exr
from showcase import ROOT, fallback_knit, native_knits, run


def sparkles(img: np.ndarray) -> int:
    from scipy.ndimage import median_filter
    lum = img @ LUMINANCE
    return int((lum > 10.0 * np.maximum(median_filter(lum, size=3), 1e-4)).sum())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="cotton")
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "sparkle"))
    ap.add_argument("--image", help="write the six renders side by side here (PNG)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    panels = []
    for spp in (16, 64):
        native = os.path.join(a.out, f"native{spp}")
        run(native_knits(native, [a.preset], spp, 256), f"native, {spp} spp", "bench_sparkle")
        paths = [("native", os.path.join(native, f"knit_{a.preset}.exr"))]
        for fb in ("nodes", "osl"):
            path = os.path.join(a.out, f"{a.preset}_{fb}_{spp}.exr")
            run(fallback_knit(a.preset, fb, spp, 256, path), f"{fb}, {spp} spp", "bench_sparkle")
            paths.append(("stock nodes" if fb == "nodes" else "OSL", path))
        for name, path in paths:
            img = read_exr(path)
            n = sparkles(img)
            print(f"{a.preset} {name:11} {spp:3d} spp: {n:4d} sparkle pixels of {img.shape[0] * img.shape[1]} "
                  f"({100.0 * n / (img.shape[0] * img.shape[1]):.2f} %)", flush=True)
            panels.append((f"{name}, {spp} spp: {n} sparkles", img))
    if a.image:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(2, 3, figsize=(9, 6.3))
        for ax, (title, img) in zip(axes.ravel(), panels):
            ax.imshow(display(img, exposure_of(img)))
            ax.set_title(title, fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
        fig.tight_layout()
        fig.savefig(a.image, dpi=90)
    return 0


if __name__ == "__main__":
    sys.exit(main())
