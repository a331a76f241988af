# SPDX-License-Identifier: Apache-2.0
"""Periodic yarn patterns (Leaf et al. 2018 style): read one tile, repeat it, weld the yarns across tiles.

The official file format of the Leaf et al. corpus is not published with it. Supported:

* the "Num Yarns" text layout of the smallest periodic patch files seen in the wild:

      Num Yarns: N          <- header, the count is the last token
      n0                    <- points in yarn 0
      x y z                 <- n0 lines
      n1 ...

  blank lines and lines starting with '#' are ignored;
* a BCC file as the tile (dispatched on its first bytes);
* an optional JSON sidecar `<file>.json` (e.g. `rib.txt.json`, or `rib.json` next to `rib.txt`):
  {"period": [px, py], "yarn_radius": r, "units": "mm"}; arguments override it.

Tiles are translated by (i px, j py, 0); a yarn that leaves one tile enters the next, so its end point and
the start point of a copy in a neighbouring tile coincide. Welding joins such pairs into one control polygon,
so that a course yarn crossing n tiles becomes a single smooth curve instead of n curves with gaps.
"""
from __future__ import annotations

import json
import math
import os
from typing import Sequence

import numpy as np

from .bcc import _up_dimension, read_bcc_control_points, to_z_up
from .curves import (
    CURVE_TYPES,
    MAX_POINTS,
    GeometryError,
    YarnCurve,
    _as_points,
    _check_int,
    _check_positive,
    control_point_problem,
    evaluate_spline,
    evaluated_point_count,
    file_name,
    median_control_point_spacing,
    validate,
)

# A yarn's end - start displacement is "mostly along x" when |dx| >= this fraction of its length.
PERIOD_DIRECTION_COS = 0.9
# Default weld tolerance in yarn radii: far below the 2r that separates two distinct non-intersecting yarns,
# far above the rounding of text coordinates.
WELD_TOLERANCE_RADII = 0.25
MAX_TILES = 1000


