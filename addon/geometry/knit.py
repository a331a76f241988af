# SPDX-License-Identifier: Apache-2.0
"""Plain knit (stockinette / jersey) centrelines: Keenan Crane's closed-form yarn curve.

Crane, "A Simple Parametric Model of Plain-Knit Yarns" (code: keenancrane/plain-knit-yarn). One course (row)
is

    gamma(t) = (t + a sin 2t,  h cos t,  d cos 2t),     one stitch per 2 pi of t,

with a the loop roundness, h the loop height and d the loop depth; row k is the same curve shifted by k w
along the wales. Rows interlock (each loop reaches through the loop of the row below) because h > w/2.
The fabric lies in Blender's XY plane (x along the courses, y along the wales, z out of the fabric), so a
generated swatch needs no rotation.
"""
from __future__ import annotations

import math

import numpy as np

from .curves import GeometryError, YarnCurve, _check_int, _check_positive

MAX_ROWS = 2000
MAX_STITCHES = 2000
MAX_KNIT_POINTS = 5_000_000


def knit_pattern(yarn_radius: float = 0.5, a: float = 1.5, h: float = 4.0, d: float = 1.0,
                 w: float | None = None) -> dict:
    """The shape of a plain knit in knit units, without its size (rows, stitches, scale) or face (purl): what a
    fit of its far field (the surface level, docs/decisions.md D44) holds for."""
    return {"kind": "plain_knit", "a": a, "h": h, "d": d, "w": h + 0.5 if w is None else w, "yarn_radius": yarn_radius}


def crane_course(t: np.ndarray, a: float = 1.5, h: float = 4.0, d: float = 1.0) -> np.ndarray:
    """Crane's course curve gamma(t) = (t + a sin 2t, h cos t, d cos 2t), shape (len(t), 3)."""
    t = np.asarray(t, dtype=np.float64)
    return np.stack([t + a * np.sin(2.0 * t), h * np.cos(t), d * np.cos(2.0 * t)], axis=-1)


def plain_knit(
    rows: int,
    stitches: int,
    *,
    a: float = 1.5,
    h: float = 4.0,
    d: float = 1.0,
    w: float | None = None,
    yarn_radius: float = 0.5,
    samples_per_loop: int = 64,
    scale: float = 1.0,
    purl: bool = False,
) -> list[YarnCurve]:
    """A rows x stitches plain-knit swatch, one open YarnCurve per row (row k at y = k w).

    Defaults are Crane's (a = 3/2, h = 4, d = 1, w = h + 1/2, r = 1/2, 64 samples per loop); in these units
    a stitch is 2 pi wide. With them the centrelines of neighbouring rows stay 1.53 apart (> 2r = 1), so
    the yarn tubes do not intersect. purl gives the reverse side (z -> -z). scale multiplies lengths and
    the radius. Raises GeometryError for invalid parameters, including h <= w/2 (rows would not interlock).
    """
    rows = _check_int("rows", rows, 1, MAX_ROWS)
    stitches = _check_int("stitches", stitches, 1, MAX_STITCHES)
    samples_per_loop = _check_int("samples_per_loop", samples_per_loop, 4, 4096)
    a = _check_positive("a", a, allow_zero=True)
    h = _check_positive("h", h)
    d = _check_positive("d", d)
    w = h + 0.5 if w is None else _check_positive("w", w)
    yarn_radius = _check_positive("yarn_radius", yarn_radius)
    scale = _check_positive("scale", scale)
    if not h > 0.5 * w:
        raise GeometryError(
            f"parameters 'h' = {h:g} and 'w' = {w:g}: the rows would not interlock (needs h > w/2, i.e. w < {2 * h:g})"
        )
    n = stitches * samples_per_loop + 1
    if rows * n > MAX_KNIT_POINTS:
        raise GeometryError(
            f"{rows} rows x {stitches} stitches x {samples_per_loop} samples per loop = {rows * n} points exceed "
            f"the limit of {MAX_KNIT_POINTS}; lower 'samples_per_loop' or the swatch size"
        )
    t = np.linspace(0.0, 2.0 * math.pi * stitches, n)
    course = crane_course(t, a, h, d)
    if purl:
        course[:, 2] = -course[:, 2]
    out = []
    for k in range(rows):
        pts = course + np.array([0.0, k * w, 0.0])
        out.append(YarnCurve(pts * scale, np.full(n, yarn_radius * scale), False))
    return out
