# SPDX-License-Identifier: Apache-2.0
"""BCC (Binary Curve Collection, Cem Yuksel) reader and writer, with the BCCX trailer.

Layout (Cem Yuksel's BCC format, cyCodeBase; the BCCX trailer as his yarn-level cloth models use it),
little-endian, no padding:

    header, 64 bytes: char[3] "BCC" | uint8 byteCount = 0x44 | char[2] curveType (C0, PL, BS, BZ) |
                      uint8 dimensions = 3 | uint8 upDimension (1 = Y-up, 2 = Z-up) |
                      uint64 curveCount | uint64 totalControlPointCount | char[40] fileInfo
    body, per curve:  int32 n (n < 0: closed loop of |n| points) | |n| x float32[3]
    BCCX trailer:     float32 yarn radius | float32[3] velocity per control point |
                      float32 rest length per control point        (optional)

The reader is written for untrusted files: every count is checked against the file size before anything
is allocated, and every problem is a GeometryError naming the file and, in the body, the curve.
"""
from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass, field
from typing import Sequence, Union

import numpy as np

from .curves import (
    CURVE_TYPES,
    MAX_POINTS,
    GeometryError,
    YarnCurve,
    _as_points,
    _check_int,
    _check_positive,
    control_point_problem,
    evaluate_splines,
    evaluated_point_count,
    file_name,
    median_control_point_spacing,
    validate,
    yarn_radius_from_passes,
)

HEADER_SIZE = 64
BYTE_COUNT = 0x44  # 4-byte integers (high nibble), 4-byte floats (low nibble)
_HEADER = struct.Struct("<3sB2sBBQQ40s")
assert _HEADER.size == HEADER_SIZE

# Y-up file coordinates -> Blender Z-up: (x, y, z) -> (x, -z, y). A proper rotation (+90 deg about x),
# so handedness, and hence the twist direction of plies and fibers, is preserved.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

PathOrBytes = Union[str, "os.PathLike[str]", bytes, bytearray, memoryview]


@dataclass
class BCCData:
    """The raw content of a BCC file: control points exactly as stored (file axes, file units)."""

    curve_type: str
    up_dimension: int  # 1 = Y-up, 2 = Z-up
    file_info: str
    control_points: list[np.ndarray] = field(default_factory=list)  # float64 (n, 3) per curve
    closed: list[bool] = field(default_factory=list)
    bccx_radius: float | None = None  # BCCX trailer, when present
    bccx_velocities: np.ndarray | None = None  # (total, 3)
    bccx_rest_lengths: np.ndarray | None = None  # (total,)


