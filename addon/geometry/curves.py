# SPDX-License-Identifier: Apache-2.0
"""Yarn centrelines: the one representation every geometry front end produces.

Every importer (BCC, Leaf et al. patterns) and generator (knit, weave, plies) ends in a list of
`YarnCurve`s: dense polylines in Blender's Z-up world frame with a radius per vertex. Keeping the spline
evaluation here, in one place, means a `C0` curve from a BCC file and a `C0` tile from a Leaf pattern are
evaluated identically, and the Blender side only ever has to turn polylines into curve objects.

Only the standard library and numpy are used (no bpy), so that the module runs inside Blender as
`neural_yarn.geometry.curves` and in plain pytest alike.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

# Upper bound on the number of evaluated points any single call may produce (~0.5 GB of float64 xyz):
# a malformed file or a typo in a UI field must fail with a message, not exhaust the memory.
MAX_POINTS = 20_000_000

# Curve types of the BCC format, also used by the pattern loader.
CURVE_TYPES = {
    "C0": "uniform Catmull-Rom",
    "PL": "polyline",
    "BS": "uniform cubic B-spline",
    "BZ": "cubic Bezier",
}


class GeometryError(ValueError):
    """Any bad input to the geometry package: a malformed file, an invalid parameter, a degenerate curve.

    The message names the file or parameter and the problem, so that the add-on can show it verbatim.
    """


@dataclass
class YarnCurve:
    """One yarn centreline, already evaluated to a polyline.

    points: (n, 3) float64 vertices in Blender's Z-up world units.
    radius: (n,) float64 yarn radius per vertex (> 0); a scalar is broadcast.
    cyclic: the curve is a closed loop; the last vertex connects to the first, which is not repeated.
    """

    points: np.ndarray
    radius: np.ndarray
    cyclic: bool = False

    def __post_init__(self) -> None:
        pts = np.array(self.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise GeometryError(f"YarnCurve points must have shape (n, 3), got {pts.shape}")
        rad = np.array(self.radius, dtype=np.float64)
        if rad.ndim == 0:
            rad = np.full(len(pts), float(rad))
        if rad.shape != (len(pts),):
            raise GeometryError(f"YarnCurve radius must be a scalar or have shape ({len(pts)},), got {rad.shape}")
        self.points = pts
        self.radius = rad
        self.cyclic = bool(self.cyclic)

    @property
    def length(self) -> float:
        """Arc length of the polyline, including the closing segment of a cyclic curve."""
        return polyline_length(self.points, self.cyclic)


# ---------------------------------------------------------------------------------------------------------
# Parameter checks shared by the modules of this package (private).


def file_name(path) -> str:
    """The path as a string; GeometryError for an empty one (an importer run without a file chosen)."""
    name = os.fspath(path)
    if not name:
        raise GeometryError("no file given: choose a file to import")
    return name


def _check_int(name: str, value: object, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise GeometryError(f"parameter '{name}' must be an integer in [{lo}, {hi}], got {value!r}")
    if not lo <= int(value) <= hi:
        raise GeometryError(f"parameter '{name}' must be an integer in [{lo}, {hi}], got {int(value)}")
    return int(value)


def _check_positive(name: str, value: object, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise GeometryError(f"parameter '{name}' must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise GeometryError(f"parameter '{name}' must be a finite number {bound}, got {value!r}")
    return v


def _as_points(name: str, array: object) -> np.ndarray:
    try:
        pts = np.array(array, dtype=np.float64)
    except (TypeError, ValueError):
        raise GeometryError(f"{name}: control points must be numbers") from None
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise GeometryError(f"{name}: control points must have shape (n, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        k = int(np.argwhere(~np.isfinite(pts))[0, 0])
        raise GeometryError(f"{name}: control point {k} has a non-finite coordinate {pts[k].tolist()}")
    return pts


# ---------------------------------------------------------------------------------------------------------
# Spline evaluation.

# Power-basis matrices: p(t) = [1 t t^2 t^3] M [P0 P1 P2 P3]^T.
_CATMULL_ROM = 0.5 * np.array([[0, 2, 0, 0], [-1, 0, 1, 0], [2, -5, 4, -1], [-1, 3, -3, 1]], dtype=np.float64)
_BSPLINE = np.array([[1, 4, 1, 0], [-3, 0, 3, 0], [3, -6, 3, 0], [-1, 3, -3, 1]], dtype=np.float64) / 6.0
_BEZIER = np.array([[1, 0, 0, 0], [-3, 3, 0, 0], [3, -6, 3, 0], [-1, 3, -3, 1]], dtype=np.float64)


def control_point_problem(curve_type: str, n: int, cyclic: bool) -> str | None:
    """Why n control points cannot form a curve of this type, or None if they can.

    Open C0/BS curves need 4 points for their first segment (the end points only shape the end tangents);
    closed ones wrap around and need 3. Open Bezier curves are runs of 4 points sharing end points (3k+1),
    closed ones 3k. A polyline needs 2 points, or 3 to close a loop.
    """
    if curve_type not in CURVE_TYPES:
        return f"unknown curve type {curve_type!r} (expected one of {', '.join(CURVE_TYPES)})"
    kind = "a closed" if cyclic else "an open"
    label = f"{kind} '{curve_type}' ({CURVE_TYPES[curve_type]}) curve"
    plural = "point" if n == 1 else "points"
    if curve_type in ("C0", "BS"):
        need = 3 if cyclic else 4
        if n < need:
            verb = "is" if n == 1 else "are"
            return f"{n} control {plural} {verb} too few: {label} needs at least {need} (fewer give no segment)"
    elif curve_type == "BZ":
        if cyclic and (n < 3 or n % 3 != 0):
            return f"{n} control {plural}: {label} needs 3k control points (3, 6, 9, ...)"
        if not cyclic and (n < 4 or n % 3 != 1):
            return f"{n} control {plural}: {label} needs 3k+1 control points (4, 7, 10, ...)"
    else:
        need = 3 if cyclic else 2
        if n < need:
            return f"{n} control {plural} {'is' if n == 1 else 'are'} too few: {label} needs at least {need}"
    return None


def segment_count(curve_type: str, n: int, cyclic: bool) -> int:
    """Number of spline segments n control points give (0 if too few)."""
    if control_point_problem(curve_type, n, cyclic) is not None:
        return 0
    if curve_type in ("C0", "BS"):
        return n if cyclic else n - 3
    if curve_type == "BZ":
        return n // 3
    return n if cyclic else n - 1


def evaluated_point_count(curve_type: str, n: int, cyclic: bool, samples_per_segment: int) -> int:
    """Number of polyline vertices `evaluate_spline` returns for n control points."""
    if curve_type == "PL":
        return n
    return segment_count(curve_type, n, cyclic) * samples_per_segment + (0 if cyclic else 1)


def _evaluate_basis(P: np.ndarray, idx: np.ndarray, basis: np.ndarray, samples: int, cyclic: bool) -> np.ndarray:
    """Points of 4-point segments idx (nseg, 4) of one curve P (n, 3), or of a batch of curves P (m, n, 3)."""
    t = np.arange(samples, dtype=np.float64) / samples
    T = np.stack([np.ones_like(t), t, t * t, t * t * t], axis=1)  # (s, 4)
    W = T @ basis  # (s, 4) weights of the 4 control points
    seg = P[..., idx, :]  # ([m,] nseg, 4, 3)
    out = np.einsum("tk,...skd->...std", W, seg)
    out = out.reshape(*out.shape[:-3], -1, 3)
    if not cyclic:
        end = np.einsum("k,...kd->...d", np.ones(4) @ basis, seg[..., -1, :, :])
        out = np.concatenate([out, end[..., None, :]], axis=-2)
    return out


def _four_point_spline(control_points, cyclic: bool, curve_type: str, basis, samples_per_segment: int) -> np.ndarray:
    """A uniform spline whose segment i uses points i-1 .. i+2 (Catmull-Rom, B-spline): n segments closed
    (indices mod n), n-3 open (from P1 to P(n-2))."""
    P = np.asarray(control_points, dtype=np.float64)
    n = len(P)
    problem = control_point_problem(curve_type, n, cyclic)
    if problem:
        raise GeometryError(problem)
    idx, _ = _spline_indices(curve_type, n, cyclic)
    return _evaluate_basis(P, idx, basis, samples_per_segment, cyclic)


def catmull_rom(control_points: np.ndarray, cyclic: bool, samples_per_segment: int = 8) -> np.ndarray:
    """Uniform Catmull-Rom (BCC 'C0'): passes through every control point it spans.

    Open curves treat the first and last control points as phantoms that only set the end tangents, so n
    points give n-3 segments from P1 to P(n-2), as BCC's 'C0' defines them; closed curves take indices mod n.
    """
    return _four_point_spline(control_points, cyclic, "C0", _CATMULL_ROM, samples_per_segment)


def bspline(control_points: np.ndarray, cyclic: bool, samples_per_segment: int = 8) -> np.ndarray:
    """Uniform cubic B-spline (BCC 'BS'): C2, approximating; n-3 segments open, n closed (unclamped)."""
    return _four_point_spline(control_points, cyclic, "BS", _BSPLINE, samples_per_segment)


def bezier(control_points: np.ndarray, cyclic: bool, samples_per_segment: int = 8) -> np.ndarray:
    """Piecewise cubic Bezier (BCC 'BZ'): segments of 4 points sharing end points (3k+1 open, 3k closed)."""
    P = np.asarray(control_points, dtype=np.float64)
    n = len(P)
    problem = control_point_problem("BZ", n, cyclic)
    if problem:
        raise GeometryError(problem)
    idx, basis = _spline_indices("BZ", n, cyclic)
    return _evaluate_basis(P, idx, basis, samples_per_segment, cyclic)


def polyline(control_points: np.ndarray, cyclic: bool) -> np.ndarray:
    """BCC 'PL': the control points are the polyline."""
    P = np.array(control_points, dtype=np.float64)
    problem = control_point_problem("PL", len(P), cyclic)
    if problem:
        raise GeometryError(problem)
    return P


def evaluate_spline(
    control_points: np.ndarray, curve_type: str, cyclic: bool, samples_per_segment: int = 8
) -> np.ndarray:
    """Evaluates control points of any BCC curve type to polyline vertices (samples_per_segment per segment)."""
    samples_per_segment = _check_int("samples_per_segment", samples_per_segment, 1, 1000)
    if curve_type == "C0":
        return catmull_rom(control_points, cyclic, samples_per_segment)
    if curve_type == "BS":
        return bspline(control_points, cyclic, samples_per_segment)
    if curve_type == "BZ":
        return bezier(control_points, cyclic, samples_per_segment)
    if curve_type == "PL":
        return polyline(control_points, cyclic)
    raise GeometryError(f"unknown curve type {curve_type!r} (expected one of {', '.join(CURVE_TYPES)})")


def _spline_indices(curve_type: str, n: int, cyclic: bool) -> tuple[np.ndarray, np.ndarray]:
    """The segments' control-point indices (nseg, 4) and the basis of a 4-point spline type."""
    if curve_type == "BZ":
        k = np.arange(n // 3) * 3
        return np.stack([k, k + 1, k + 2, (k + 3) % n], axis=1), _BEZIER
    i = np.arange(n) if cyclic else np.arange(1, n - 2)
    idx = np.stack([(i - 1) % n, i % n, (i + 1) % n, (i + 2) % n], axis=1)
    return idx, (_CATMULL_ROM if curve_type == "C0" else _BSPLINE)


def evaluate_splines(
    control_points: Sequence[np.ndarray], curve_type: str, closed: Sequence[bool], samples_per_segment: int = 8
) -> list[np.ndarray]:
    """evaluate_spline for many curves at once: the curves of equal control-point count and closure are
    evaluated together (one einsum per group), so a file of 300 k short curves takes a second, not a minute
    of per-curve Python. Returns the same arrays as evaluate_spline would, in order; GeometryError (naming the
    curve) for control points no curve of this type can have."""
    samples_per_segment = _check_int("samples_per_segment", samples_per_segment, 1, 1000)
    if curve_type not in CURVE_TYPES:
        raise GeometryError(f"unknown curve type {curve_type!r} (expected one of {', '.join(CURVE_TYPES)})")
    groups: dict[tuple[int, bool], list[int]] = {}
    for c, (P, cyc) in enumerate(zip(control_points, closed)):
        problem = control_point_problem(curve_type, len(P), bool(cyc))
        if problem:
            raise GeometryError(f"curve {c}: {problem}")
        groups.setdefault((len(P), bool(cyc)), []).append(c)
    out: list[np.ndarray | None] = [None] * len(control_points)
    for (n, cyc), members in groups.items():
        pts = np.stack([np.asarray(control_points[c], dtype=np.float64) for c in members])  # (m, n, 3)
        if curve_type != "PL":
            idx, basis = _spline_indices(curve_type, n, cyc)
            pts = _evaluate_basis(pts, idx, basis, samples_per_segment, cyc)
        for k, c in enumerate(members):
            out[c] = pts[k]
    return out


def spline_curve(
    control_points: np.ndarray, curve_type: str, cyclic: bool, radius: float, samples_per_segment: int = 8
) -> YarnCurve:
    """A constant-radius YarnCurve from spline control points."""
    pts = evaluate_spline(control_points, curve_type, cyclic, samples_per_segment)
    return YarnCurve(pts, np.full(len(pts), float(radius)), cyclic)


# ---------------------------------------------------------------------------------------------------------
# Polyline utilities.


def polyline_length(points: np.ndarray, cyclic: bool) -> float:
    """Arc length of a polyline (with the closing segment if cyclic)."""
    P = np.asarray(points, dtype=np.float64)
    if len(P) < 2:
        return 0.0
    seg = np.diff(np.concatenate([P, P[:1]]) if cyclic else P, axis=0)
    return float(np.sum(np.linalg.norm(seg, axis=1)))


def median_control_point_spacing(control_curves: Sequence[np.ndarray], closed: Sequence[bool] | None = None) -> float:
    """Median distance between consecutive control points over all curves (0 if every spacing is 0).

    Used as the length scale for default radii and weld tolerances when a file stores no yarn radius:
    control points of relaxed yarn models are spaced about one yarn diameter apart (0.12-0.26 file units on
    Yuksel's files).
    """
    curves = [np.asarray(P, dtype=np.float64) for P in control_curves]
    flags = [bool(closed[c]) if closed is not None else False for c in range(len(curves))]
    # Each curve with its first point appended when closed; the differences across curve boundaries dropped.
    parts = [np.concatenate([P, P[:1]]) if cyc else P for P, cyc in zip(curves, flags) if len(P) >= 2]
    if not parts:
        return 0.0
    lengths = np.array([len(P) for P in parts])
    seg = np.linalg.norm(np.diff(np.concatenate(parts), axis=0), axis=1)
    keep = np.ones(len(seg), dtype=bool)
    keep[np.cumsum(lengths)[:-1] - 1] = False
    g = seg[keep]
    g = g[g > 0.0]
    return float(np.median(g)) if len(g) else 0.0


#: yarn_radius_from_passes: the most points compared with one query (a relaxed garment has ~150 within its
#: neighbour cells; only curves piled up in one place have more).
MAX_CANDIDATES = 5000


def yarn_radius_from_passes(curve_points: Sequence[np.ndarray], *, queries: int = 1000, seed: int = 0,
                            percentile: float = 10.0) -> float:
    """The yarn radius at which the yarns of a relaxed yarn-level model touch: half the distance from points
    of the yarns to the nearest point of *another pass* (another curve, or the same curve coming back: arc
    length along it more than 3x the straight distance), at its `percentile` over `queries` sampled points.
    Yarn-level models are relaxed with yarn contact, so most passes touch a neighbour somewhere; the low
    percentile takes those contacts and not the gaps between them. 0 if no two passes come near each other
    (within 8 point spacings). Deterministic for a seed; a grid of 8-spacing cells keeps it near-linear."""
    curves = [np.asarray(p, dtype=np.float64) for p in curve_points if len(p) >= 2]
    if len(curves) == 0:
        return 0.0
    P = np.concatenate(curves)
    cid = np.repeat(np.arange(len(curves)), [len(p) for p in curves])
    arc = np.concatenate([np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
                          for p in curves])
    steps = np.concatenate([np.linalg.norm(np.diff(p, axis=0), axis=1) for p in curves])
    steps = steps[steps > 0.0]
    if len(steps) == 0:
        return 0.0
    cell = 8.0 * float(np.median(steps))
    c = np.floor((P - P.min(axis=0)) / cell).astype(np.int64)
    dims = c.max(axis=0) + 3  # (+1 on each side for the neighbour cells)
    key = ((c[:, 0] + 1) * dims[1] + (c[:, 1] + 1)) * dims[2] + (c[:, 2] + 1)
    order = np.argsort(key, kind="stable")
    sorted_keys = key[order]
    rng = np.random.default_rng(seed)
    picked = rng.choice(len(P), size=min(queries, len(P)), replace=False)
    offsets = np.array([(dx * dims[1] + dy) * dims[2] + dz for dx in (-1, 0, 1) for dy in (-1, 0, 1)
                        for dz in (-1, 0, 1)])
    nearest = []
    for i in picked:
        lo = np.searchsorted(sorted_keys, key[i] + offsets)
        hi = np.searchsorted(sorted_keys, key[i] + offsets, side="right")
        cand = np.concatenate([order[a:b] for a, b in zip(lo, hi)])
        if len(cand) > MAX_CANDIDATES:  # curves piled up in one place: a fair sample of them is enough
            cand = rng.choice(cand, size=MAX_CANDIDATES, replace=False)
        d = np.linalg.norm(P[cand] - P[i], axis=1)
        other = ((cid[cand] != cid[i]) | (np.abs(arc[cand] - arc[i]) > 3.0 * d)) & (d <= cell)
        if other.any():
            nearest.append(d[other].min())
    return 0.5 * float(np.percentile(nearest, percentile)) if nearest else 0.0


def resample(curve: YarnCurve, max_segment_length: float) -> YarnCurve:
    """Subdivides every segment into equal pieces no longer than max_segment_length.

    Original vertices are kept (so the shape is unchanged: this is linear subdivision, not smoothing) and
    radii are interpolated linearly. Used before operations whose accuracy depends on sampling density, such
    as twisting plies around a yarn.
    """
    h = _check_positive("max_segment_length", max_segment_length)
    P = curve.points
    R = curve.radius
    n = len(P)
    if n < 2:
        return YarnCurve(P.copy(), R.copy(), curve.cyclic)
    Q = np.concatenate([P, P[:1]]) if curve.cyclic else P
    RQ = np.concatenate([R, R[:1]]) if curve.cyclic else R
    lengths = np.linalg.norm(np.diff(Q, axis=0), axis=1)
    with np.errstate(over="ignore", invalid="ignore"):
        pieces_f = np.ceil(lengths / h)
    if not np.all(np.isfinite(pieces_f)) or float(np.sum(np.maximum(pieces_f, 1.0))) > MAX_POINTS:
        raise GeometryError(
            f"parameter 'max_segment_length' = {h:g} would give more than {MAX_POINTS} points for a curve of length "
            f"{float(np.sum(lengths)):g}"
        )
    pieces = np.maximum(pieces_f.astype(np.int64), 1)
    seg = np.repeat(np.arange(len(pieces)), pieces)
    starts = np.concatenate([[0], np.cumsum(pieces)[:-1]])
    t = (np.arange(int(pieces.sum())) - np.repeat(starts, pieces)) / np.repeat(pieces, pieces)
    pts = Q[seg] + t[:, None] * (Q[seg + 1] - Q[seg])
    rad = RQ[seg] + t * (RQ[seg + 1] - RQ[seg])
    if not curve.cyclic:
        pts = np.concatenate([pts, P[-1:]], axis=0)
        rad = np.concatenate([rad, R[-1:]])
    return YarnCurve(pts, rad, curve.cyclic)


#: Renderable scale, in scene units: coordinates beyond MAX_COORDINATE, or a radius below MIN_RADIUS or
#: below MIN_RADIUS_RELATIVE of the largest coordinate (single precision resolves ~6e-8 of it), import and
#: render nothing, with no error (a file of coordinates +-3e38 or 1e-30, or a wrong import scale).
MAX_COORDINATE = 1e7
MIN_RADIUS = 1e-7
MIN_RADIUS_RELATIVE = 1e-6


def validate(curves: Iterable[YarnCurve], *, source: str | None = None) -> None:
    """Raises GeometryError for a curve no renderer can use; returns nothing if all are fine.

    Rejected: non-finite coordinates or radii, radius <= 0, zero-length curves (fewer than two distinct
    points), which would otherwise reach Cycles as invisible or NaN-producing primitives, and geometry
    outside the renderable scale (MAX_COORDINATE, MIN_RADIUS, MIN_RADIUS_RELATIVE). The message names the
    curve index (and `source`, e.g. the file name, when given).
    """
    prefix = f"{source}: " if source else ""
    curves = list(curves)
    for i, c in enumerate(curves):
        if not isinstance(c, YarnCurve):
            raise GeometryError(f"{prefix}curve {i} is a {type(c).__name__}, not a YarnCurve")
        if c.points.ndim != 2 or c.points.shape[1] != 3 or c.radius.shape != (len(c.points),):
            raise GeometryError(f"{prefix}curve {i}: points {c.points.shape} and radius {c.radius.shape} do not match")
    if not curves:
        return
    # All curves at once; the first curve that fails any check is then checked alone for its message.
    counts = np.array([len(c.points) for c in curves])
    if (counts < 2).any():
        bad = int(np.argmax(counts < 2))
    else:
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        P = np.concatenate([c.points for c in curves])
        R = np.concatenate([c.radius for c in curves])
        with np.errstate(invalid="ignore", over="ignore"):
            finite = np.logical_and.reduceat(np.isfinite(P).all(axis=1) & np.isfinite(R), starts)
            moves = np.logical_or.reduceat((P != np.repeat(P[starts], counts, axis=0)).any(axis=1), starts)
            extent = np.maximum.reduceat(np.abs(P).max(axis=1), starts)
            floor = np.maximum(MIN_RADIUS, MIN_RADIUS_RELATIVE * extent)
            ok = finite & moves & (extent <= MAX_COORDINATE) & (np.minimum.reduceat(R, starts) >= floor)
        if ok.all():
            return
        bad = int(np.argmin(ok))
    _validate_one(curves[bad], bad, prefix)
    raise AssertionError("validate: a curve failed the batched checks but not its own")  # (never)


def _validate_one(c: YarnCurve, i: int, prefix: str) -> None:
    """The checks of `validate` for curve i alone, with their messages."""
    P, R = c.points, c.radius
    bad = ~np.isfinite(P).all(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise GeometryError(f"{prefix}curve {i}: vertex {k} has a non-finite coordinate {P[k].tolist()}")
    if not np.isfinite(R).all():
        k = int(np.argmax(~np.isfinite(R)))
        raise GeometryError(f"{prefix}curve {i}: vertex {k} has a non-finite radius {R[k]}")
    if (R <= 0.0).any():
        k = int(np.argmax(R <= 0.0))
        raise GeometryError(f"{prefix}curve {i}: vertex {k} has radius {R[k]:g} (must be > 0)")
    if len(P) < 2 or not np.any(P != P[0]):
        what = "1 point" if len(P) == 1 else ("no points" if len(P) == 0 else "all points equal")
        raise GeometryError(f"{prefix}curve {i} has zero length ({what}): fewer than 2 distinct points")
    extent = float(np.abs(P).max())
    if extent > MAX_COORDINATE:
        raise GeometryError(f"{prefix}curve {i}: a coordinate of {extent:.3g} is beyond the renderable "
                            f"{MAX_COORDINATE:g} scene units; check the file's units and the import scale")
    floor = max(MIN_RADIUS, MIN_RADIUS_RELATIVE * extent)
    if R.min() < floor:
        raise GeometryError(f"{prefix}curve {i}: radius {R.min():.3g} is below the renderable {floor:.3g} "
                            f"scene units at coordinates up to {extent:.3g}; check the import scale")


def bounding_box(curves: Sequence[YarnCurve], *, include_radius: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) corners of all curves, grown by each vertex's radius unless include_radius is False."""
    if len(curves) == 0:
        raise GeometryError("bounding_box of an empty list of curves")
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for c in curves:
        r = c.radius[:, None] if include_radius else 0.0
        lo = np.minimum(lo, np.min(c.points - r, axis=0))
        hi = np.maximum(hi, np.max(c.points + r, axis=0))
    return lo, hi
