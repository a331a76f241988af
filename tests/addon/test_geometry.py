# SPDX-License-Identifier: Apache-2.0
"""Tests of addon/geometry (imported as the top-level package `geometry`, see conftest.py).

Plain Python + numpy, no Blender. Every file is written by the test itself into tmp_path.
"""
import json
import math
import os
import struct
import subprocess
import time
import tracemalloc

import numpy as np
import pytest

import geometry as geo
from geometry import GeometryError, YarnCurve

# ---------------------------------------------------------------------------------------------------------
# helpers

HEADER = struct.Struct("<3sB2sBBQQ40s")


def raw_bcc(curves, *, sign=b"BCC", byte_count=0x44, ctype=b"C0", dims=3, up=2, n_curves=None, total=None,
            info=b"", closed=None, counts=None, trailer=b""):
    """Builds BCC bytes field by field, so that tests can write any malformed variant."""
    closed = closed or [False] * len(curves)
    n_curves = len(curves) if n_curves is None else n_curves
    total = sum(len(c) for c in curves) if total is None else total
    out = [HEADER.pack(sign, byte_count, ctype, dims, up, n_curves, total, info)]
    for k, (c, cl) in enumerate(zip(curves, closed)):
        n = counts[k] if counts is not None else (-len(c) if cl else len(c))
        out.append(struct.pack("<i", n))
        out.append(np.asarray(c, dtype="<f4").tobytes())
    return b"".join(out) + trailer