def read_leaf_text(path: str | os.PathLike[str]) -> list[np.ndarray]:
    """Parses the "Num Yarns" text layout into one (n, 3) control-point array per yarn.

    Errors name the file and the line: a missing or non-integer count, a non-numeric or non-finite
    coordinate, fewer points than declared, fewer yarns than declared, or content after the last yarn.
    """
    name = file_name(path)
    try:
        with open(name, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise GeometryError(f"{name}: cannot read the file: {e.strerror or e}") from None
    lines = raw.decode("utf-8", errors="replace").splitlines()
    rows = [(k + 1, ln.split()) for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]

    def fail(line: int | None, msg: str) -> GeometryError:
        return GeometryError(f"{name}: line {line}: {msg}" if line is not None else f"{name}: {msg}")

    if not rows:
        raise fail(None, "empty file (expected a header 'Num Yarns: N')")
    line, tokens = rows[0]
    try:
        n_yarns = int(tokens[-1])
    except ValueError:
        raise fail(line, f"expected a header 'Num Yarns: N', the yarn count {tokens[-1]!r} is not an integer") from None
    if n_yarns < 1:
        raise fail(line, f"the header declares {n_yarns} yarns (must be >= 1)")

    yarns: list[np.ndarray] = []
    r = 1
    last_line = rows[-1][0]
    for y in range(n_yarns):
        if r >= len(rows):
            raise fail(None, f"the header declares {n_yarns} yarns, but the file ends after {y} (line {last_line})")
        line, tokens = rows[r]
        r += 1
        if len(tokens) != 1:
            hint = f" (does yarn {y - 1} have more points than it declares?)" if y > 0 and len(tokens) == 3 else ""
            raise fail(line, f"expected the point count of yarn {y}, got {len(tokens)} values{hint}")
        try:
            n = int(tokens[0])
        except ValueError:
            raise fail(line, f"the point count of yarn {y}, {tokens[0]!r}, is not an integer") from None
        if n < 1:
            raise fail(line, f"yarn {y} declares {n} points (must be >= 1)")
        pts = []
        for k in range(n):
            if r >= len(rows):
                raise fail(None, f"yarn {y} declares {n} points, but the file ends after {k} (line {last_line})")
            line, tokens = rows[r]
            if len(tokens) != 3:
                raise fail(
                    line,
                    f"yarn {y} declares {n} points but has only {k}: expected 'x y z', got {' '.join(tokens)!r}",
                )
            try:
                p = [float(t) for t in tokens]
            except ValueError:
                raise fail(line, f"yarn {y}, point {k}: non-numeric coordinate in {' '.join(tokens)!r}") from None
            if not all(math.isfinite(v) for v in p):
                raise fail(line, f"yarn {y}, point {k}: non-finite coordinate in {' '.join(tokens)!r}")
            pts.append(p)
            r += 1
        yarns.append(np.array(pts, dtype=np.float64))
    if r < len(rows):
        hint = f" (does yarn {n_yarns - 1} have more points than it declares?)" if len(rows[r][1]) == 3 else ""
        raise fail(rows[r][0], f"unexpected content after the last of the {n_yarns} declared yarns{hint}")
    return yarns


def sidecar_path(path: str | os.PathLike[str]) -> str | None:
    """The JSON sidecar of a pattern file: `<file>.json`, else `<stem>.json`; None if neither exists."""
    name = file_name(path)
    for cand in (name + ".json", os.path.splitext(name)[0] + ".json"):
        if cand != name and os.path.isfile(cand):
            return cand
    return None


def _sidecar_number(side: str, key: str, value, allow_zero: bool = False) -> float:
    """A sidecar's number, checked; the message names the file, then the key (not a key holding a path)."""
    try:
        return _check_positive(key, value, allow_zero=allow_zero)
    except GeometryError as e:
        raise GeometryError(f"{side}: {e}") from None


def read_leaf_sidecar(path: str | os.PathLike[str]) -> dict:
    """Tile metadata from the sidecar of `path`: {"period": (px, py) | None, "yarn_radius": r | None,
    "units": str | None}, all None when there is no sidecar. Unknown keys are errors (catches typos)."""
    out: dict = {"period": None, "yarn_radius": None, "units": None}
    side = sidecar_path(path)
    if side is None:
        return out
    try:
        with open(side, "rb") as f:
            meta = json.loads(f.read().decode("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise GeometryError(f"{side}: not a readable JSON sidecar: {e}") from None
    if not isinstance(meta, dict):
        raise GeometryError(f"{side}: the sidecar must be a JSON object")
    unknown = sorted(set(meta) - set(out))
    if unknown:
        raise GeometryError(f"{side}: unknown key(s) {unknown} (allowed: period, yarn_radius, units)")
    if meta.get("period") is not None:
        p = meta["period"]
        if not (isinstance(p, list) and len(p) == 2):
            raise GeometryError(f"{side}: 'period' must be a list [px, py], got {p!r}")
        out["period"] = tuple(_sidecar_number(side, "period", v, allow_zero=True) for v in p)
    if meta.get("yarn_radius") is not None:
        out["yarn_radius"] = _sidecar_number(side, "yarn_radius", meta["yarn_radius"])
    if meta.get("units") is not None:
        if not isinstance(meta["units"], str):
            raise GeometryError(f"{side}: 'units' must be a string, got {meta['units']!r}")
        out["units"] = meta["units"]
    return out


def estimate_period(control_curves: Sequence[np.ndarray]) -> tuple[float | None, float | None]:
    """Tile periods (px, py) from the yarns' end - start displacements; None where no yarn tells.

    In a periodic patch a yarn that leaves the tile re-enters it one period away, so its displacement is a
    lattice vector. px is the median |dx| over yarns whose displacement is mostly along x (|dx| >= 0.9 |d|),
    py likewise; yarns closed within the tile or running diagonally do not vote.
    """
    curves = [np.asarray(P, dtype=np.float64) for P in control_curves]
    if not curves:
        return None, None
    extent = float(np.ptp(np.concatenate(curves), axis=0).max()) if curves else 0.0
    votes: tuple[list[float], list[float]] = ([], [])
    for P in curves:
        d = P[-1] - P[0]
        norm = float(np.linalg.norm(d))
        if norm <= 1e-9 * max(extent, 1e-300):
            continue
        for axis in (0, 1):
            if abs(d[axis]) >= PERIOD_DIRECTION_COS * norm:
                votes[axis].append(abs(float(d[axis])))
    px = float(np.median(votes[0])) if votes[0] else None
    py = float(np.median(votes[1])) if votes[1] else None
    return px, py


def weld_endpoints(polygons: Sequence[np.ndarray], tolerance: float) -> list[tuple[np.ndarray, bool]]:
    """Joins open control polygons whose end and start lie within `tolerance`; returns (points, cyclic).

    Pairs are accepted greedily, nearest first, each end and each start at most once; a welded pair becomes
    one control point (their average). Chains that close on themselves become cyclic polygons.
    """
    n = len(polygons)
    if n == 0:
        return []
    for c, P in enumerate(polygons):
        if len(P) < 2:
            raise GeometryError(f"weld_endpoints: polygon {c} has {len(P)} point(s); at least 2 are needed")
    starts = np.array([P[0] for P in polygons])
    ends = np.array([P[-1] for P in polygons])
    # Spatial hash of the start points with cells of size tolerance: O(n) candidate search.
    # (Cells no smaller than 1e-12 of the coordinates' magnitude keep the integer keys far from overflow.)
    big = float(max(np.abs(starts).max(), np.abs(ends).max(), 1e-300))
    cell = max(tolerance, 1e-12 * big)
    grid: dict[tuple[int, int, int], list[int]] = {}
    keys = np.floor(starts / cell).astype(np.int64)
    for b, key in enumerate(map(tuple, keys)):
        grid.setdefault(key, []).append(b)
    pairs = []
    for a in range(n):
        ka = np.floor(ends[a] / cell).astype(np.int64)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for b in grid.get((int(ka[0] + dx), int(ka[1] + dy), int(ka[2] + dz)), ()):
                        dist = float(np.linalg.norm(ends[a] - starts[b]))
                        if dist <= tolerance and (b != a or len(polygons[a]) > 2):
                            pairs.append((dist, a, b))
    pairs.sort()
    succ = [-1] * n
    pred = [-1] * n
    for _, a, b in pairs:
        if succ[a] < 0 and pred[b] < 0:
            succ[a] = b
            pred[b] = a

    def join(chain: list[int], cyclic: bool) -> tuple[np.ndarray, bool]:
        pts = [np.asarray(polygons[chain[0]], dtype=np.float64)]
        for b in chain[1:]:
            Q = np.asarray(polygons[b], dtype=np.float64)
            weld = 0.5 * (pts[-1][-1] + Q[0])
            pts[-1] = np.concatenate([pts[-1][:-1], weld[None]])
            pts.append(Q[1:])
        P = np.concatenate(pts)
        if cyclic:
            P[0] = 0.5 * (P[0] + P[-1])
            P = P[:-1]
        return P, cyclic

    out = []
    done = [False] * n
    for a in range(n):
        if pred[a] < 0:
            chain = [a]
            done[a] = True
            while succ[chain[-1]] >= 0:
                chain.append(succ[chain[-1]])
                done[chain[-1]] = True
            out.append(join(chain, False))
    for a in range(n):  # what is left are cycles
        if not done[a]:
            chain = [a]
            done[a] = True
            while not done[succ[chain[-1]]]:
                chain.append(succ[chain[-1]])
                done[chain[-1]] = True
            out.append(join(chain, True))
    return out


def tile_pattern(
    control_curves: Sequence[np.ndarray],
    nx: int,
    ny: int,
    period: tuple[float, float] | None = None,
    weld_tolerance: float | None = None,
    curve_type: str = "C0",
    *,
    closed: Sequence[bool] | None = None,
    yarn_radius: float | None = None,
    samples_per_segment: int = 8,
    scale: float = 1.0,
) -> list[YarnCurve]:
    """Repeats a periodic tile nx x ny times in the XY plane, welds yarns across tiles, evaluates splines.

    control_curves: the tile's control polygons (Z-up). period (px, py) defaults to `estimate_period`;
    GeometryError if a needed period (nx > 1 needs px, ny > 1 needs py) cannot be estimated.
    yarn_radius defaults to 0.5 x the median control-point spacing (as for BCC). weld_tolerance defaults to
    0.25 yarn radii. closed flags (e.g. from a BCC tile) mark loops that are copied but never welded.
    Coordinates, radius and tolerance are in pattern units; `scale` is applied to the result.
    """
    if curve_type not in CURVE_TYPES:
        raise GeometryError(f"parameter 'curve_type' must be one of {', '.join(CURVE_TYPES)}, got {curve_type!r}")
    nx = _check_int("nx", nx, 1, MAX_TILES)
    ny = _check_int("ny", ny, 1, MAX_TILES)
    scale = _check_positive("scale", scale)
    samples_per_segment = _check_int("samples_per_segment", samples_per_segment, 1, 1000)
    curves = [_as_points(f"yarn {c}", P) for c, P in enumerate(control_curves)]
    if not curves:
        raise GeometryError("the pattern has no yarns")
    flags = [False] * len(curves) if closed is None else [bool(f) for f in closed]
    if len(flags) != len(curves):
        raise GeometryError(f"parameter 'closed' has {len(flags)} flags for {len(curves)} yarns")
    for c, P in enumerate(curves):
        if len(P) < 2:
            raise GeometryError(f"yarn {c} has {len(P)} control point; a pattern yarn needs at least 2")

    if period is None:
        px, py = estimate_period([P for P, f in zip(curves, flags) if not f])
        if nx > 1 and px is None:
            raise GeometryError(
                "cannot estimate the x period: no yarn's end - start displacement runs mostly along x; "
                "pass period=(px, py) or add a sidecar with \"period\""
            )
        if ny > 1 and py is None:
            raise GeometryError(
                "cannot estimate the y period: no yarn's end - start displacement runs mostly along y; "
                "pass period=(px, py) or add a sidecar with \"period\""
            )
        px, py = px or 0.0, py or 0.0
    else:
        try:
            px, py = (float(v) for v in period)
        except (TypeError, ValueError):
            raise GeometryError(f"parameter 'period' must be a pair (px, py), got {period!r}") from None
        for label, v, needed in (("px", px, nx > 1), ("py", py, ny > 1)):
            if not math.isfinite(v) or (needed and v <= 0.0):
                raise GeometryError(f"parameter 'period': {label} = {v!r} must be finite and > 0")

    if yarn_radius is None:
        # 0 only if every yarn's control points coincide; `validate` below then names the first curve.
        yarn_radius = 0.5 * median_control_point_spacing(curves, flags) or 1.0
    else:
        yarn_radius = _check_positive("yarn_radius", yarn_radius)
    tol = WELD_TOLERANCE_RADII * yarn_radius if weld_tolerance is None else _check_positive(
        "weld_tolerance", weld_tolerance, allow_zero=True
    )
    total_cp = sum(len(P) for P in curves) * nx * ny
    if total_cp * max(samples_per_segment, 1) > MAX_POINTS:
        raise GeometryError(
            f"tiling {nx} x {ny} copies of {len(curves)} yarns would exceed {MAX_POINTS} evaluated points"
        )

    open_copies: list[np.ndarray] = []
    loops: list[np.ndarray] = []
    for j in range(ny):
        for i in range(nx):
            shift = np.array([i * px, j * py, 0.0])
            for P, f in zip(curves, flags):
                (loops if f else open_copies).append(P + shift)
    joined = weld_endpoints(open_copies, tol) + [(P, True) for P in loops]

    out = []
    for c, (P, cyc) in enumerate(joined):
        problem = control_point_problem(curve_type, len(P), cyc)
        if problem:
            raise GeometryError(f"tiled yarn {c} (after welding): {problem}")
        if evaluated_point_count(curve_type, len(P), cyc, samples_per_segment) > MAX_POINTS:
            raise GeometryError(f"tiled yarn {c} would exceed {MAX_POINTS} evaluated points")
        pts = evaluate_spline(P, curve_type, cyc, samples_per_segment) * scale
        out.append(YarnCurve(pts, np.full(len(pts), yarn_radius * scale), cyc))
    validate(out, source="tiled pattern")
    return out


def read_leaf(
    path: str | os.PathLike[str],
    *,
    nx: int = 1,
    ny: int = 1,
    period: tuple[float, float] | None = None,
    yarn_radius: float | None = None,
    weld_tolerance: float | None = None,
    curve_type: str | None = None,
    samples_per_segment: int = 8,
    scale: float = 1.0,
    up_axis: str | int = "auto",
) -> list[YarnCurve]:
    """Loads a periodic tile (a BCC file or the "Num Yarns" text layout, told apart by the first bytes),
    takes period and radius from the arguments, else the sidecar, else the BCCX trailer, else estimates,
    and tiles it nx x ny (see `tile_pattern`). curve_type defaults to the BCC header's, or 'C0' for text.
    BCC tiles are converted to Z-up first, so periods always refer to Blender's X and Y."""
    name = file_name(path)
    try:
        with open(name, "rb") as f:
            magic = f.read(3)
    except OSError as e:
        raise GeometryError(f"{name}: cannot read the file: {e.strerror or e}") from None
    bccx_radius = None
    if magic == b"BCC":
        raw = read_bcc_control_points(name)
        up = _up_dimension(up_axis, raw.up_dimension)
        controls = [to_z_up(P, up) for P in raw.control_points]
        closed = list(raw.closed)
        default_type = raw.curve_type
        bccx_radius = raw.bccx_radius
    else:
        controls = read_leaf_text(name)
        closed = [False] * len(controls)
        default_type = "C0"
    meta = read_leaf_sidecar(name)
    if period is None:
        period = meta["period"]
    if yarn_radius is None:
        yarn_radius = meta["yarn_radius"] if meta["yarn_radius"] is not None else bccx_radius
    try:
        return tile_pattern(
            controls,
            nx,
            ny,
            period,
            weld_tolerance,
            curve_type or default_type,
            closed=closed,
            yarn_radius=yarn_radius,
            samples_per_segment=samples_per_segment,
            scale=scale,
        )
    except GeometryError as e:
        raise GeometryError(f"{name}: {e}") from None
