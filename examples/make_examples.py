#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Writes the reference scenes for the patched standalone Cycles (and renders them with --render).

    .venv/bin/python examples/make_examples.py [--out build/examples] [--render] [--samples 64] [--presets ...]

Per preset (the paper's single-yarn close-up: a straight ply across the frame, a perspective camera, two
sphere lights, one in front and one behind for the transmission), from the same geometry and fiber
packing seed:
    <out>/<preset>_fibers.xml   explicit fibers (khungurn_fiber_bsdf on every fiber curve; the reference)
    <out>/<preset>_yarn.xml     aggregated (one thick curve of the ply's radius, neural_yarn_bsdf)
and two small patches of aggregated plies:
    <out>/knit_<preset>.xml     a 4 x 4 plain knit (Crane's loop curve) of 3-ply yarns
    <out>/twill_<preset>.xml    a 6 x 6 twill of 3-ply yarns
(with --explicit-patches also their explicit fibers, <out>/knit_<preset>_fibers.xml, ...), the patches' ply
curves made by the Blender add-on's own geometry package (addon/geometry: the curves the add-on gives Blender;
scripts/garment.py patch_plies) and written once as plies files (<out>/knit_plies.json, twill_plies.json), as the
evaluation harness's scenes `knit` and `twill` are. Every scene is written by
`neuralyarn cycles-scene` (the close-up's light rig, moved out with the camera for the patches); each
aggregated one also as its description (<out>/<name>.json), which Blender renders through the add-on
(scripts/fallback_render.py). Model paths in the scenes are relative to the scene file, so <out> can be moved
together with a models/ copy. With --render each scene is rendered to <out>/<name>.png (and .exr)
with build/cycles/bin/cycles; everything is seeded, so the images are reproducible.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
sys.path.insert(0, os.path.join(ROOT, "addon"))
from resources import PRESETS  # noqa: E402  (addon/resources.py: the core's preset list)
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from evaluate import patch_scene_args  # noqa: E402  (the patches as the evaluation harness draws them)
from garment import PATCHES  # noqa: E402


def run(cmd: list[str]) -> str:
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"make_examples: {' '.join(cmd)} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    return r.stdout


def check_image(exr: str) -> float:
    """Fails unless the image has no NaN/Inf and a mean RGB above 1e-4; returns the mean."""
    stats = run(["oiiotool", "--stats", exr])
    for key in ("NanCount", "InfCount"):
        m = re.search(key + r": ([0-9 ]+)", stats)
        if m is None or any(int(v) for v in m.group(1).split()):
            raise SystemExit(f"make_examples: {exr}: {key} {m.group(1) if m else '?'}")
    m = re.search(r"Avg: ([-0-9.eE+ ]+)", stats)
    mean = sum(float(v) for v in m.group(1).split()[:3]) / 3.0 if m else 0.0
    if not mean > 1e-4:
        raise SystemExit(f"make_examples: {exr} is black (mean {mean:g})")
    return mean


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "examples"))
    ap.add_argument("--presets", nargs="+", default=PRESETS, choices=PRESETS)
    ap.add_argument("--scenes", nargs="+", default=["closeup", *PATCHES], choices=["closeup", *PATCHES],
                    help="which scenes to write (default all)")
    ap.add_argument("--render", action="store_true", help="render every scene with build/cycles/bin/cycles")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=160)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--explicit-patches", action="store_true",
                    help="also write knit/twill patches with explicit fibers (the close-up's ply swept along every "
                         "ply curve; millions of curve keys)")
    ap.add_argument("--check", action="store_true",
                    help="with --render: fail unless every image is finite (no NaN/Inf) and not black")
    args = ap.parse_args()
    cli = os.path.join(ROOT, "build", "cpp_core", "neuralyarn")
    cycles = os.path.join(ROOT, "build", "cycles", "bin", "cycles")
    for tool in [cli] + ([cycles] if args.render else []):
        if not os.access(tool, os.X_OK):
            raise SystemExit(f"make_examples: {tool} is not built; run scripts/setup.sh first")
    os.makedirs(args.out, exist_ok=True)

    # Patch geometry (the same for every preset), written once as plies files that cycles-scene draws for every
    # preset and method.
    patches = {kind: list(patch_scene_args(args.out, kind)) for kind in PATCHES if kind in args.scenes}

    scenes = []  # (XML to render, width, height)
    for p in args.presets:
        model = os.path.join(ROOT, "models", p + ".json")
        if "closeup" in args.scenes:
            fibers, yarn = (os.path.join(args.out, f"{p}_{v}") for v in ("fibers", "yarn"))
            size = ["--width", str(args.width), "--height", str(args.height)]
            run([cli, "cycles-scene", "--preset", p, *size, "--out", fibers + ".xml"])
            # Each aggregated scene also as its description, which Blender renders (scripts/fallback_render.py).
            run([cli, "cycles-scene", "--preset", p, "--model", model, *size, "--out", yarn + ".xml",
                 "--out", yarn + ".json"])
            scenes += [(fibers + ".xml", args.width, args.height), (yarn + ".xml", args.width, args.height)]
        square = ["--width", str(args.width), "--height", str(args.width)]
        for kind, patch in patches.items():
            name = os.path.join(args.out, f"{kind}_{p}")
            run([cli, "cycles-scene", "--preset", p, "--model", model, *square, *patch, "--out", name + ".xml",
                 "--out", name + ".json"])
            scenes.append((name + ".xml", args.width, args.width))
            if args.explicit_patches:
                run([cli, "cycles-scene", "--preset", p, *square, *patch, "--out", name + "_fibers.xml"])
                scenes.append((name + "_fibers.xml", args.width, args.width))
    print(f"make_examples: wrote {len(scenes)} scenes to {args.out}")

    if args.render:
        for k, (scene, width, height) in enumerate(scenes):
            exr = scene[:-4] + ".exr"
            t0 = time.monotonic()
            # (The standalone app takes the image size from its command line, not from the XML.)
            run([cycles, "--background", "--quiet", "--samples", str(args.samples), "--threads", str(args.threads),
                 "--width", str(width), "--height", str(height), "--output", exr, scene])
            run(["oiiotool", exr, "--colorconvert", "linear", "sRGB", "-d", "uint8", "-o", scene[:-4] + ".png"])
            line = f"[{k + 1}/{len(scenes)}] {os.path.basename(scene)}: {time.monotonic() - t0:.1f} s"
            if args.check:
                mean = check_image(exr)
                line += f", mean {mean:.4g}, finite"
            print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
