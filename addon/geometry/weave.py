# SPDX-License-Identifier: Apache-2.0
"""Woven fabrics: a weave pattern matrix plus crimped, cosine-eased warp and weft centrelines.

Standard textile geometry (a weave's interlacing matrix, as in textile design). P[i][j] = 1 means warp i passes over weft j; the matrix
is one repeat and is applied periodically. Warp i runs along y at x = i s_x, weft j along x at y = j s_y.
At a crossing the yarn on top sits at z = +c and the other at -c; between neighbouring crossings z is eased
by (1 - cos pi u)/2, so floats (the same state at consecutive crossings) stay flat and the curve has a
continuous tangent everywhere.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .curves import GeometryError, YarnCurve, _check_int, _check_positive

MAX_YARNS = 10_000
MAX_WEAVE_POINTS = 5_000_000


def weave_pattern(kind: str, **params: object) -> np.ndarray:
    """The repeat of a named weave as an int8 0/1 matrix P[i][j] (1 = warp i over weft j).

    plain:                 P = (i + j) mod 2, 2 x 2.
    twill(u=2, d=2, direction=+1):
                           P = ((j - direction i) mod K) < u, K = u + d; direction +1/-1 flips the diagonal.
    satin(K=5, m=2, face='warp'):
                           move m with 1 < m < K-1 and gcd(m, K) = 1. A weft-faced satin has one binding
                           point per row, P = [(j - m i) mod K == 0] (each warp passes over 1 weft in K); a
                           warp-faced satin is its complement (each warp floats over K-1 wefts).
    basket(n=2):           P = (floor(i/n) + floor(j/n)) mod 2, 2n x 2n.
    """
    allowed = {"plain": {}, "twill": {"u": 2, "d": 2, "direction": 1}, "satin": {"K": 5, "m": 2, "face": "warp"},
               "basket": {"n": 2}}
    if kind not in allowed:
        raise GeometryError(f"unknown weave {kind!r} (expected one of {', '.join(allowed)})")
    unknown = sorted(set(params) - set(allowed[kind]))
    if unknown:
        names = sorted(allowed[kind]) or "none"
        raise GeometryError(f"weave '{kind}': unknown parameter(s) {unknown} (allowed: {names})")
    p = {**allowed[kind], **params}
    if kind == "plain":
        i, j = np.indices((2, 2))
        P = (i + j) % 2
    elif kind == "twill":
        u = _check_int("u", p["u"], 1, 64)
        d = _check_int("d", p["d"], 1, 64)
        sigma = p["direction"]
        if isinstance(sigma, bool) or sigma not in (1, -1):
            raise GeometryError(f"parameter 'direction' must be +1 or -1, got {sigma!r}")
        K = u + d
        i, j = np.indices((K, K))
        P = ((j - int(sigma) * i) % K) < u  # type: ignore[call-overload]
    elif kind == "satin":
        K = _check_int("K", p["K"], 5, 128)
        m = _check_int("m", p["m"], 2, K - 2)  # 1 < m < K - 1
        if math.gcd(m, K) != 1:
            raise GeometryError(f"satin move m = {m} must be coprime with K = {K} (gcd is {math.gcd(m, K)})")
        face = p["face"]
        if face not in ("warp", "weft"):
            raise GeometryError(f"parameter 'face' must be 'warp' or 'weft', got {face!r}")
        i, j = np.indices((K, K))
        P = ((j - m * i) % K) == 0
        if face == "warp":
            P = ~P
    else:
        n = _check_int("n", p["n"], 1, 64)
        i, j = np.indices((2 * n, 2 * n))
        P = (i // n + j // n) % 2
    return np.asarray(P, dtype=np.int8)


def _as_pattern(pattern: object) -> np.ndarray:
    if isinstance(pattern, str):
        return weave_pattern(pattern)
    try:
        P = np.array(pattern, dtype=np.float64)
    except (TypeError, ValueError):
        raise GeometryError("parameter 'pattern' must be a 2-D matrix of 0/1") from None
    if P.ndim != 2 or P.size == 0:
        raise GeometryError(f"parameter 'pattern' must be a non-empty 2-D matrix of 0/1, got shape {P.shape}")
    if not np.all((P == 0.0) | (P == 1.0)):
        bad = np.argwhere((P != 0.0) & (P != 1.0))[0]
        raise GeometryError(f"parameter 'pattern': entry [{bad[0]}][{bad[1]}] = {P[tuple(bad)]!r} is not 0 or 1")
    return P.astype(np.int8)


def _eased_profile(z: np.ndarray, x: np.ndarray, spacing: float) -> np.ndarray:
    """z at positions x from crossing heights z[k] at k * spacing (k = 0 .. len(z)-1), cosine-eased."""
    f = x / spacing
    k = np.clip(np.floor(f).astype(np.int64), 0, len(z) - 2)
    u = f - k
    return z[k] + (z[k + 1] - z[k]) * 0.5 * (1.0 - np.cos(math.pi * u))


def weave_clearance(
    pattern: object, spacing: tuple[float, float], yarn_radius: float, crimp: float | None = None
) -> float:
    """Smallest distance between a warp and a weft centreline anywhere in the (periodic) fabric.

    Tubes of radius r do not intersect when this is >= 2r. At a crossing the distance is 2c, but next to it
    the two yarns bend towards each other with curvature c pi^2 / s^2; for circular yarns the crossing stays
    the closest point only while s >= pi sqrt(2) c (about 4.44 r for c = r). Computed numerically per
    distinct crossing neighbourhood (a 201 x 201 grid refined twice), so it holds for any pattern.
    """
    P = _as_pattern(pattern)
    sx, sy = (_check_positive("spacing", v) for v in spacing)
    r = _check_positive("yarn_radius", yarn_radius)
    c = r if crimp is None else _check_positive("crimp", crimp)
    Kw, Kf = P.shape
    configs = set()
    for i in range(Kw):
        for j in range(Kf):
            warp = tuple(c if P[i, (j + dj) % Kf] else -c for dj in (-1, 0, 1))
            weft = tuple(-c if P[(i + di) % Kw, j] else c for di in (-1, 0, 1))
            configs.add((warp, weft))
    L = min(sx, sy, 2.0 * r)  # beyond |X|, |Y| = 2r the distance exceeds 2r anyway
    best = math.inf
    for warp, weft in configs:
        zw_nodes, zf_nodes = np.array(warp), np.array(weft)

        def dist(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
            zw = _eased_profile(zw_nodes, Y + sy, sy)  # warp: along y, crossing j at Y = 0
            zf = _eased_profile(zf_nodes, X + sx, sx)  # weft: along x, crossing i at X = 0
            return np.sqrt(X * X + Y * Y + (zw - zf) ** 2)

        cx, cy, half = 0.0, 0.0, L
        for n in (201, 41, 41):
            xs = np.clip(np.linspace(cx - half, cx + half, n), -L, L)
            ys = np.clip(np.linspace(cy - half, cy + half, n), -L, L)
            X, Y = np.meshgrid(xs, ys)
            D = dist(X, Y)
            k = np.unravel_index(int(np.argmin(D)), D.shape)
            cx, cy = float(X[k]), float(Y[k])
            best = min(best, float(D[k]))
            half = 2.0 * half / (n - 1)
    return best


def woven_fabric(
    pattern: object,
    warps: int,
    wefts: int,
    *,
    spacing: tuple[float, float] | float = (2.5, 2.5),
    yarn_radius: float = 0.5,
    crimp: float | None = None,
    samples_per_crossing: int = 16,
) -> list[YarnCurve]:
    """Warp and weft centrelines of a woven swatch: `warps` curves along y, then `wefts` curves along x.

    pattern: a 0/1 matrix (or a weave name with default parameters), applied periodically. spacing
    (s_x, s_y) is the warp and weft pitch; crimp c defaults to the yarn radius so that yarns touch at the
    crossings (centres 2c = 2r apart). Each yarn extends half a pitch beyond the outer crossings, eased
    towards the next crossing of the periodic pattern, like a cut edge. Raises GeometryError when the tubes
    would intersect: s < 2r (neighbouring parallel yarns), c < r (at the crossings), or warp and weft
    closer than 2r next to a crossing (s too small for the crimp's bending, see `weave_clearance`). Rows of
    all ones or zeros (yarns that never interlace) are allowed. The default spacing 2.5 = 5 r clears the
    plain-weave bound pi sqrt(2) c = 2.22 for the default r = c = 0.5.
    """
    P = _as_pattern(pattern)
    warps = _check_int("warps", warps, 1, MAX_YARNS)
    wefts = _check_int("wefts", wefts, 1, MAX_YARNS)
    if isinstance(spacing, (int, float, np.floating, np.integer)) and not isinstance(spacing, bool):
        spacing = (float(spacing), float(spacing))
    try:
        sx_raw, sy_raw = spacing  # type: ignore[misc]
    except (TypeError, ValueError):
        raise GeometryError(f"parameter 'spacing' must be a pair (s_x, s_y), got {spacing!r}") from None
    sx = _check_positive("spacing s_x", sx_raw)
    sy = _check_positive("spacing s_y", sy_raw)
    r = _check_positive("yarn_radius", yarn_radius)
    c = r if crimp is None else _check_positive("crimp", crimp)
    spc = _check_int("samples_per_crossing", samples_per_crossing, 2, 1024)
    for label, s in (("s_x", sx), ("s_y", sy)):
        if s < 2.0 * r:
            raise GeometryError(
                f"parameter 'spacing': {label} = {s:g} < 2 x yarn_radius = {2 * r:g}: neighbouring parallel yarns "
                f"would intersect"
            )
    if c < r:
        raise GeometryError(
            f"parameter 'crimp' = {c:g} < yarn_radius = {r:g}: warp and weft would intersect at the crossings "
            f"(their centres are 2 crimp apart there)"
        )
    n_points = warps * (wefts * spc + 1) + wefts * (warps * spc + 1)
    if n_points > MAX_WEAVE_POINTS:
        raise GeometryError(
            f"{warps} warps x {wefts} wefts give {n_points} points, over the limit of {MAX_WEAVE_POINTS}"
        )
    gap = weave_clearance(P, (sx, sy), r, c)
    if gap < 2.0 * r * (1.0 - 1e-6):
        raise GeometryError(
            f"warp and weft would intersect next to the crossings: their centrelines come {gap:.4g} close, less "
            f"than 2 x yarn_radius = {2 * r:g}; increase 'spacing' (the plain-weave bound is pi sqrt(2) crimp = "
            f"{math.pi * math.sqrt(2.0) * c:.4g}) or lower 'crimp' towards the radius"
        )

    Kw, Kf = P.shape
    out = []
    # Crossing indices -1 .. n (one beyond each end) so that the half-pitch ends are eased as well.
    ys = np.linspace(-0.5 * sy, (wefts - 0.5) * sy, wefts * spc + 1)
    jj = np.arange(-1, wefts + 1)
    for i in range(warps):
        z_nodes = np.where(P[i % Kw, jj % Kf] == 1, c, -c).astype(np.float64)
        z = _eased_profile(z_nodes, ys + sy, sy)
        pts = np.stack([np.full_like(ys, i * sx), ys, z], axis=1)
        out.append(YarnCurve(pts, np.full(len(pts), r), False))
    xs = np.linspace(-0.5 * sx, (warps - 0.5) * sx, warps * spc + 1)
    ii = np.arange(-1, warps + 1)
    for j in range(wefts):
        z_nodes = np.where(P[ii % Kw, j % Kf] == 1, -c, c).astype(np.float64)
        z = _eased_profile(z_nodes, xs + sx, sx)
        pts = np.stack([xs, np.full_like(xs, j * sy), z], axis=1)
        out.append(YarnCurve(pts, np.full(len(pts), r), False))
    return out
