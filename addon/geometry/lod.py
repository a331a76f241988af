# SPDX-License-Identifier: GPL-3.0-or-later
"""Level of detail: which representation of a yarn object a camera needs (docs/decisions.md D27).

Levels, finest first: `fibers` (explicit fibers, the reference), `plies` (each ply a thick curve with the ply
model), `yarns` (each K-ply yarn one thick curve with the yarn-level model), `surface` (yarns below a pixel
as a cloth surface with stock closures, D44: measured and fitted by `neuralyarn surface`; the add-on draws it on
its Knitted Swatch of the default shape, when asked for: Auto never chooses it, as the evaluation harness never
measured it as accurate as the yarn level). The choice is made from the
projected width of a ply in pixels at the object's nearest visible point, as Cycles' Principled Hair Huang
switches near/far field from the curve radius against the pixel footprint; where an object's yarns lie at different
distances (a cloth receding from the camera), Auto splits it: the yarns nearer than the threshold as plies, the
others as yarns, each yarn by its own nearest point (a yarn is cut nowhere: its ends would show). The thresholds
are the ply widths below which the coarser level is as accurate as the finer in the evaluation harness's distance
sweep (docs/benchmarks.md, "Level of detail"). No bpy here: the Blender side fills a View from the scene camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LEVELS = ("fibers", "plies", "yarns", "surface")
#: The plying (plies per yarn, ply twist) the shipped yarn-level models were baked for (their "structure";
#: tests/addon/test_lod.py holds the two together).
YARN_MODEL_PLIES, YARN_MODEL_PLY_TWIST = 3, 0.5
#: Auto draws yarns where a ply is narrower than this many pixels (D52): in the evaluation harness's sweep of the
#: widths 1.38, 1.04 and 0.83 px under grazing, back, axis and key-rim light (and 13.8, 4.1 px before, where the
#: ply level is the better), the yarn level's FLIP is within 10 % of the best level's at 0.83 px under every light
#: but the back light and 10-27 % above the ply level's at 1.04 px under grazing and key-rim light, where the
#: plies' pattern (its period 1.56 ply widths) is still on screen. No width meets the goal under every light
#: (docs/benchmarks.md, "Level of detail").
YARNS_BELOW_PLY_PIXELS = 1.0
#: Auto draws explicit fibers only where a fiber itself is at least this wide: the ply model is the fibers'
#: mean look and cannot show single fibers. (The harness's close-ups do not reach fibers this wide, so this is
#: a judgement, not a measurement: a fiber two pixels wide is seen as a fiber.)
FIBERS_ABOVE_FIBER_PIXELS = 2.0
#: Auto splits an object whose yarns lie at different distances into two parts -- the yarns whose ply is at least
#: YARNS_BELOW_PLY_PIXELS wide as plies, the others as yarns -- once the far part holds at least this share of its
#: yarns. Below it the split saves less than a tenth of the object's ply curves, for a second object in the outliner
#: (a judgement; what a split saves is measured in docs/benchmarks.md, "One object in two parts").
SPLIT_MIN_FAR_SHARE = 0.1


@dataclass(frozen=True)
class View:
    """What the choice needs of a camera: its position and unit viewing direction (world units), "PERSP" with
    the field of view of the image's larger side (Blender's sensor fit Auto) or "ORTHO" with its ortho scale
    (the larger side's extent), and the render's size in pixels."""

    position: tuple
    forward: tuple
    kind: str
    fov: float
    ortho_scale: float
    width: int
    height: int


@dataclass(frozen=True)
class LevelChoice:
    level: str
    ply_pixels: float | None  # the widest ply's width on screen (None: no usable camera)
    warning: str | None
    #: Auto on an object split in two: the indices of the curves it draws as yarns (their ply under
    #: YARNS_BELOW_PLY_PIXELS wide, or behind the camera); the others get `level`. Empty: the whole object at `level`.
    far: tuple = ()


def _depths(points: np.ndarray, view: View) -> np.ndarray:
    """The points' distances in front of the camera along its viewing direction (negative: behind it)."""
    fwd = np.asarray(view.forward, dtype=np.float64)
    return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - np.asarray(view.position, dtype=np.float64)) @ (
        fwd / np.linalg.norm(fwd))


def _widths(ply_radius, depth: np.ndarray, view: View) -> np.ndarray:
    """The pinhole width in pixels of a ply of `ply_radius` (a number or one per point) at each depth; -inf behind
    the camera."""
    with np.errstate(divide="ignore"):
        if view.kind == "ORTHO":
            px = 2.0 * np.asarray(ply_radius, dtype=np.float64) * max(view.width, view.height) / view.ortho_scale
        else:
            px = 2.0 * np.asarray(ply_radius, dtype=np.float64) * max(view.width, view.height) / (
                2.0 * depth * math.tan(0.5 * view.fov))
    return np.where(depth > 0.0, np.broadcast_to(px, depth.shape), -np.inf)


