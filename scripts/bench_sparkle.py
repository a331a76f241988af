# SPDX-License-Identifier: Apache-2.0
"""Garment-scale sparkle of a preset (issue 20, C11; issue 17's "no sparkle on garments"): a knit of 3-ply
yarns at 256 x 256 rendered with the native closure (patched Cycles, examples/make_examples.py's 4 x 4 knit)
and with both stock-Blender fallbacks (stock nodes and OSL, addon/batch.py's 6 x 6 knit), at 16 and 64 spp,
and the number of sparkle pixels in each: luminance above 10x the median of its 3 x 3 neighbourhood.

    .venv/bin/python scripts/bench_sparkle.py [--preset cotton] [--out build/sparkle]
        [--image docs/images/cotton_garment_scale.png]

The two scene builders differ (their knits and cameras): the counts compare rates, not pixels. With --eval, the
renders of one evaluate.sh run instead, where every method drew the same scene description (D37), compared pixel by
pixel: for each method and seed, the sparkle pixels that no native render of another seed has (issue 17's "no pixel
above 10x its 3 x 3 neighbourhood median that the native closure does not have"); a native seed against the other
native seeds is that count's noise floor. Run evaluate.sh with --seeds 3 or more:

    bash scripts/evaluate.sh --scenes garment --garment-stitches 10 --garment-size 256 256 --methods native osl nodes \
        --presets cotton --lights key-rim --spp 64 --seeds 3 --ref-spp 16 --ref-rotations 1 --out build/eval_sparkle
    .venv/bin/python scripts/bench_sparkle.py --eval build/eval_sparkle

A benchmark: prints, never a test.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from collections import defaultdict

import numpy as np

from images import LUMINANCE, display, exposure_of, read_exr
from showcase import ROOT, fallback_knit, native_knits, run


def sparkle_mask(img: np.ndarray) -> np.ndarray:
    """Pixels whose luminance is above 10x the median of their 3 x 3 neighbourhood."""
    from scipy.ndimage import median_filter
    lum = img[..., :3] @ LUMINANCE
    return lum > 10.0 * np.maximum(median_filter(lum, size=3), 1e-4)


def sparkles(img: np.ndarray) -> int:
    return int(sparkle_mask(img).sum())


def same_scene(eval_dir: str, image: str | None, also: list[str] | None = None) -> int:
    """The per-pixel comparison over an evaluate.sh run's renders (see the module's docstring); `image`: each
    group's seed-1 renders side by side, the sparkle pixels that no other native seed has in green; `also`:
    NAME=PATTERN, more renders of the run's scenes as a method NAME (PATTERN with {preset} and {seed})."""
    path = os.path.join(eval_dir, "results.json")
    if not os.path.isfile(path):
        raise SystemExit(f"bench_sparkle: {path} is missing (--eval takes the --out directory of an evaluate.sh run)")
    with open(path) as f:
        runs = json.load(f)["runs"]
    groups = defaultdict(lambda: defaultdict(dict))  # (scene, preset, light, distance, spp) -> method -> seed -> mask
    for r in runs:
        if r.get("failed") or not r.get("image"):
            continue
        key = (r["scene"], r["preset"], r["light"], r["distance"], r["spp"])
        img = read_exr(os.path.join(eval_dir, r["image"]))[..., :3]
        groups[key][r["method"]][r["seed"]] = (sparkle_mask(img), img)
    for spec in also or []:
        name, sep, pattern = spec.partition("=")
        if not sep or not name or "{seed}" not in pattern:
            raise SystemExit(f"bench_sparkle: --also {spec!r}: expected NAME=PATTERN with {{seed}} (and {{preset}})")
        for key, methods in groups.items():
            for seed in methods.get("native", {}):
                path = pattern.format(preset=key[1], seed=seed)
                if os.path.isfile(path):
                    img = read_exr(path)[..., :3]
                    methods[name][seed] = (sparkle_mask(img), img)
    print("| scene | preset | light | spp | method | seeds | sparkle pixels (mean) | of them in no native render of "
          "another seed (mean) | of those brighter than the native renders' 99th percentile (mean) | frame pixels |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    compared = 0
    panels = []
    for (scene, preset, light, distance, spp), methods in sorted(groups.items(), key=lambda kv: str(kv[0])):
        native = methods.get("native", {})
        if len(native) < 2:
            print(f"bench_sparkle: {scene} {preset} {light} {spp} spp: fewer than two native seeds, skipped "
                  "(evaluate.sh --seeds 3)", file=sys.stderr)
            continue
        row = []
        # What a viewer sees as glitter: an unmatched sparkle pixel as bright as the native image's brightest
        # lit pixels (most of the count sits in dim gaps, where 10x a dark median is still dark).
        lum = np.mean([img for _, img in native.values()], axis=0) @ LUMINANCE
        p99 = np.percentile(lum[lum > 1e-4], 99.0) if (lum > 1e-4).any() else 0.0
        for method, masks in methods.items():
            counts, new, bright = [], [], []
            for seed, (mask, img) in masks.items():
                seen = np.logical_or.reduce([m for s, (m, _) in native.items() if s != seed])
                counts.append(int(mask.sum()))
                new.append(int((mask & ~seen).sum()))
                bright.append(int((mask & ~seen & (img @ LUMINANCE > p99)).sum()))
                if seed == 1:
                    shown = display(img, exposure_of(img)).copy()
                    shown[mask & ~seen] = (0.0, 1.0, 0.0)
                    row.append((f"{preset} {method}: {new[-1]} of {counts[-1]}", shown))
            size = next(iter(masks.values()))[0].size
            print(f"| {scene} | {preset} | {light} | {spp} | {method} | {len(masks)} | {np.mean(counts):.0f} | "
                  f"{np.mean(new):.0f} | {np.mean(bright):.0f} | {size} |")
            compared += 1
        panels.append(row)
    if image and panels:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        cols = max(len(r) for r in panels)
        fig, axes = plt.subplots(len(panels), cols, figsize=(3 * cols, 3.1 * len(panels)), squeeze=False)
        for ax_row, row in zip(axes, panels):
            for ax in ax_row:
                ax.axis("off")
            for ax, (title, shown) in zip(ax_row, row):
                ax.imshow(shown)
                ax.set_title(title, fontsize=9)
        fig.tight_layout()
        fig.savefig(image, dpi=60)
    return 0 if compared else 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="cotton")
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "sparkle"))
    ap.add_argument("--image", help="write the six renders side by side here (PNG; with --eval, each group's seed-1 "
                                    "renders, the sparkle pixels no other native seed has in green)")
    ap.add_argument("--eval", metavar="DIR", help="compare the renders of this evaluate.sh run pixel by pixel instead")
    ap.add_argument("--also", nargs="+", metavar="NAME=PATTERN",
                    help="with --eval: more renders of the run's scenes as a method NAME, PATTERN a path with {preset} "
                         "and {seed} (e.g. a fallback re-rendered with other tables by fallback_render.py)")
    a = ap.parse_args()
    if a.eval:
        return same_scene(a.eval, a.image, a.also)
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
