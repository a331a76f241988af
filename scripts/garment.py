#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The garment-scale scene's geometry: a plain-knit sleeve of 3-ply yarn, as ply centrelines for
`neuralyarn cycles-scene --plies` (a "neuralyarn-plies 1" file, docs/file_formats.md).

    .venv/bin/python scripts/garment.py --rows 40 --stitches 40 --out plies.json

rows x stitches of Crane's plain knit (the add-on's geometry package: addon/geometry/knit.py, default
shape), each yarn three S-twisted plies (alpha_yarn 0.5, as the examples' patches), wrapped into a tube whose
circumference is the courses' length (a sleeve; the seam at the back), axis vertical (y), the knit's face
outward; in ply radii (ply radius 1), the tube's front at z = 0 facing a camera on -z, centred on the origin
vertically and across. Deterministic (no random numbers). Prints one line: rows, stitches, plies, points,
tube radius and height in ply radii. The file also holds the yarns the plies were twisted from ("yarns",
"yarn_radius", "plies_per_yarn", "ply_twist"): the yarn level draws those (docs/decisions.md D27).
`straight_yarn_plies` is the harness's yarn close-up: one straight 3-ply yarn along x; `patch_plies` the
examples' and the harness's small patches (a 4 x 4 plain knit, a 6 x 6 twill) of 3-ply yarns.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
sys.path.insert(0, os.path.join(ROOT, "addon"))
import geometry  # noqa: E402  (addon/geometry: pure numpy)

PLIES_PER_YARN = 3
ALPHA_YARN = 0.5
SAMPLES_PER_LOOP = 24
#: Ply keys per ply turn about the yarn (twist_plies keeps at least one key per ply radius): the straight yarn's
#: close-up 16, the garment 8 (9.5 with that floor). A renderer draws a Catmull-Rom spline through the keys, and
#: the explicit fibers are swept along the same spline (sweep.h); at 8 keys per turn it stays within 0.7 % of a
#: ply radius of the plies' helix (the keys' polygon: 7.5 %), under 0.04 pixels while a ply is under 10 pixels
#: wide, as on every garment the harness frames (docs/benchmarks.md, "The garment's ply keys").
SAMPLES_PER_TURN = 16
GARMENT_SAMPLES_PER_TURN = 8


def _knit(rows: int, stitches: int, samples_per_turn: int = GARMENT_SAMPLES_PER_TURN) -> tuple[list, list, float]:
    """The garment's knit in Crane's units: its yarns (one per row), their plies and the plies' radius."""
    yarns = geometry.plain_knit(rows, stitches, samples_per_loop=SAMPLES_PER_LOOP)
    plies = []
    for y in yarns:
        plies += geometry.twist_plies(y, PLIES_PER_YARN, alpha_yarn=ALPHA_YARN, samples_per_turn=samples_per_turn)
    return yarns, plies, float(np.mean([p.radius.mean() for p in plies]))


def garment_plies(rows: int, stitches: int, samples_per_turn: int = GARMENT_SAMPLES_PER_TURN) -> dict:
    """The plies file's content: {"format", "ply_radius" (1), "plies", "rows", "stitches", "tube_radius",
    "height", "width"} (lengths in ply radii), the plies at `samples_per_turn` keys per ply turn. Raises
    geometry.GeometryError for bad sizes."""
    yarns, plies, r_ply = _knit(rows, stitches, samples_per_turn)
    course = 2.0 * math.pi * stitches / r_ply  # one stitch is 2 pi wide (Crane's units)
    tube = course / (2.0 * math.pi)
    pts = [p.points / r_ply for p in plies]
    y_mid = 0.5 * (min(p[:, 1].min() for p in pts) + max(p[:, 1].max() for p in pts))
    x_mid = 0.5 * course

    def wrapped(p: np.ndarray) -> list[float]:
        theta = (p[:, 0] - x_mid) / tube
        r = tube + p[:, 2]  # the knit's face (+z) outward
        q = np.stack([r * np.sin(theta), p[:, 1] - y_mid, tube - r * np.cos(theta)], axis=1)
        return [round(float(v), 4) for v in q.ravel()]

    height = max(p[:, 1].max() for p in pts) - min(p[:, 1].min() for p in pts)
    return {"format": "neuralyarn-plies 1", "ply_radius": 1.0, "rows": rows, "stitches": stitches,
            "tube_radius": tube, "height": float(height), "width": 2.0 * tube + 2.0 * (1.0 + ALPHA_YARN),
            "plies": [wrapped(p) for p in pts], **_yarns([wrapped(y.points / r_ply) for y in yarns]),
            "surface": _tube_surface(tube, float(height), (0.0, 0.0, tube))}


#: Segments around the surface level's tube (its mid-surface, docs/decisions.md D44): 0.4 % of the radius
#: between chord and arc.
TUBE_SEGMENTS = 256


def _tube_surface(radius: float, height: float, centre: tuple) -> dict:
    """The knit's mid-surface of the sleeve: a cylinder of `radius` about the vertical axis through `centre`, the
    triangles wound so that their normals point outward (the knit's face)."""
    n = TUBE_SEGMENTS
    theta = 2.0 * math.pi * np.arange(n) / n
    cx, cy, cz = centre
    ring = [np.stack([cx + radius * np.sin(theta), np.full(n, cy + y), cz - radius * np.cos(theta)], axis=1)
            for y in (-0.5 * height, 0.5 * height)]
    tris = []
    for i in range(n):
        j = (i + 1) % n
        tris += [i, n + i, j, j, n + i, n + j]  # (bottom i, top i, bottom j): outward (checked by the test)
    return {"vertices": [round(float(v), 4) for v in np.concatenate(ring).ravel()], "triangles": tris}


def flat_knit_plies(rows: int, stitches: int) -> dict:
    """The garment's knit, flat: rows x stitches of the same plies and yarns in the plane z = 0 (ply radius 1),
    its face toward +z, with its "period" (one stitch along x, one row along y): the patch `neuralyarn surface`
    walks through to measure the surface level's BSDF (D44)."""
    yarns, plies, r_ply = _knit(rows, stitches)
    # One row along y: the knit's own row spacing (a one-row patch takes it from two rows of one stitch).
    pair = yarns if rows > 1 else geometry.plain_knit(2, 1, samples_per_loop=SAMPLES_PER_LOOP)
    wale = float(pair[1].points[0, 1] - pair[0].points[0, 1])

    def flat(p: np.ndarray) -> list[float]:
        return [round(float(v), 5) for v in (p / r_ply).ravel()]

    return {"format": "neuralyarn-plies 1", "ply_radius": 1.0, "rows": rows, "stitches": stitches,
            "period": [2.0 * math.pi / r_ply, wale / r_ply], "plies": [flat(p.points) for p in plies],
            **_yarns([flat(y.points) for y in yarns])}


def yarn_radius() -> float:
    """The yarns' radius in ply radii (twist_plies fits the plies inside the yarn: R_yarn = R_ply (1 + d / R_ply))."""
    return 1.0 + geometry.ply_center_distance(PLIES_PER_YARN, 1.0, ALPHA_YARN)


def _yarns(centrelines: list[list[float]]) -> dict:
    """The plies file's yarn keys: the yarns' centrelines, radius and plying."""
    return {"yarns": centrelines, "plies_per_yarn": PLIES_PER_YARN, "ply_twist": ALPHA_YARN,
            "yarn_radius": yarn_radius()}


def straight_yarn_plies(length: float) -> dict:
    """One straight yarn of PLIES_PER_YARN plies along x, centred on the origin, `length` ply radii long (ply
    radius 1): the harness's yarn close-up."""
    r_yarn = yarn_radius()
    n = max(2, int(math.ceil(length / 0.25)) + 1)  # the plies are resampled per turn by twist_plies
    axis = np.stack([np.linspace(-0.5 * length, 0.5 * length, n), np.zeros(n), np.zeros(n)], axis=1)
    yarn = geometry.YarnCurve(axis, np.full(n, r_yarn))
    plies = geometry.twist_plies(yarn, PLIES_PER_YARN, alpha_yarn=ALPHA_YARN, samples_per_turn=SAMPLES_PER_TURN)
    return {"format": "neuralyarn-plies 1", "ply_radius": 1.0, "length": length,
            "plies": [[round(float(v), 5) for v in p.points.ravel()] for p in plies],
            **_yarns([[round(float(v), 5) for v in axis[[0, -1]].ravel()]])}


def crossed_plies(angles: list[float], length: float) -> dict:
    """Straight plies `length` ply radii long through the view's axis (ply radius 1), the first at depth 0, each next
    one diameter further (touching the one before), turned by `angles` degrees in the image plane: a ply in another's
    shadow (decisions D68; tests/cycles/near_field.py, scripts/bench_near_field.py)."""
    t = np.linspace(-0.5 * length, 0.5 * length, 400)
    plies = []
    for k, a in enumerate(angles):
        c, s = math.cos(math.radians(a)), math.sin(math.radians(a))
        p = np.stack([t * c, t * s, np.full_like(t, 2.0 * k)], axis=1)
        plies.append([round(float(v), 5) for v in p.ravel()])
    return {"format": "neuralyarn-plies 1", "ply_radius": 1.0, "length": length, "plies": plies}


def parallel_plies(offsets: list[tuple[float, float]], length: float) -> dict:
    """Straight plies `length` ply radii long along x (ply radius 1), each at its (height y, depth z) offset: one ply
    shadowing part of another's width (decisions D70; scripts/bench_near_field.py `half`)."""
    t = np.linspace(-0.5 * length, 0.5 * length, 400)
    plies = [[round(float(v), 5) for v in np.stack([t, np.full_like(t, y), np.full_like(t, z)], axis=1).ravel()]
             for y, z in offsets]
    return {"format": "neuralyarn-plies 1", "ply_radius": 1.0, "length": length, "plies": plies}


#: The patches' yarns (yarn radius 0.5 in Crane's units): examples/make_examples.py's and the harness's scenes
#: `knit` and `twill`.
PATCHES = {"knit": lambda: geometry.plain_knit(4, 4, samples_per_loop=48),
           "twill": lambda: geometry.woven_fabric("twill", 6, 6, spacing=2.5, yarn_radius=0.5)}


def patch_plies(kind: str) -> dict:
    """A patch as a plies file's content in ply radii (ply radius 1): each yarn of PATCHES[kind] twisted from
    PLIES_PER_YARN plies, centred at the origin in the xy plane and tilted 35 degrees about x toward a camera on
    -z; "size" is the diagonal of its bounding box before the tilt."""
    plies = []
    for y in PATCHES[kind]():
        plies += geometry.twist_plies(y, PLIES_PER_YARN, alpha_yarn=ALPHA_YARN, samples_per_turn=24)
    r_ply = float(np.mean([p.radius.mean() for p in plies]))
    pts = [(np.concatenate([p.points, p.points[:1]]) if p.cyclic else p.points) / r_ply for p in plies]
    every = np.concatenate(pts)
    lo, hi = every.min(axis=0), every.max(axis=0)
    tilt = math.radians(35.0)
    rot = np.array([[1, 0, 0], [0, math.cos(tilt), -math.sin(tilt)], [0, math.sin(tilt), math.cos(tilt)]])
    return {"format": "neuralyarn-plies 1", "ply_radius": 1.0, "size": float(np.linalg.norm(hi - lo)),
            "plies": [[round(float(v), 5) for v in ((p - 0.5 * (lo + hi)) @ rot.T).ravel()] for p in pts]}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=40)
    ap.add_argument("--stitches", type=int, default=40)
    ap.add_argument("--flat", action="store_true", help="the knit flat, with its period: the surface level's patch")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    try:
        g = (flat_knit_plies if a.flat else garment_plies)(a.rows, a.stitches)
    except geometry.GeometryError as e:
        print(f"garment: error: {e}", file=sys.stderr)
        return 1
    with open(a.out, "w") as f:
        json.dump(g, f, separators=(",", ":"))
    print(f"{a.rows} rows x {a.stitches} stitches: {len(g['plies'])} plies, "
          f"{sum(len(p) for p in g['plies']) // 3} points, " +
          (f"period {g['period'][0]:.2f} x {g['period'][1]:.2f}" if a.flat else
           f"tube radius {g['tube_radius']:.1f}, height {g['height']:.1f}") + " ply radii")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
