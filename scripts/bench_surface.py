#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The surface level (D44) against what it was fitted to: the flat knit it was measured on, drawn at the yarn
level (its yarns, the yarn-level model) and at the surface level (one quad, the fitted stock closures), side by
side in the patched standalone Cycles under the same lights; prints the central region's mean colour of both and
their ratio per channel. It separates the fit's error (lobes, tables, the renderer's reading of them) from the
surface level's error against explicit fibers (the harness, `evaluate.sh --methods surface`). With --garment N,
the same on the harness's N x N sleeve at --size (its mid-surface against its yarns): where the yarns are below a
pixel and explicit fibers do not fit in memory. On the flat knit, under the parametric suns (sun-DEG-normal), it also
prints what the walk itself predicts there (the sun's irradiance times the maps' f |cos theta_l| at the view bin
nearest the normal and the sun's |cos| bin, over the azimuths), and each render over it: the fit's error and the
renderer's disagreement with the walk, apart.

    .venv/bin/python scripts/bench_surface.py --presets fleece cotton --lights environment sun-30-normal \\
        sun-150-normal --spp 256 --out build/bench_surface
    .venv/bin/python scripts/bench_surface.py --garment 40 --size 80 60 --out build/bench_surface_garment
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import evaluate  # noqa: E402  (the harness's fit settings and the sleeve's framing)
from garment import flat_knit_plies  # noqa: E402
from images import read_exr  # noqa: E402

CLI, CYCLES = evaluate.CLI, evaluate.CYCLES
#: The flat knit's renders: SIZE x SIZE pixels, the camera CAMERA_DISTANCE ply radii away along the knit's normal
#: (it sees the back face).
SIZE = 64
CAMERA_DISTANCE = 200.0


def patch(out: str) -> tuple[str, str]:
    """The flat knit (for `neuralyarn surface`) and the same knit centred on the origin with a quad over it
    (for cycles-scene --plies, whose camera looks at the origin along +z)."""
    g = flat_knit_plies(evaluate.SURFACE_FIT["rows"], evaluate.SURFACE_FIT["stitches"])  # the harness's patch
    fit = os.path.join(out, "flat_knit.json")
    with open(fit, "w") as f:
        json.dump(g, f, separators=(",", ":"))
    pts = np.concatenate([np.reshape(y, (-1, 3)) for y in g["yarns"]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.0])
    for key in ("yarns", "plies"):
        g[key] = [[round(float(v), 5) for v in (np.reshape(q, (-1, 3)) - c).ravel()] for q in g[key]]
    x0, y0, x1, y1 = lo[0] - c[0], lo[1] - c[1], hi[0] - c[0], hi[1] - c[1]
    g["surface"] = {"vertices": [x0, y0, 0, x1, y0, 0, x1, y1, 0, x0, y1, 0], "triangles": [0, 1, 2, 0, 2, 3]}
    scene = os.path.join(out, "flat_knit_scene.json")
    with open(scene, "w") as f:
        json.dump(g, f, separators=(",", ":"))
    return fit, scene


def render(xml: str, exr: str, spp: int, size: tuple[int, int]) -> tuple[np.ndarray, float]:
    """The central region's mean colour (the middle half of each side) and the wall time."""
    w, h = size
    t0 = time.monotonic()
    subprocess.run([CYCLES, "--background", "--quiet", "--samples", str(spp), "--threads", "2", "--width", str(w),
                    "--height", str(h), "--output", exr, xml], check=True, capture_output=True)
    seconds = time.monotonic() - t0
    return read_exr(exr)[h // 4:3 * h // 4, w // 4:3 * w // 4, :3].mean(axis=(0, 1)), seconds


def walk_prediction(maps_file: str, xml: str, light: str) -> np.ndarray | None:
    """E times the maps' mean f |cos theta_l| over the light's azimuths (the surface level takes the cloth as
    isotropic) for a parametric sun seen along the patch's normal from its back (side 1, the last view bin), or
    None for another light."""
    m = re.fullmatch(r"sun-(\d+(?:\.\d+)?)-(?:normal|axis)", light)
    if not m:
        return None
    with open(maps_file) as f:
        maps = json.load(f)
    v, t, p = maps["view_bins"], maps["light_theta"], maps["light_phi"]
    d = np.reshape(maps["D"], (2, v, 2, t, p, 3))
    deg = float(m.group(1))
    c = abs(math.cos(math.radians(deg)))
    strength = float(re.search(r'<light light_type="distant"[^>]* strength="([^ "]+)', open(xml).read()).group(1))
    return strength * d[1, v - 1, 0 if deg < 90 else 1, min(int(c * t), t - 1)].mean(axis=0)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--presets", nargs="+", default=["fleece"])
    ap.add_argument("--lights", nargs="+", default=["environment", "sun-30-normal", "sun-60-normal", "sun-150-normal",
                                                     "sun-170-normal"])
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--paths", default=evaluate.SURFACE_FIT["paths"], help="paths of the surface fit (default: the "
                    "harness's)")
    ap.add_argument("--garment", type=int, help="instead of the flat knit: the harness's sleeve of N x N stitches")
    ap.add_argument("--size", type=int, nargs=2, metavar=("W", "H"), help="image size (default 64 64; the "
                    "garment's: evaluate.py's)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    fit, scene = patch(a.out)
    size = tuple(a.size) if a.size else (SIZE, SIZE)
    framing = ["--camera-distance", str(CAMERA_DISTANCE)]
    if a.garment:
        os.makedirs(os.path.join(a.out, "scenes"), exist_ok=True)
        args = list(evaluate.garment_framing(a.out, a.garment, size[0] / size[1]))
        i = args.index("--plies")
        scene, framing = args[i + 1], args[:i] + args[i + 2:]
    print("preset light: yarn level rgb | surface level rgb | surface / yarn - 1 (%) | seconds yarn / surface")
    for preset in a.presets:
        yarn_model = evaluate.yarn_model_path(preset)
        surface = os.path.join(a.out, f"surface_{preset}.json")
        t0 = time.monotonic()
        maps_file = os.path.join(a.out, f"surface_{preset}_maps.json")
        subprocess.run([CLI, "surface", "--plies", fit, "--model", yarn_model, "--paths", a.paths, "--quiet",
                        "--out", surface, "--maps-out", maps_file], check=True, capture_output=True)
        print(f"{preset}: surface fitted in {time.monotonic() - t0:.1f} s")
        for light in a.lights:
            res = {}
            for level, extra in (("yarns", ["--model", yarn_model]), ("surface", ["--surface", surface])):
                xml = os.path.join(a.out, f"{preset}_{light}_{level}.xml")
                subprocess.run([CLI, "cycles-scene", "--preset", preset, "--lights", light, "--width", str(size[0]),
                                "--height", str(size[1]), "--plies", scene, *framing,
                                "--level", level, *extra, "--out", xml], check=True, capture_output=True)
                res[level] = render(xml, xml[:-4] + ".exr", a.spp, size)
            (y, ty), (s, ts) = res["yarns"], res["surface"]
            rel = 100.0 * (s / np.maximum(y, 1e-12) - 1.0)
            print(f"{preset} {light}: {' '.join(f'{v:.5f}' for v in y)} | {' '.join(f'{v:.5f}' for v in s)} | "
                  f"{' '.join(f'{v:+.1f}' for v in rel)} | {ty:.1f} / {ts:.1f}")
            walk = None if a.garment else walk_prediction(maps_file, xml, light)
            if walk is not None:
                print(f"    the walk predicts {' '.join(f'{v:.5f}' for v in walk)}: yarn level / walk "
                      f"{' '.join(f'{v:.3f}' for v in y / walk)}, surface level / walk {' '.join(f'{v:.3f}' for v in s / walk)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