def ply_pixels(points: np.ndarray, ply_radius: float, view: View, depth: np.ndarray | None = None) -> float | None:
    """Width in pixels of a ply of `ply_radius` at the nearest of `points` in front of the camera (None: every
    point is behind it). `depth`: the points' _depths, if known."""
    depth = _depths(points, view) if depth is None else depth
    widest = float(_widths(ply_radius, depth, view).max()) if depth.size else -math.inf
    return widest if math.isfinite(widest) else None


def curve_ply_pixels(points: np.ndarray, counts, ply_radius, view: View, depth: np.ndarray | None = None) -> np.ndarray:
    """Each curve's ply width in pixels at its nearest point in front of the camera, as ply_pixels gives it for the
    whole object: `points` (n, 3) holds the curves one after the other, `counts` their numbers of points (each >= 1),
    `ply_radius` is a number or one per point; `depth`: the points' _depths, if known. NaN for a curve wholly behind
    the camera."""
    counts = np.asarray(counts, dtype=np.int64)
    depth = _depths(points, view) if depth is None else depth
    if counts.size == 0 or np.any(counts < 1) or counts.sum() != depth.size:
        raise ValueError(f"{counts.size} curves of {int(counts.sum())} points do not hold {depth.size} points")
    widest = np.maximum.reduceat(_widths(ply_radius, depth, view), np.concatenate([[0], np.cumsum(counts)[:-1]]))
    return np.where(np.isfinite(widest), widest, np.nan)


def choose_level(points: np.ndarray, ply_radius, view: View | None, *, fiber_radius_ratio: float = 0.03,
                 requested: str = "auto", curve_counts=None) -> LevelChoice:
    """The level for one object: `requested` ("auto" or one of LEVELS) for the curve points `points` (n, 3)
    whose plies have radius `ply_radius` (a number or one per point; world units). Never raises for a bad
    camera: no camera, a zero resolution or a camera inside the cloth give plies (the look of fibers at any
    size) with one warning; an object behind the camera gets yarns; `surface` only when asked for.
    With `curve_counts` (the points of each curve, in order), Auto may split the object: the curves whose own
    ply is under YARNS_BELOW_PLY_PIXELS wide become `far` once they are SPLIT_MIN_FAR_SHARE of them."""
    if requested not in ("auto",) + LEVELS:
        raise ValueError(f"level of detail must be auto or one of {', '.join(LEVELS)}, got {requested!r}")
    if requested == "surface":  # asked for only: Auto never draws it (it is never as accurate as the yarn level)
        return LevelChoice("surface", None, None)
    radii = np.atleast_1d(np.asarray(ply_radius, dtype=np.float64))
    warning = None
    if radii.size == 0 or not np.all(np.isfinite(radii)) or np.any(radii <= 0):
        return LevelChoice("plies" if requested == "auto" else requested, None, "no usable ply radius: drawing plies")
    if radii.max() > 1.01 * radii.min():
        warning = f"mixed ply radii ({radii.min():.4g} to {radii.max():.4g}): chosen for the widest"
    if requested != "auto":
        return LevelChoice(requested, None, warning)
    if view is None:
        return LevelChoice("plies", None, "no scene camera: drawing plies")
    if view.width <= 0 or view.height <= 0:
        return LevelChoice("plies", None, f"render resolution {view.width} x {view.height}: drawing plies")
    bad = (view.kind == "PERSP" and not 0.0 < view.fov < math.pi) or (
        view.kind == "ORTHO" and not view.ortho_scale > 0.0) or view.kind not in ("PERSP", "ORTHO")
    if bad:
        return LevelChoice("plies", None, f"unusable camera ({view.kind}): drawing plies")
    depth = _depths(points, view)
    if view.kind == "PERSP" and (np.any(np.abs(depth) < 2.0 * radii.max()) or (np.any(depth > 0) and np.any(depth < 0))):
        return LevelChoice("plies", None, "the camera is inside the cloth: drawing plies")
    px = ply_pixels(points, float(radii.max()), view, depth)
    if px is None:
        return LevelChoice("yarns", None, "the object is behind the camera: drawing yarns")
    level = level_for_ply_pixels(px, fiber_radius_ratio)
    far = ()
    if curve_counts is not None and level != "yarns":
        per_curve = curve_ply_pixels(points, curve_counts, radii if radii.size > 1 else float(radii[0]), view, depth)
        far_curves = np.flatnonzero(~(per_curve >= YARNS_BELOW_PLY_PIXELS))  # NaN: behind the camera, unseen
        # (All of them can be far where the radii differ per point: the object's width is its widest ply at its
        # nearest point, a curve's its own. Then there is nothing to split: the object's level stands.)
        if SPLIT_MIN_FAR_SHARE * per_curve.size <= far_curves.size < per_curve.size:
            far = tuple(int(k) for k in far_curves)
    return LevelChoice(level, px, warning, far)


def level_for_ply_pixels(px: float, fiber_radius_ratio: float = 0.03) -> str:
    """Auto's level for a ply `px` pixels wide (the evaluation harness asks the same of its cameras)."""
    if px * fiber_radius_ratio >= FIBERS_ABOVE_FIBER_PIXELS:
        return "fibers"
    return "yarns" if px < YARNS_BELOW_PLY_PIXELS else "plies"