def _load(path_or_bytes: PathOrBytes) -> tuple[bytes, str]:
    if isinstance(path_or_bytes, (bytes, bytearray, memoryview)):
        return bytes(path_or_bytes), "<BCC data>"
    name = file_name(path_or_bytes)
    try:
        with open(name, "rb") as f:
            return f.read(), str(name)
    except OSError as e:
        raise GeometryError(f"{name}: cannot read the file: {e.strerror or e}") from None


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def read_bcc_control_points(path_or_bytes: PathOrBytes) -> BCCData:
    """Parses a BCC/BCCX file without evaluating it: header fields and control points as stored.

    Checks everything about the *format* (signature, header fields, counts against the file size, truncation,
    non-finite coordinates, zero-point curves, trailing bytes) but nothing about the *geometry*, so the
    1-point minimal file (one curve of one control point) parses here while `read_bcc` rejects it.
    """
    data, src = _load(path_or_bytes)
    size = len(data)

    def fail(msg: str) -> GeometryError:
        return GeometryError(f"{src}: {msg}")

    if size == 0:
        raise fail("empty file (a BCC header needs 64 bytes)")
    if data[:3] != b"BCC"[: min(size, 3)]:
        raise fail(f"not a BCC file: the signature is {data[:3]!r}, expected b'BCC'")
    if size < HEADER_SIZE:
        raise fail(
            f"truncated header: the file has {_plural(size, 'byte')}, a BCC header needs {HEADER_SIZE} "
            f"({HEADER_SIZE - size} bytes missing)"
        )
    _, byte_count, ctype_raw, dims, up, curve_count, total, info_raw = _HEADER.unpack_from(data, 0)
    if byte_count != BYTE_COUNT:
        raise fail(f"unsupported byteCount 0x{byte_count:02X} in the header (only 0x44: 4-byte ints and floats)")
    ctype = ctype_raw.decode("latin-1")
    if ctype not in CURVE_TYPES:
        raise fail(f"unknown curve type {ctype_raw!r} in the header (expected one of {', '.join(CURVE_TYPES)})")
    if dims != 3:
        raise fail(f"unsupported dimensions = {dims} in the header (only 3)")
    if up not in (1, 2):
        raise fail(f"bad up dimension {up} in the header (expected 1 = Y-up or 2 = Z-up)")
    info = info_raw.split(b"\0", 1)[0].decode("utf-8", errors="replace").strip()

    body = size - HEADER_SIZE
    # Each curve needs at least its 4-byte count, each control point 12 bytes. Nothing is ever allocated
    # from the header's counts (each curve's array is bounded by the bytes actually left), so counts the file
    # cannot hold are reported as absurd only once the curves themselves turn out complete; a file that is
    # merely cut short gets the more useful "truncated body: curve c" message instead.
    curves_absurd = curve_count > body // 4
    total_absurd = total > (body - 4 * min(curve_count, body // 4)) // 12

    out = BCCData(ctype, int(up), info)
    pos = HEADER_SIZE
    seen = 0
    starts: list[int] = []  # byte offset of each curve's first control point
    sizes: list[int] = []
    for c in range(curve_count):
        left = size - pos
        if left == 0 and curves_absurd:
            raise fail(
                f"the header declares {curve_count} curves, but the {body} body bytes can hold at most {body // 4}; "
                f"the file ends after {_plural(c, 'complete curve')} (absurd curveCount)"
            )
        if left < 4:
            raise fail(
                f"truncated body: curve {c} of {curve_count} is missing its point count "
                f"({4 - left} bytes missing)"
            )
        n = int.from_bytes(data[pos : pos + 4], "little", signed=True)
        pos += 4
        if n == 0:
            raise fail(f"curve {c} has a control point count of 0")
        m = abs(n)
        need = 12 * m
        left = size - pos
        if need > left:
            raise fail(
                f"truncated body: curve {c} of {curve_count} declares {_plural(m, 'control point')} "
                f"({need} bytes), but only {left} bytes remain ({need - left} bytes missing)"
            )
        if seen + m > total:
            raise fail(
                f"count mismatch: curve {c} brings the control points to {seen + m}, more than the header's "
                f"totalControlPointCount {total}"
            )
        starts.append(pos)
        sizes.append(m)
        pos += need
        seen += m
        out.closed.append(n < 0)
    if seen != total:
        absurd = (
            f"; {total} is more than the {body} body bytes could hold (absurd totalControlPointCount)"
            if total_absurd
            else ""
        )
        raise fail(
            f"count mismatch: the curves hold {seen} control points, but the header's totalControlPointCount "
            f"is {total}{absurd}"
        )

    # All control points in one gather (a per-curve frombuffer costs more than the whole parse for 300 k
    # short curves), then one array view per curve.
    if sizes:
        counts = np.asarray(sizes, dtype=np.int64)
        point_bytes = np.repeat(np.asarray(starts, dtype=np.int64), counts) + 12 * (
            np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts))
        with np.errstate(invalid="ignore"):  # signalling NaNs in the file are reported just below
            floats = np.frombuffer(data, dtype="<f4", count=len(data) // 4)  # (64-byte header, 4-byte counts: aligned)
            pts = floats[(point_bytes // 4)[:, None] + np.arange(3)].astype(np.float64)
        finite = np.isfinite(pts).all(axis=1)
        if not finite.all():
            k = int(np.argmin(finite))
            c = int(np.searchsorted(np.cumsum(counts), k, side="right"))
            j = k - int(np.cumsum(counts)[c] - counts[c])
            raise fail(f"curve {c}, control point {j} has a non-finite coordinate {pts[k].tolist()}")
        out.control_points = np.split(pts, np.cumsum(counts)[:-1])
    rest = size - pos
    bccx = 4 + 16 * total
    if rest == bccx:
        radius = struct.unpack_from("<f", data, pos)[0]
        if not (math.isfinite(radius) and radius > 0.0):
            raise fail(f"BCCX trailer: yarn radius {radius} must be finite and > 0")
        out.bccx_radius = float(radius)
        with np.errstate(invalid="ignore"):  # stored as read; not used for geometry
            out.bccx_velocities = np.frombuffer(data, "<f4", 3 * total, pos + 4).reshape(total, 3).astype(np.float64)
            out.bccx_rest_lengths = np.frombuffer(data, "<f4", total, pos + 4 + 12 * total).astype(np.float64)
    elif rest != 0:
        raise fail(
            f"{_plural(rest, 'trailing byte')} after the last curve (not a BCCX trailer, which would be "
            f"{bccx} bytes for {total} control points)"
        )
    return out


def _up_dimension(up_axis: object, header_up: int) -> int:
    if isinstance(up_axis, str):
        key = up_axis.strip().upper()
        if key == "AUTO":
            return header_up
        if key in ("Y", "Y-UP", "Y_UP"):
            return 1
        if key in ("Z", "Z-UP", "Z_UP"):
            return 2
    elif not isinstance(up_axis, bool) and up_axis in (1, 2):
        return int(up_axis)  # type: ignore[arg-type]
    raise GeometryError(f"parameter 'up_axis' must be 'auto', 'Y' or 'Z' (or 1, 2), got {up_axis!r}")


def to_z_up(points: np.ndarray, up_dimension: int) -> np.ndarray:
    """File coordinates -> Blender Z-up: unchanged for Z-up files, (x, -z, y) for Y-up files."""
    return points @ Y_UP_TO_Z_UP.T if up_dimension == 1 else np.array(points, dtype=np.float64)


def read_bcc(
    path_or_bytes: PathOrBytes,
    *,
    scale: float = 1.0,
    yarn_radius: float | None = None,
    samples_per_segment: int = 8,
    up_axis: str | int = "auto",
    progress=None,
) -> list[YarnCurve]:
    """Reads a BCC/BCCX file into evaluated, Z-up, validated yarn curves (one per file curve, in order).

    scale multiplies coordinates and radii (file units -> scene units). up_axis 'auto' follows the header;
    'Y' or 'Z' overrides a wrong header. yarn_radius is in file units; when None, the BCCX trailer's radius
    is used, else the radius at which neighbouring yarn passes touch (yarn_radius_from_passes: relaxed
    yarn-level models are simulated with yarn contact), else 0.5 x the median control-point spacing. BCC stores
    no radius (nor units).
    Raises GeometryError for malformed files and for curves too short or degenerate to render. `progress`,
    if given, is called with the fraction done (0 to 1) after each stage (parse, evaluate, curves, checks).
    """
    report = progress if progress is not None else (lambda fraction: None)
    scale = _check_positive("scale", scale)
    if yarn_radius is not None:
        yarn_radius = _check_positive("yarn_radius", yarn_radius)
    samples_per_segment = _check_int("samples_per_segment", samples_per_segment, 1, 1000)
    raw = read_bcc_control_points(path_or_bytes)
    report(0.25)
    src = "<BCC data>" if isinstance(path_or_bytes, (bytes, bytearray, memoryview)) else os.fspath(path_or_bytes)
    up = _up_dimension(up_axis, raw.up_dimension)
    if not raw.control_points:
        raise GeometryError(f"{src}: the file contains no curves")

    n_points = 0
    for c, (P, cyc) in enumerate(zip(raw.control_points, raw.closed)):
        problem = control_point_problem(raw.curve_type, len(P), cyc)
        if problem:
            raise GeometryError(f"{src}: curve {c}: {problem}")
        n_points += evaluated_point_count(raw.curve_type, len(P), cyc, samples_per_segment)
    if n_points > MAX_POINTS:
        raise GeometryError(
            f"{src}: {n_points} evaluated points exceed the limit of {MAX_POINTS}; lower 'samples_per_segment' "
            f"(now {samples_per_segment})"
        )

    evaluated = evaluate_splines([to_z_up(P, up) for P in raw.control_points], raw.curve_type, raw.closed,
                                 samples_per_segment)
    report(0.4)
    if yarn_radius is not None:
        radius = yarn_radius
    elif raw.bccx_radius is not None:
        radius = raw.bccx_radius
    else:
        # Where neighbouring passes touch; else half the control-point spacing (0 only if every curve's points
        # coincide: `validate` below then names the first curve).
        radius = (yarn_radius_from_passes(evaluated) or
                  0.5 * median_control_point_spacing(raw.control_points, raw.closed) or 1.0)
    radius *= scale
    report(0.5)
    curves = [YarnCurve(pts * scale, np.full(len(pts), radius), cyc) for pts, cyc in zip(evaluated, raw.closed)]
    report(0.75)
    validate(curves, source=src)
    report(1.0)
    return curves


def bcc_bytes(
    control_point_curves: Sequence[np.ndarray],
    curve_type: str = "C0",
    up: int = 2,
    closed: bool | Sequence[bool] = False,
    *,
    file_info: str = "neuralyarn",
    yarn_radius: float | None = None,
) -> bytes:
    """Encodes curves as BCC (or BCCX, when yarn_radius is given) bytes; see `write_bcc`."""
    if curve_type not in CURVE_TYPES:
        raise GeometryError(f"parameter 'curve_type' must be one of {', '.join(CURVE_TYPES)}, got {curve_type!r}")
    if isinstance(up, bool) or up not in (1, 2):
        raise GeometryError(f"parameter 'up' must be 1 (Y-up) or 2 (Z-up), got {up!r}")
    curves = [_as_points(f"curve {c}", P) for c, P in enumerate(control_point_curves)]
    flags = [bool(closed)] * len(curves) if isinstance(closed, (bool, np.bool_)) else [bool(f) for f in closed]
    if len(flags) != len(curves):
        raise GeometryError(f"parameter 'closed' has {len(flags)} flags for {len(curves)} curves")
    for c, (P, cyc) in enumerate(zip(curves, flags)):
        problem = control_point_problem(curve_type, len(P), cyc)
        if problem:
            raise GeometryError(f"curve {c}: {problem}")
        if len(P) > 2**31 - 1:
            raise GeometryError(f"curve {c}: {len(P)} control points do not fit the int32 count")
        if np.any(np.abs(P) > np.finfo(np.float32).max):
            raise GeometryError(f"curve {c}: coordinates overflow float32")
    info = file_info.encode("utf-8")
    if len(info) > 40:
        raise GeometryError(f"parameter 'file_info' is {len(info)} bytes long, the header holds 40")
    total = sum(len(P) for P in curves)
    parts = [_HEADER.pack(b"BCC", BYTE_COUNT, curve_type.encode("ascii"), 3, up, len(curves), total, info)]
    for P, cyc in zip(curves, flags):
        n = -len(P) if cyc else len(P)
        parts.append(struct.pack("<i", n))
        parts.append(np.ascontiguousarray(P, dtype="<f4").tobytes())
    if yarn_radius is not None:
        r = _check_positive("yarn_radius", yarn_radius)
        parts.append(struct.pack("<f", r))
        parts.append(np.zeros((total, 3), dtype="<f4").tobytes())  # velocities: a static model
        rest = []
        for P, cyc in zip(curves, flags):
            nxt = np.roll(P, -1, axis=0)
            gap = np.linalg.norm(nxt - P, axis=1)
            if not cyc:
                gap[-1] = 0.0  # the last point of an open curve has no successor
            rest.append(gap)
        if rest:
            parts.append(np.concatenate(rest).astype("<f4").tobytes())
    return b"".join(parts)


def write_bcc(
    path: str | os.PathLike[str],
    control_point_curves: Sequence[np.ndarray],
    curve_type: str = "C0",
    up: int = 2,
    closed: bool | Sequence[bool] = False,
    *,
    file_info: str = "neuralyarn",
    yarn_radius: float | None = None,
) -> None:
    """Writes control points verbatim (no axis conversion) as a BCC file labelled with `up`.

    closed is one flag for all curves or one per curve (stored as a negative count). Control point counts
    must suit curve_type (the same rule `read_bcc` applies), so everything written can be read back. A
    yarn_radius adds a BCCX trailer (zero velocities, rest lengths = distance to the next control point).
    """
    blob = bcc_bytes(
        control_point_curves, curve_type=curve_type, up=up, closed=closed, file_info=file_info, yarn_radius=yarn_radius
    )
    try:
        with open(os.fspath(path), "wb") as f:
            f.write(blob)
    except OSError as e:
        raise GeometryError(f"{os.fspath(path)}: cannot write the file: {e.strerror or e}") from None