def wiggly(n, seed=0):
    """An asymmetric open curve with distinct, roughly evenly spaced control points."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=np.float64)
    return np.stack([t, 0.3 * np.sin(t) + 0.1 * rng.standard_normal(n), 0.2 * t * t / n + 0.5], axis=1)


def min_distance(A, B, chunk=2048):
    """Smallest distance between two point sets (brute force, chunked)."""
    best = math.inf
    for i in range(0, len(A), chunk):
        d = np.linalg.norm(A[i:i + chunk, None, :] - B[None, :, :], axis=2)
        best = min(best, float(d.min()))
    return best


def expect_error(fn, *fragments):
    with pytest.raises(GeometryError) as e:
        fn()
    msg = str(e.value)
    for f in fragments:
        assert f in msg, f"{f!r} not in {msg!r}"
    return msg


# ---------------------------------------------------------------------------------------------------------
# BCC: the minimal test vector and its variants (yarn_geometry.md §1.6)

MINIMAL = bytes.fromhex("424343" "44" "4330" "03" "02") + struct.pack("<QQ", 1, 1) + bytes(40) + \
    struct.pack("<i3f", 1, 0.0, 1.0, 2.0)


def test_minimal_vector_parses_low_level():
    assert len(MINIMAL) == 80
    d = geo.read_bcc_control_points(MINIMAL)
    assert (d.curve_type, d.up_dimension, d.file_info) == ("C0", 2, "")
    assert len(d.control_points) == 1 and d.closed == [False]
    np.testing.assert_array_equal(d.control_points[0], [[0.0, 1.0, 2.0]])
    assert d.bccx_radius is None


def test_minimal_vector_is_rejected_for_rendering():
    # One control point is no curve: read_bcc explains why instead of returning a zero-length curve.
    expect_error(lambda: geo.read_bcc(MINIMAL), "curve 0", "1 control point", "at least 4")


def test_minimal_vector_variants():
    pts = [[0.0, 1.0, 2.0], [1.0, 1.0, 2.0], [1.0, 2.0, 2.0]]
    d = geo.read_bcc_control_points(raw_bcc([pts], closed=[True]))
    assert d.closed == [True] and len(d.control_points[0]) == 3
    d = geo.read_bcc_control_points(raw_bcc([pts[:2]], ctype=b"PL", up=1))
    assert (d.curve_type, d.up_dimension) == ("PL", 1)
    # Garbage fileInfo: no NUL at all, not UTF-8.
    d = geo.read_bcc_control_points(raw_bcc([pts], info=bytes(range(200, 240))))
    assert isinstance(d.file_info, str)
    d = geo.read_bcc_control_points(raw_bcc([pts], info=b"Cem Yuksel 2010\0\xff\xfe garbage"))
    assert d.file_info == "Cem Yuksel 2010"
    expect_error(lambda: geo.read_bcc_control_points(MINIMAL[:-1]), "truncated body", "curve 0", "1 bytes missing")


# ---------------------------------------------------------------------------------------------------------
# BCC round trips


@pytest.mark.parametrize("closed", [False, True])
def test_roundtrip_c0(tmp_path, closed):
    P = wiggly(9)
    path = tmp_path / "c0.bcc"
    geo.write_bcc(path, [P, P[:6] + 5.0], curve_type="C0", closed=closed)
    raw = geo.read_bcc_control_points(path)
    assert raw.closed == [closed, closed]
    np.testing.assert_allclose(raw.control_points[0], P, rtol=1e-6, atol=1e-6)  # float32 on disk
    curves = geo.read_bcc(path, samples_per_segment=5)
    assert len(curves) == 2 and all(c.cyclic == closed for c in curves)
    n_seg = 9 if closed else 6
    assert len(curves[0].points) == n_seg * 5 + (0 if closed else 1)
    expected = geo.catmull_rom(raw.control_points[0], closed, 5)
    np.testing.assert_allclose(curves[0].points, expected, atol=1e-12)


def test_roundtrip_polyline_and_other_types(tmp_path):
    P = wiggly(7)
    path = tmp_path / "pl.bcc"
    geo.write_bcc(path, [P], curve_type="PL", file_info="test")
    c = geo.read_bcc(path)[0]
    np.testing.assert_allclose(c.points, P.astype(np.float32), rtol=0, atol=0)
    assert geo.read_bcc_control_points(path).file_info == "test"
    for ctype, n in (("BS", 7), ("BZ", 7)):
        geo.write_bcc(path, [P[:n]], curve_type=ctype)
        c = geo.read_bcc(path, samples_per_segment=4)[0]
        np.testing.assert_allclose(c.points, geo.evaluate_spline(P[:n].astype(np.float32), ctype, False, 4), atol=1e-12)


def test_y_up_is_converted_to_blender_z_up(tmp_path):
    P = np.array([[1.0, 2.0, 3.0], [4.0, 7.0, -5.0], [-2.0, 0.5, 9.0]])  # asymmetric in every axis
    path = tmp_path / "yup.bcc"
    geo.write_bcc(path, [P], curve_type="PL", up=1)
    c = geo.read_bcc(path)[0]
    np.testing.assert_allclose(c.points, np.stack([P[:, 0], -P[:, 2], P[:, 1]], axis=1))
    # A proper rotation: the triple product (handedness) is preserved.
    e = np.diff(P, axis=0)
    f = np.diff(c.points, axis=0)
    assert np.linalg.det(geo.to_z_up(np.eye(3), 1)) == pytest.approx(1.0)
    assert np.isclose(np.linalg.norm(np.cross(e[0], e[1])), np.linalg.norm(np.cross(f[0], f[1])))
    np.testing.assert_allclose(np.cross(f[0], f[1]), geo.to_z_up(np.cross(e[0], e[1])[None], 1)[0])
    # Overrides: a wrongly labelled file can be read as Z-up verbatim.
    np.testing.assert_allclose(geo.read_bcc(path, up_axis="Z")[0].points, P)
    geo.write_bcc(path, [P], curve_type="PL", up=2)
    np.testing.assert_allclose(geo.read_bcc(path, up_axis="Y")[0].points, c.points)
    expect_error(lambda: geo.read_bcc(path, up_axis="X"), "up_axis")


def test_bccx_trailer_radius_and_defaults(tmp_path):
    P = wiggly(8)
    path = tmp_path / "x.bcc"
    geo.write_bcc(path, [P, P + 3.0], curve_type="C0", closed=[False, True], yarn_radius=0.3)
    raw = geo.read_bcc_control_points(path)
    assert raw.bccx_radius == pytest.approx(0.3, rel=1e-7)
    assert raw.bccx_velocities.shape == (16, 3) and not raw.bccx_velocities.any()
    gaps = np.linalg.norm(np.diff(P, axis=0), axis=1)
    np.testing.assert_allclose(raw.bccx_rest_lengths[:7], gaps, rtol=1e-6)
    assert raw.bccx_rest_lengths[7] == 0.0  # open curve: last point has no successor
    assert raw.bccx_rest_lengths[15] == pytest.approx(np.linalg.norm(P[0] - P[-1]), rel=1e-6)  # closed wraps
    curves = geo.read_bcc(path)
    assert all(np.allclose(c.radius, 0.3) for c in curves)
    # An explicit radius wins; scale applies to coordinates and radius alike.
    curves2 = geo.read_bcc(path, yarn_radius=0.1, scale=2.0)
    assert np.allclose(curves2[0].radius, 0.2)
    np.testing.assert_allclose(curves2[0].points, 2.0 * curves[0].points)
    # Without a trailer: half the median control-point spacing.
    geo.write_bcc(path, [P], curve_type="C0")
    assert np.allclose(geo.read_bcc(path)[0].radius, 0.5 * np.median(gaps), rtol=1e-6)


# ---------------------------------------------------------------------------------------------------------
# BCC: malformed files

GOOD = [wiggly(5), wiggly(6, 1)]


@pytest.mark.parametrize("blob, fragments", [
    (b"", ["empty file"]),
    (b"BCX" + bytes(100), ["not a BCC file", "signature"]),
    (b"PK\x03\x04", ["not a BCC file"]),
    (raw_bcc(GOOD)[:40], ["truncated header", "40 bytes", "24 bytes missing"]),
    (raw_bcc(GOOD, byte_count=0x48), ["byteCount", "0x48"]),
    (raw_bcc(GOOD, dims=2), ["dimensions = 2"]),
    (raw_bcc(GOOD, ctype=b"XX"), ["unknown curve type", "XX"]),
    (raw_bcc(GOOD, up=3), ["bad up dimension 3"]),
    (raw_bcc(GOOD, up=0), ["bad up dimension 0"]),
    (raw_bcc(GOOD)[:-7], ["truncated body", "curve 1 of 2", "7 bytes missing"]),
    (raw_bcc(GOOD)[:64 + 4 + 60 + 2], ["truncated body", "curve 1 of 2", "missing its point count", "2 bytes missing"]),
    (raw_bcc(GOOD, total=12), ["count mismatch", "12"]),
    (raw_bcc(GOOD, total=10), ["count mismatch", "curve 1", "10"]),
    (raw_bcc(GOOD, n_curves=2**63), ["absurd curveCount"]),
    (raw_bcc(GOOD, n_curves=1000), ["absurd curveCount", "1000 curves"]),
    (raw_bcc(GOOD, total=2**62), ["absurd totalControlPointCount"]),
    (raw_bcc(GOOD, counts=[5, 2**31 - 1]), ["truncated body", "curve 1", "2147483647 control points"]),
    (raw_bcc(GOOD, counts=[5, -2**31]), ["truncated body", "curve 1", "2147483648 control points"]),
    (raw_bcc([[], wiggly(5)], total=5), ["curve 0 has a control point count of 0"]),
    (raw_bcc([wiggly(3)]), ["curve 0", "3 control points", "open 'C0'", "at least 4"]),
    (raw_bcc([wiggly(2)], closed=[True]), ["curve 0", "closed 'C0'", "at least 3"]),
    (raw_bcc([wiggly(5)], ctype=b"BZ"), ["curve 0", "3k+1"]),
    (raw_bcc([wiggly(4)], ctype=b"BZ", closed=[True]), ["curve 0", "3k control points"]),
    (raw_bcc([wiggly(5), np.where(np.arange(18).reshape(6, 3) == 7, np.nan, wiggly(6))]),
     ["curve 1, control point 2", "non-finite"]),
    (raw_bcc([np.where(np.arange(15).reshape(5, 3) == 14, np.inf, wiggly(5))]),
     ["curve 0, control point 4", "non-finite"]),
    (raw_bcc(GOOD) + b"\0\0\0", ["3 trailing bytes after the last curve"]),
    (raw_bcc(GOOD, trailer=struct.pack("<f", -1.0) + bytes(16 * 11)), ["BCCX", "radius"]),
    (raw_bcc([np.ones((5, 3))]), ["curve 0 has zero length"]),
    (raw_bcc([], n_curves=0, total=0), ["no curves"]),
])
def test_malformed_bcc(blob, fragments):
    expect_error(lambda: geo.read_bcc(blob), *fragments)


def test_bad_arguments_and_paths(tmp_path):
    blob = raw_bcc(GOOD)
    for s in (0.0, -1.0, math.nan, math.inf, "x"):
        expect_error(lambda: geo.read_bcc(blob, scale=s), "scale")
    expect_error(lambda: geo.read_bcc(blob, yarn_radius=0.0), "yarn_radius")
    expect_error(lambda: geo.read_bcc(blob, samples_per_segment=0), "samples_per_segment")
    expect_error(lambda: geo.read_bcc(tmp_path / "missing.bcc"), "missing.bcc", "cannot read")
    bad = tmp_path / "bad.bcc"
    bad.write_bytes(blob[:-7])
    expect_error(lambda: geo.read_bcc(bad), "bad.bcc", "curve 1")  # messages name the file
    expect_error(lambda: geo.write_bcc(bad, [wiggly(3)], curve_type="C0"), "curve 0", "at least 4")
    expect_error(lambda: geo.write_bcc(bad, [wiggly(5)], up=3), "up")


def test_fuzzed_bcc_never_escapes_geometry_error():
    rng = np.random.default_rng(20240611)
    base = bytearray(geo.bcc_bytes([wiggly(6), wiggly(5, 2)], closed=[False, True], yarn_radius=0.25))
    outcomes = {"error": 0, "ok": 0}
    tracemalloc.start()
    t0 = time.perf_counter()
    for case in range(200):
        blob = bytearray(base)
        kind = case % 4
        if kind == 0:
            blob = blob[: int(rng.integers(0, len(blob)))]
        else:
            # Bit flips, half of them aimed at the header and the first count, where they hurt most.
            for _ in range(int(rng.integers(1, 5))):
                hi = 68 if kind == 1 else len(blob)
                pos = int(rng.integers(0, hi))
                blob[pos] ^= 1 << int(rng.integers(0, 8))
            if kind == 3:
                blob = blob[: int(rng.integers(60, len(blob) + 1))]
        try:
            curves = geo.read_bcc(bytes(blob))
        except GeometryError:
            outcomes["error"] += 1
            continue
        outcomes["ok"] += 1
        geo.validate(curves)
        assert all(np.isfinite(c.points).all() and (c.radius > 0).all() for c in curves)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert time.perf_counter() - t0 < 10.0
    assert peak < 50 * 2**20, f"fuzzing allocated {peak / 2**20:.1f} MiB"
    assert outcomes["error"] > 0 and outcomes["ok"] > 0, outcomes


# ---------------------------------------------------------------------------------------------------------
# Spline evaluation and curve utilities


def test_catmull_rom_interpolates_interior_points_open_and_closed():
    P = wiggly(8)
    s = 6
    open_pts = geo.catmull_rom(P, False, s)
    assert len(open_pts) == 5 * s + 1
    np.testing.assert_allclose(open_pts[::s], P[1:-1], atol=1e-12)  # phantom ends excluded
    closed_pts = geo.catmull_rom(P, True, s)
    assert len(closed_pts) == 8 * s
    np.testing.assert_allclose(closed_pts[::s], P, atol=1e-12)


@pytest.mark.parametrize("fn", [geo.catmull_rom, geo.bspline])
def test_closed_curves_are_continuous_at_the_seam(fn):
    P = wiggly(7, 3)
    s = 16
    a = fn(P, True, s)
    # Rotating the control points only rotates the samples: the seam is an ordinary segment.
    np.testing.assert_allclose(fn(np.roll(P, -1, axis=0), True, s), np.roll(a, -s, axis=0), atol=1e-12)
    # Position and first difference continuous across the seam (last sample -> first sample).
    steps = np.diff(np.concatenate([a, a[:1]]), axis=0)
    seam, before, after = steps[-1], steps[-2], steps[0]
    assert np.linalg.norm(seam - 0.5 * (before + after)) < 0.05 * np.linalg.norm(seam)


def test_bspline_of_collinear_equally_spaced_points_is_the_line():
    P = np.outer(np.arange(9.0), [1.0, 2.0, -0.5]) + [3.0, 0.0, 1.0]
    pts = geo.bspline(P, False, 10)
    direction = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    rel = pts - P[0]
    off_line = rel - np.outer(rel @ direction, direction)
    assert np.abs(off_line).max() < 1e-12
    np.testing.assert_allclose(pts[0], P[1], atol=1e-12)
    np.testing.assert_allclose(pts[-1], P[-2], atol=1e-12)
    np.testing.assert_allclose(np.diff(pts @ direction), np.linalg.norm(P[1] - P[0]) / 10)  # uniform speed


def test_bezier_interpolates_segment_end_points():
    P = wiggly(7)
    pts = geo.bezier(P, False, 8)
    assert len(pts) == 17
    np.testing.assert_allclose(pts[[0, 8, 16]], P[[0, 3, 6]], atol=1e-12)
    closed = geo.bezier(P[:6], True, 8)
    np.testing.assert_allclose(closed[[0, 8]], P[[0, 3]], atol=1e-12)
    expect_error(lambda: geo.bezier(P[:6], False), "3k+1")


def test_resample_validate_bounding_box():
    c = YarnCurve(np.array([[0, 0, 0], [1, 0, 0], [1, 3, 0]], float), np.array([1.0, 2.0, 3.0]), True)
    r = geo.resample(c, 0.25)
    seg = np.linalg.norm(np.diff(np.concatenate([r.points, r.points[:1]]), axis=0), axis=1)
    assert seg.max() <= 0.25 + 1e-12 and r.cyclic
    assert r.length == pytest.approx(c.length) == pytest.approx(4.0 + math.sqrt(10.0))
    for p in c.points:  # original vertices kept
        assert np.min(np.linalg.norm(r.points - p, axis=1)) == 0.0
    assert r.radius.min() == 1.0 and r.radius.max() == 3.0
    lo, hi = geo.bounding_box([c])
    np.testing.assert_allclose(lo, [-2, -2, -3])
    np.testing.assert_allclose(hi, [4, 6, 3])
    geo.validate([c, r])
    expect_error(lambda: geo.validate([c, YarnCurve(np.ones((4, 3)), 1.0)]), "curve 1 has zero length")
    expect_error(lambda: geo.validate([YarnCurve(np.zeros((1, 3)), 1.0)]), "curve 0 has zero length", "1 point")
    expect_error(lambda: geo.validate([YarnCurve(c.points, [1.0, 0.0, 1.0])]), "vertex 1", "radius")
    expect_error(lambda: geo.validate([YarnCurve([[0, 0, 0], [1, np.nan, 0]], 1.0)]), "vertex 1", "non-finite")
    expect_error(lambda: geo.validate([YarnCurve(c.points, [1.0, np.inf, 1.0])]), "non-finite radius")
    expect_error(lambda: YarnCurve(np.zeros((3, 2)), 1.0), "shape")


# ---------------------------------------------------------------------------------------------------------
# Leaf et al. periodic patterns

PX, PY = 7.3, 5.1


def leaf_tile():
    """A 1 x 1 tile: a course yarn spanning one x period and a wale yarn spanning one y period."""
    t = np.linspace(0.0, 1.0, 9)
    course = np.stack([PX * t, 0.8 * np.sin(2 * math.pi * t), 0.3 * np.cos(2 * math.pi * t)], axis=1)
    wale = np.stack([2.0 + 0.4 * np.sin(2 * math.pi * t), PY * t, -0.3 * np.cos(2 * math.pi * t)], axis=1)
    return [course, wale]


def write_leaf_text(path, yarns):
    lines = [f"Num Yarns: {len(yarns)}", ""]
    for Y in yarns:
        lines.append(str(len(Y)))
        lines += [f"{x:.17g} {y:.17g} {z:.17g}" for x, y, z in Y]
        lines.append("")
    path.write_text("\n".join(lines))


def test_leaf_text_roundtrip_and_period_estimate(tmp_path):
    path = tmp_path / "tile.txt"
    write_leaf_text(path, leaf_tile())
    yarns = geo.read_leaf_text(path)
    assert [len(y) for y in yarns] == [9, 9]
    np.testing.assert_array_equal(yarns[0], leaf_tile()[0])
    px, py = geo.estimate_period(yarns)
    assert abs(px - PX) < 1e-6 and abs(py - PY) < 1e-6


def test_leaf_tiling_welds_yarns_across_tiles(tmp_path):
    curves = geo.tile_pattern(leaf_tile(), 3, 2, yarn_radius=0.4, samples_per_segment=4)
    # 2 courses, each welded across 3 tiles, and 3 wales, each welded across 2 tiles.
    assert len(curves) == 5
    courses = sorted((c for c in curves if np.ptp(c.points[:, 0]) > PX), key=lambda c: c.points[0, 1])
    wales = [c for c in curves if np.ptp(c.points[:, 1]) > PY]
    assert len(courses) == 2 and len(wales) == 3
    # One welded control polygon: 3 x 9 points - 2 welds = 25 -> 22 C0 segments.
    assert len(courses[0].points) == 22 * 4 + 1
    # Its evaluated samples pass through the interior control points of all three tiles.
    t = np.linspace(0.0, 1.0, 9)
    expected_x = np.concatenate([PX * t[:-1], PX + PX * t[:-1], 2 * PX + PX * t])[1:-1]
    np.testing.assert_allclose(courses[0].points[::4, 0], expected_x, atol=1e-12)
    assert courses[1].points[0, 1] - courses[0].points[0, 1] == pytest.approx(PY)
    steps = np.linalg.norm(np.diff(courses[0].points, axis=0), axis=1)
    assert steps.max() < 3.0 * np.median(steps)  # no gaps at the welds
    assert all(np.allclose(c.radius, 0.4) for c in curves)


def test_leaf_period_from_sidecar_and_bcc_tile(tmp_path):
    tile = leaf_tile()
    path = tmp_path / "rib.txt"
    write_leaf_text(path, tile)
    (tmp_path / "rib.txt.json").write_text(json.dumps({"period": [PX, PY], "yarn_radius": 0.35, "units": "mm"}))
    curves = geo.read_leaf(path, nx=2, ny=2, samples_per_segment=2)
    assert len(curves) == 4 and np.allclose(curves[0].radius, 0.35)
    assert geo.read_leaf_sidecar(path) == {"period": (PX, PY), "yarn_radius": 0.35, "units": "mm"}
    (tmp_path / "rib.txt.json").write_text(json.dumps({"periode": [1, 2]}))
    expect_error(lambda: geo.read_leaf(path), "unknown key", "periode")
    # A BCC file as the tile source, dispatched on its first bytes (no sidecar: period estimated).
    bpath = tmp_path / "tile.bcc"
    geo.write_bcc(bpath, tile, curve_type="C0")
    assert len(geo.read_leaf(bpath, nx=3, ny=2, yarn_radius=0.4)) == 5


def test_leaf_period_not_estimable(tmp_path):
    course = leaf_tile()[0]
    assert len(geo.tile_pattern([course], 4, 1)) == 1  # py not needed for one row
    expect_error(lambda: geo.tile_pattern([course], 4, 2), "y period")
    expect_error(lambda: geo.tile_pattern([course], 2, 2, period=(PX, 0.0)), "period", "py")


@pytest.mark.parametrize("text, fragments", [
    ("", ["empty file"]),
    ("Num Yarns:\n4\n0 0 0\n", ["line 1", "not an integer"]),
    ("Num Yarns: 1\nfour\n0 0 0\n", ["line 2", "point count of yarn 0", "not an integer"]),
    ("Num Yarns: 1\n2\n0 0 0\n1 x 0\n", ["line 4", "yarn 0, point 1", "non-numeric"]),
    ("Num Yarns: 1\n2\n0 0 0\n1 nan 0\n", ["line 4", "non-finite"]),
    ("Num Yarns: 2\n3\n0 0 0\n1 0 0\n2\n0 1 0\n1 1 0\n", ["line 5", "yarn 0 declares 3 points but has only 2"]),
    ("Num Yarns: 1\n3\n0 0 0\n\n1 0 0\n", ["yarn 0 declares 3 points", "file ends after 2", "line 5"]),
    ("Num Yarns: 2\n2\n0 0 0\n1 0 0\n", ["declares 2 yarns", "ends after 1"]),
    ("Num Yarns: 1\n2\n0 0 0\n1 0 0\n0 2 0\n", ["line 5", "more points than it declares"]),
    ("Num Yarns: 1\n2\n0 0 0\n1 0 0\n7\n", ["line 5", "after the last of the 1 declared yarns"]),
    ("Num Yarns: 1\n0\n", ["line 2", "declares 0 points"]),
])
def test_malformed_leaf_text(tmp_path, text, fragments):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    expect_error(lambda: geo.read_leaf_text(path), "bad.txt", *fragments)


# ---------------------------------------------------------------------------------------------------------
# Plain knit (Crane)


def test_plain_knit_geometry():
    a, h, d, r, s = 1.5, 4.0, 1.0, 0.5, 2.0
    rows = geo.plain_knit(3, 4, scale=s)
    w = h + 0.5
    spl = 64
    assert len(rows) == 3 and all(not c.cyclic for c in rows)
    P = rows[0].points
    assert len(P) == 4 * spl + 1
    np.testing.assert_allclose(P[spl:] - P[:-spl], np.tile([2 * math.pi * s, 0, 0], (len(P) - spl, 1)), atol=1e-12)
    np.testing.assert_allclose(rows[1].points - rows[0].points, np.tile([0, w * s, 0], (len(P), 1)), atol=1e-12)
    assert np.abs(P[:, 2]).max() == pytest.approx(d * s)
    np.testing.assert_allclose(rows[0].radius, r * s)
    t = np.linspace(0, 8 * math.pi, len(P))
    np.testing.assert_allclose(P / s, geo.crane_course(t, a, h, d), atol=1e-12)
    purl = geo.plain_knit(3, 4, scale=s, purl=True)
    np.testing.assert_allclose(purl[0].points * [1, 1, -1], P)
    # Interlocking: each loop reaches past the middle between its row and the next (h > w/2).
    assert P[:, 1].max() / s > w / 2


def test_plain_knit_neighbouring_rows_do_not_touch():
    # Crane's defaults (a = 3/2, h = 4, d = 1, w = 4.5, r = 1/2): the centrelines of neighbouring rows
    # come no closer than 1.535 (computed here by brute force on 2000 samples per loop, refined near the
    # minimum), so tubes of radius 1/2 (distance 2r = 1) do not intersect.
    rows = geo.plain_knit(2, 3, samples_per_loop=512)
    dist = min_distance(rows[0].points, rows[1].points)
    assert 2 * 0.5 < dist < 1.6
    assert dist == pytest.approx(1.535, abs=0.01)


@pytest.mark.parametrize("kwargs, fragment", [
    (dict(rows=0, stitches=3), "rows"),
    (dict(rows=3, stitches=2001), "stitches"),
    (dict(rows=2000, stitches=2000), "exceed"),
    (dict(rows=2, stitches=2, h=2.0, w=4.0), "interlock"),
    (dict(rows=2, stitches=2, h=math.nan), "'h'"),
    (dict(rows=2, stitches=2, yarn_radius=-1.0), "yarn_radius"),
    (dict(rows=2, stitches=2, scale=math.inf), "scale"),
    (dict(rows=2, stitches=2, samples_per_loop=2), "samples_per_loop"),
])
def test_plain_knit_rejects_bad_parameters(kwargs, fragment):
    expect_error(lambda: geo.plain_knit(**kwargs), fragment)


# ---------------------------------------------------------------------------------------------------------
# Weaves


def test_weave_patterns_match_formulas():
    np.testing.assert_array_equal(geo.weave_pattern("plain"), [[0, 1], [1, 0]])
    for u, d, sigma in ((2, 2, 1), (1, 3, 1), (3, 1, -1), (2, 3, -1)):
        P = geo.weave_pattern("twill", u=u, d=d, direction=sigma)
        K = u + d
        i, j = np.indices((K, K))
        np.testing.assert_array_equal(P, ((j - sigma * i) % K) < u)
        assert (P.sum(axis=1) == u).all()
    for K, m in ((5, 2), (5, 3), (8, 3), (8, 5), (7, 3)):
        weft = geo.weave_pattern("satin", K=K, m=m, face="weft")
        assert (weft.sum(axis=1) == 1).all() and (weft.sum(axis=0) == 1).all()
        i, j = np.indices((K, K))
        np.testing.assert_array_equal(weft, ((j - m * i) % K) == 0)
        warp = geo.weave_pattern("satin", K=K, m=m, face="warp")
        np.testing.assert_array_equal(warp, 1 - weft)
    for n in (1, 2, 3):
        P = geo.weave_pattern("basket", n=n)
        i, j = np.indices((2 * n, 2 * n))
        np.testing.assert_array_equal(P, (i // n + j // n) % 2)
    expect_error(lambda: geo.weave_pattern("satin", K=8, m=2), "coprime")
    expect_error(lambda: geo.weave_pattern("satin", K=6, m=4), "coprime")
    expect_error(lambda: geo.weave_pattern("satin", K=5, m=1), "'m'")
    expect_error(lambda: geo.weave_pattern("satin", K=5, m=4), "'m'")
    expect_error(lambda: geo.weave_pattern("twill", direction=0), "direction")
    expect_error(lambda: geo.weave_pattern("twill", k=3), "unknown parameter")
    expect_error(lambda: geo.weave_pattern("jacquard"), "unknown weave")


@pytest.mark.parametrize("kind, params", [("plain", {}), ("twill", {"u": 2, "d": 2}), ("satin", {"K": 5, "m": 2}),
                                          ("basket", {"n": 2})])
def test_woven_fabric_crossings(kind, params):
    P = geo.weave_pattern(kind, **params)
    r, sx, sy, spc = 0.5, 2.5, 2.7, 64  # dense: polyline chords cut corners by ~ curvature * step^2 / 8
    W, F = 7, 6
    curves = geo.woven_fabric(P, W, F, spacing=(sx, sy), yarn_radius=r, samples_per_crossing=spc)
    warps, wefts = curves[:W], curves[W:]
    assert len(wefts) == F
    for i in range(W):
        for j in range(F):
            zw = warps[i].points[spc // 2 + j * spc]
            zf = wefts[j].points[spc // 2 + i * spc]
            np.testing.assert_allclose(zw[:2], [i * sx, j * sy], atol=1e-12)
            np.testing.assert_allclose(zf[:2], [i * sx, j * sy], atol=1e-12)
            sep = zw[2] - zf[2]
            assert abs(sep) >= 2 * r - 1e-9 and abs(sep) == pytest.approx(2 * r)  # crimp c = r
            assert (sep > 0) == bool(P[i % P.shape[0], j % P.shape[1]])  # warp on top where P = 1
    # Floats stay flat: consecutive crossings in the same state give a constant height between them.
    for i in range(W):
        for j in range(F - 1):
            if P[i % P.shape[0], j % P.shape[1]] == P[i % P.shape[0], (j + 1) % P.shape[1]]:
                z = warps[i].points[spc // 2 + j * spc: spc // 2 + (j + 1) * spc + 1, 2]
                assert np.ptp(z) == 0.0
    # The tubes do not intersect anywhere (densely resampled centrelines).
    A = np.concatenate([geo.resample(c, 0.05).points for c in warps])
    B = np.concatenate([geo.resample(c, 0.05).points for c in wefts])
    assert min_distance(A, B) >= 2 * r * (1 - 1e-3)


def test_woven_fabric_rejects_intersecting_or_bad_input():
    expect_error(lambda: geo.woven_fabric("plain", 3, 3, spacing=(0.9, 2.5), yarn_radius=0.5), "s_x", "intersect")
    # 2r <= s < pi sqrt(2) c: the yarns touch at the crossing but cut into each other next to it.
    msg = expect_error(lambda: geo.woven_fabric("plain", 3, 3, spacing=2.0, yarn_radius=0.5), "next to the crossings")
    assert "2.221" in msg
    assert geo.weave_clearance("plain", (2.0, 2.0), 0.5) < 1.0 - 1e-3
    assert geo.weave_clearance("plain", (2.23, 2.23), 0.5) == pytest.approx(1.0, abs=1e-9)
    geo.woven_fabric("plain", 3, 3, spacing=2.23, yarn_radius=0.5)
    expect_error(lambda: geo.woven_fabric("plain", 3, 3, crimp=0.4), "crimp")
    expect_error(lambda: geo.woven_fabric([], 3, 3), "non-empty")
    expect_error(lambda: geo.woven_fabric([1, 0], 3, 3), "2-D")
    expect_error(lambda: geo.woven_fabric([[0, 2], [1, 0]], 3, 3), "[0][1]", "not 0 or 1")
    expect_error(lambda: geo.woven_fabric("plain", 0, 3), "warps")
    # A yarn that never interlaces is allowed.
    assert len(geo.woven_fabric([[1, 1], [0, 1]], 2, 2)) == 4


# ---------------------------------------------------------------------------------------------------------
# Plied yarns


def straight_axis(length=40.0, radius=1.0, n=41):
    x = np.linspace(0.0, length, n)
    return YarnCurve(np.stack([x, np.zeros(n), np.zeros(n)], axis=1), radius, False)


def test_ply_center_distance():
    R = 0.7
    assert geo.ply_center_distance(2, R, 0.0) == pytest.approx(R, rel=1e-12)
    assert geo.ply_center_distance(3, R, 0.0) == pytest.approx(R / math.sin(math.pi / 3), rel=1e-12)
    d = geo.ply_center_distance(3, R, 0.25)
    assert d > R / math.sin(math.pi / 3)  # tilted plies need more room
    assert geo.neighbour_ply_distance(3, d, R, 0.25) == pytest.approx(2 * R, rel=1e-9)
    assert geo.ply_center_distance(3, 2 * R, 0.25) == pytest.approx(2 * d, rel=1e-9)  # scale invariance


_CLI = os.environ.get("NY_CLI") or os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "build",
                                                 "cpp_core", "neuralyarn")


@pytest.mark.parametrize("K", [1, 2, 3, 5, 16])
def test_ply_center_distance_is_the_cores(K):
    """The add-on sizes yarn-level curves (level_of_detail.py) and garments (scripts/garment.py) with its own
    d; the yarn-level models were baked with the core's. Both bisect to 1e-13 of d and find the neighbour
    distance's minimum to machine precision, so they agree to rounding; 1e-9 leaves room for libm against
    numpy while a different algorithm (the planar bound alone, another bracket) is off by 1e-3 or more."""
    if not os.path.isfile(_CLI):
        pytest.skip(f"the core's CLI is not built at {_CLI}")
    alphas = (0.0, 0.1, 0.5, 1.3, 8.0)
    r = subprocess.run([_CLI, "yarn-geometry", "--plies", str(K), "--ply-twist", *map(repr, alphas)],
                       capture_output=True, text=True, check=True)
    lines = [json.loads(line) for line in r.stdout.splitlines()]
    assert [(c["plies"], c["ply_twist"]) for c in lines] == [(K, a) for a in alphas]
    for alpha, core in zip(alphas, lines):
        d = geo.ply_center_distance(K, 1.0, alpha)
        assert d == pytest.approx(core["ply_distance"], rel=1e-9, abs=1e-12), alpha
        assert 1.0 + d == pytest.approx(core["yarn_radius"], rel=1e-9), alpha


@pytest.mark.parametrize("K, alpha", [(2, 0.2), (3, 0.2), (3, 0.5), (5, 0.3)])
def test_plies_around_a_straight_axis(K, alpha):
    R = 0.5
    # 128 samples per turn: the chords of the sampled helices cut ~3e-4 R off the true gap.
    # (By the screw symmetry the closest approach recurs all along the yarn: 12 units are plenty.)
    plies = geo.twist_plies(straight_axis(12.0, n=13), K, ply_radius=R, alpha_yarn=alpha, samples_per_turn=128)
    d = geo.ply_center_distance(K, R, alpha)
    w = math.pi * alpha / (d + R)
    assert len(plies) == K
    for k, p in enumerate(plies):
        x = p.points[:, 0]
        np.testing.assert_allclose(np.hypot(p.points[:, 1], p.points[:, 2]), d, rtol=1e-12)
        # docs/conventions.md: (x, d cos(2 pi k/K - w x), d sin(2 pi k/K - w x)).
        th = 2 * math.pi * k / K - w * x
        np.testing.assert_allclose(p.points[:, 1:], d * np.stack([np.cos(th), np.sin(th)], axis=1), atol=1e-9)
        np.testing.assert_allclose(p.radius, R)
        # S twist = left-handed about +x: the angle about +x decreases as x increases.
        ang = np.unwrap(np.arctan2(p.points[:, 2], p.points[:, 1]))
        assert np.all(np.diff(ang) < 0)
        assert np.polyfit(x, ang, 1)[0] == pytest.approx(-w, rel=1e-9)
    dense = [geo.resample(p, R / 40).points for p in plies]
    gap = min(min_distance(dense[k], dense[(k + 1) % K]) for k in range(K))
    assert 2 * R * (1 - 1e-3) <= gap <= 2 * R * 1.02


def test_plies_fill_the_yarn_radius_by_default():
    plies = geo.twist_plies(straight_axis(radius=1.0), 3, alpha_yarn=0.2)
    R = plies[0].radius[0]
    d = float(np.hypot(*plies[0].points[0, 1:]))
    assert d + R == pytest.approx(1.0, rel=1e-12)
    assert d == pytest.approx(geo.ply_center_distance(3, R, 0.2), rel=1e-9)
    single = geo.twist_plies(straight_axis(), 1, alpha_yarn=0.2)
    assert len(single) == 1 and np.array_equal(single[0].points, straight_axis().points)


def closure_ok(p):
    steps = np.linalg.norm(np.diff(p.points, axis=0), axis=1)
    return np.linalg.norm(p.points[-1] - p.points[0]) <= 1.5 * np.median(steps)


@pytest.mark.parametrize("alpha", [0.0, 0.23, 0.41])
def test_plies_close_up_around_closed_curves(alpha):
    t = np.linspace(0, 2 * math.pi, 2000, endpoint=False)  # chords 2.5e-5 inside the circle
    circle = YarnCurve(np.stack([20 * np.cos(t), 20 * np.sin(t), np.zeros_like(t)], axis=1), 1.0, True)
    plies = geo.twist_plies(circle, 3, alpha_yarn=alpha)
    R = plies[0].radius[0]
    d = geo.ply_center_distance(3, R, alpha)
    for p in plies:
        assert p.cyclic and closure_ok(p)
        rho = np.hypot(p.points[:, 0], p.points[:, 1])
        np.testing.assert_allclose(np.hypot(rho - 20.0, p.points[:, 2]), d, rtol=2e-4)
    _, _, _, hol_circle = geo.parallel_transport_frames(circle.points, True)
    assert abs(hol_circle) < 1e-9  # planar loop: no holonomy


def test_holonomy_of_a_non_planar_loop_is_absorbed():
    # For a loop with non-vanishing curvature the transported frame turns against the (periodic) Frenet
    # frame by -torsion, so the holonomy is -(total torsion) mod 2 pi; torsion from spectral derivatives.
    n = 4000
    t = np.linspace(0, 2 * math.pi, n, endpoint=False)
    P = np.stack([10 * np.cos(t), 10 * np.sin(t) + 3 * np.cos(2 * t), 6 * np.sin(t) ** 2 * np.cos(t)], axis=1)
    F = np.fft.fft(P, axis=0)
    ik = 1j * np.fft.fftfreq(n, 1.0 / n)[:, None]
    d1, d2, d3 = (np.fft.ifft(F * ik**m, axis=0).real for m in (1, 2, 3))
    c = np.cross(d1, d2)
    tau = np.einsum("ij,ij->i", c, d3) / np.einsum("ij,ij->i", c, c)
    total_torsion = float(np.sum(tau * np.linalg.norm(d1, axis=1)) * 2 * math.pi / n)
    _, _, _, hol = geo.parallel_transport_frames(P, True)
    expected = (-total_torsion + math.pi) % (2 * math.pi) - math.pi
    assert abs(hol) > 1.0 and hol == pytest.approx(expected, abs=1e-6)
    loop = YarnCurve(P[::4], 0.8, True)
    for alpha in (0.0, 0.3):
        plies = geo.twist_plies(loop, 4, alpha_yarn=alpha)
        assert all(p.cyclic and closure_ok(p) for p in plies)


def test_parallel_transport_frames_are_orthonormal_and_rotation_minimising():
    t = np.linspace(0, 4 * math.pi, 400)
    helix = np.stack([3 * np.cos(t), 3 * np.sin(t), 0.5 * t], axis=1)
    T, N, B, _ = geo.parallel_transport_frames(helix, False)
    for a, b in ((T, N), (T, B), (N, B)):
        assert np.abs(np.einsum("ij,ij->i", a, b)).max() < 1e-12
    np.testing.assert_allclose(np.cross(T, N), B, atol=1e-12)
    # Rotation-minimising: N changes only along T (dN . B ~ 0).
    dN = np.diff(N, axis=0)
    assert np.abs(np.einsum("ij,ij->i", dN, 0.5 * (B[1:] + B[:-1]))).max() < 1e-4


def test_twist_plies_rejects_bad_input_and_fiber_warning():
    expect_error(lambda: geo.twist_plies(straight_axis(), 0, alpha_yarn=0.1), "'K'")
    expect_error(lambda: geo.twist_plies(straight_axis(), 3, alpha_yarn=-0.1), "alpha_yarn")
    expect_error(lambda: geo.twist_plies(YarnCurve(np.ones((3, 3)), 1.0), 3, alpha_yarn=0.1), "zero length")
    assert geo.explicit_fiber_warning(300, 300) is None
    msg = geo.explicit_fiber_warning(1200, 300, points_per_fiber=500)
    assert "360,000 curves" in msg and "GiB" in msg


@pytest.mark.parametrize("coordinate, radius, message", [
    (3e38, 1.0, "beyond the renderable"),          # coordinates near float32's limit
    (1e-30, 1e-31, "below the renderable 1e-07"),   # a whole file of 1e-30 (issue 20, A4)
    (1e3, 1e-4, "below the renderable 0.001"),      # radius below single precision at that coordinate
])
def test_validate_rejects_geometry_outside_the_renderable_scale(coordinate, radius, message):
    pts = np.array([[0.0, 0.0, 0.0], [coordinate, coordinate, 0.0]])
    with pytest.raises(GeometryError, match=message):
        geo.validate([YarnCurve(pts, np.full(2, radius))], source="f.bcc")
    # The same shapes at a renderable scale pass: 10 um fibers at 1 m, and a 1 km scene of 1 m yarn.
    geo.validate([YarnCurve(np.array([[0.0, 0, 0], [1.0, 1.0, 0]]), np.full(2, 5e-6))])
    geo.validate([YarnCurve(np.array([[0.0, 0, 0], [1e3, 1e3, 0]]), np.full(2, 1.0))])


def test_bcc_of_tiny_coordinates_is_refused_with_the_scale():
    blob = geo.bcc_bytes([np.array([[0.0, 0, 0], [1e-30, 0, 0], [2e-30, 1e-30, 0], [3e-30, 0, 0]])])
    with pytest.raises(GeometryError, match="import scale"):
        geo.read_bcc(blob, scale=0.001)


SAMPLES = os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "addon", "samples")


def test_shipped_samples_are_what_make_samples_writes(tmp_path):
    """addon/samples/ (the files to try the importers with) are reproducible from scripts/make_samples.py."""
    import subprocess
    root = os.path.join(os.path.dirname(__file__), os.pardir, os.pardir)
    python = os.path.join(root, ".venv", "bin", "python")
    if not os.path.isfile(python):
        pytest.skip(".venv is not set up (scripts/setup.sh)")
    subprocess.run([python, os.path.join(root, "scripts", "make_samples.py"), "--out", str(tmp_path)], check=True,
                   capture_output=True)
    names = sorted(os.listdir(tmp_path))
    assert names == sorted(os.listdir(SAMPLES))
    for name in names:
        with open(os.path.join(SAMPLES, name), "rb") as a, open(tmp_path / name, "rb") as b:
            assert a.read() == b.read(), f"addon/samples/{name} differs from what make_samples.py writes"


def test_shipped_samples_import_at_garment_scale():
    knit = geo.read_bcc(os.path.join(SAMPLES, "knit_6x4.bccx"), scale=0.01)
    lo, hi = geo.bounding_box(knit)
    assert len(knit) == 4 and knit[0].radius[0] == pytest.approx(0.001)
    assert 0.03 < hi[0] - lo[0] < 0.2  # centimetres wide, in metres
    weave = geo.read_leaf(os.path.join(SAMPLES, "plain_weave_tile.txt"), nx=3, ny=3, scale=0.01)
    assert len(weave) == 12 and weave[0].radius[0] == pytest.approx(0.0005)


def test_read_bcc_of_many_curves_is_batched_and_reports_progress(tmp_path):
    """Issue 20, D15: 300 k curves took 36-50 s in a per-curve loop without progress. The batched reader
    gives each curve exactly what the per-curve evaluation gives, and reports its stages."""
    rng = np.random.default_rng(7)
    raw = [np.cumsum(rng.normal(size=(int(rng.integers(4, 9)), 3)), axis=0) for _ in range(2000)]
    path = tmp_path / "many.bcc"
    geo.write_bcc(str(path), raw, curve_type="C0", closed=[k % 3 == 0 for k in range(len(raw))])
    seen = []
    curves = geo.read_bcc(str(path), scale=0.5, samples_per_segment=4, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) >= 3
    stored = geo.read_bcc_control_points(str(path))
    for k in (0, 1, 2, 999, 1998, 1999):
        expect = geo.evaluate_spline(geo.bcc.to_z_up(stored.control_points[k], stored.up_dimension), "C0",
                                     k % 3 == 0, 4) * 0.5
        assert np.array_equal(curves[k].points, expect)
        assert curves[k].cyclic == (k % 3 == 0)


@pytest.mark.parametrize("curve_type, n", [("C0", 6), ("BS", 5), ("BZ", 7), ("PL", 3)])
def test_evaluate_splines_equals_evaluate_spline(curve_type, n):
    rng = np.random.default_rng(3)
    P = [rng.normal(size=(n if k % 2 else n + 3, 3)) for k in range(12)]
    closed = [curve_type != "BZ" and k % 4 == 0 for k in range(12)]
    got = geo.evaluate_splines(P, curve_type, closed, 5)
    for k in range(12):
        assert np.allclose(got[k], geo.evaluate_spline(P[k], curve_type, closed[k], 5), rtol=0, atol=1e-12)


@pytest.mark.parametrize("weave, spacing, radius", [("plain", 2.5, 0.5), ("twill", 2.5, 0.5), ("plain", 3.0, 0.6)])
def test_bcc_without_a_radius_gets_the_radius_at_which_its_passes_touch(tmp_path, weave, spacing, radius):
    """Issue 20, D14: the default radius (half the control-point spacing) overlapped neighbouring passes on
    Yuksel's glove and left gaps on his trellis. A woven swatch whose yarns touch, written as BCC without a
    radius, reads back with its true radius within 3 %."""
    pattern = geo.weave_pattern(weave, **({"u": 2, "d": 2} if weave == "twill" else {}))
    curves = geo.woven_fabric(pattern, 8, 8, spacing=spacing, yarn_radius=radius)
    path = tmp_path / "w.bcc"
    geo.write_bcc(str(path), [c.points for c in curves], curve_type="PL")
    got = geo.read_bcc(str(path))[0].radius[0]
    assert got == pytest.approx(radius, rel=0.03)


def test_passes_that_never_meet_fall_back_to_the_spacing():
    far = [np.array([[0.0, 10.0 * k, 0.0], [1.0, 10.0 * k, 0.0], [2.0, 10.0 * k, 0.0]]) for k in range(3)]
    assert geo.yarn_radius_from_passes(far) == 0.0
    curves = geo.read_bcc(geo.bcc_bytes(far, curve_type="PL"))
    assert curves[0].radius[0] == pytest.approx(0.5)  # half the control-point spacing


@pytest.mark.parametrize("meta, key", [({"yarn_radius": -1.0}, "yarn_radius"), ({"period": [2.0, "x"]}, "period")])
def test_a_bad_sidecar_number_names_the_file_then_the_key(tmp_path, meta, key):
    """Issue 20, E16: the message put the file's path inside the parameter's name ("parameter '/x.json: ...'")."""
    (tmp_path / "tile.txt").write_text("Num Yarns: 1\n\n2\n0 0 0\n1 0 0\n")
    (tmp_path / "tile.txt.json").write_text(json.dumps(meta))
    with pytest.raises(GeometryError) as e:
        geo.read_leaf_sidecar(str(tmp_path / "tile.txt"))
    msg = str(e.value)
    assert msg.startswith(str(tmp_path / "tile.txt.json") + ": parameter '" + key + "'"), msg
