# SPDX-License-Identifier: Apache-2.0
"""The garment scene (scripts/garment.py and evaluate.sh --scenes garment): the knitted sleeve's ply curves are
a tube of the right size, deterministic, refused for bad sizes; the harness renders a small one with explicit
fibers and the native closure against the same curves, and a garment whose explicit fibers would not fit is
recorded as failed while the native closure's cost is still measured."""
import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import garment  # noqa: E402

EVALUATE = os.path.join(ROOT, "scripts", "evaluate.sh")


def test_the_sleeve_is_a_tube_of_knitted_plies():
    g = garment.garment_plies(3, 4)
    assert g["format"] == "neuralyarn-plies 1" and g["ply_radius"] == 1.0
    assert len(g["plies"]) == 3 * garment.PLIES_PER_YARN
    pts = np.concatenate([np.reshape(p, (-1, 3)) for p in g["plies"]])
    # Around the vertical axis through (0, ., tube): within the knit's thickness of the tube radius (the loops
    # rise a couple of yarn radii off the tube), the front at z ~ 0 facing the camera on -z.
    r = np.hypot(pts[:, 0], pts[:, 2] - g["tube_radius"])
    assert np.all(np.abs(r - g["tube_radius"]) < 12.0), (r.min(), r.max())
    assert abs(pts[:, 2].min()) < 12.0 and pts[:, 2].max() > 1.8 * g["tube_radius"]
    # Four stitches go once around: the courses' length is the circumference.
    assert g["tube_radius"] == pytest.approx(4 * 2 * math.pi / garment_ply_radius() / (2 * math.pi), rel=1e-6)
    assert abs(pts[:, 1].mean()) < 0.2 * g["height"]
    assert garment.garment_plies(3, 4) == g  # deterministic
    with pytest.raises(garment.geometry.GeometryError):
        garment.garment_plies(0, 4)


def garment_ply_radius():
    """The ply radius in Crane's units (the yarn radius 0.5 split into 3 plies)."""
    y = garment.geometry.plain_knit(1, 1, samples_per_loop=garment.SAMPLES_PER_LOOP)[0]
    plies = garment.geometry.twist_plies(y, garment.PLIES_PER_YARN, alpha_yarn=garment.ALPHA_YARN,
                                         samples_per_turn=garment.GARMENT_SAMPLES_PER_TURN)
    return float(np.mean([p.radius.mean() for p in plies]))


def test_a_small_garment_in_the_harness(tmp_path):
    # References at 16 spp (the quick default is 64): their noise floor stays far below the bound below.
    r = subprocess.run(["bash", EVALUATE, "--quick", "--scenes", "garment", "--garment-stitches", "2", "--lights",
                        "grazing", "--methods", "explicit", "native", "--ref-spp", "16", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.load(open(tmp_path / "results.json"))
    runs = {x["method"]: x for x in res["runs"]}
    assert set(runs) == {"explicit", "native"}
    for m, x in runs.items():
        assert x["failed"] is False and x["scene"] == "garment" and x["flip"] is not None, (m, x)
        assert x["distance"] == res["scenes"]["garment"]["distance"] > 12.0
    # Same plies: the native scene has one curve per ply, the explicit one every ply's fibers.
    n_plies = 2 * garment.PLIES_PER_YARN
    assert runs["native"]["curve_keys"] == sum(len(p) // 3 for p in json.load(
        open(tmp_path / "scenes" / "garment_2x2.json"))["plies"])
    assert runs["explicit"]["curve_keys"] > 100 * runs["native"]["curve_keys"]
    # Under the grazing light the aggregated sleeve is not far from the fibers (a wrong light scale or
    # frame would be off by far more).
    assert abs(runs["native"]["mean_luminance_error"]) < 0.5, runs["native"]
    assert n_plies == len(json.load(open(tmp_path / "scenes" / "garment_2x2.json"))["plies"])


def test_a_garment_too_large_for_explicit_fibers_still_measures_the_native_cost(tmp_path):
    r = subprocess.run(["bash", EVALUATE, "--quick", "--scenes", "garment", "--garment-stitches", "40", "--lights",
                        "grazing", "--methods", "explicit", "native", "--ref-spp", "2", "--ref-rotations", "1",
                        "--out", str(tmp_path)], capture_output=True, text=True, timeout=900)
    assert r.returncode == 2, r.stderr[-3000:]  # some renders failed
    res = json.load(open(tmp_path / "results.json"))
    runs = {x["method"]: x for x in res["runs"]}
    assert "curve keys" in runs["explicit"]["failed"]
    assert runs["native"]["failed"] is False and runs["native"]["seconds_render"] is not None
    assert runs["native"]["flip"] is None and "curve keys" in runs["native"]["no_reference"]


def test_the_sleeve_carries_its_mid_surface():
    """The surface level (D44) draws the sleeve's mid-surface: a closed cylinder at the tube radius about the
    tube's axis, as tall as the knit, every triangle's normal (by its winding) outward, toward the knit's face."""
    g = garment.garment_plies(3, 4)
    v = np.reshape(g["surface"]["vertices"], (-1, 3))
    tri = np.reshape(g["surface"]["triangles"], (-1, 3))
    assert len(tri) == 2 * garment.TUBE_SEGMENTS and tri.min() == 0 and tri.max() == len(v) - 1
    assert np.allclose(np.hypot(v[:, 0], v[:, 2] - g["tube_radius"]), g["tube_radius"], rtol=1e-4)
    assert v[:, 1].max() - v[:, 1].min() == pytest.approx(g["height"], rel=1e-4)
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    n = np.cross(b - a, c - a)
    centre = (a + b + c) / 3.0
    radial = centre - np.stack([np.zeros(len(centre)), centre[:, 1], np.full(len(centre), g["tube_radius"])], axis=1)
    assert np.all(np.einsum("ij,ij->i", n, radial) > 0.0)
    # The knit's face is outward: its loops' crests (the face's side, +z before wrapping) lie outside the tube.
    pts = np.concatenate([np.reshape(p, (-1, 3)) for p in g["yarns"]])
    r = np.hypot(pts[:, 0], pts[:, 2] - g["tube_radius"])
    assert r.min() < g["tube_radius"] < r.max()


def test_the_flat_knit_repeats_with_its_period():
    """`neuralyarn surface` enters one period of the flat knit: its rows are one period apart along y, and each
    row's course repeats one period along x."""
    f = garment.flat_knit_plies(3, 4)
    px, py = f["period"]
    rows = [np.reshape(y, (-1, 3)) for y in f["yarns"]]
    assert np.allclose(rows[1] - rows[0], [0.0, py, 0.0], atol=1e-4)
    q = rows[0]
    k = garment.SAMPLES_PER_LOOP  # samples per stitch
    assert np.allclose(q[k:] - q[:-k], [px, 0.0, 0.0], atol=1e-3)
    assert abs(q[:, 2].max() + q[:, 2].min()) < 1e-3  # about the plane z = 0
    assert "surface" not in f and f["yarn_radius"] == pytest.approx(garment.yarn_radius())


def test_the_surface_level_in_the_harness(tmp_path):
    """The surface level (D44) on a small sleeve: fitted once a run from the yarn-level model, drawn as the
    sleeve's mid-surface with stock closures weighted by the file's tables."""
    r = subprocess.run(["bash", EVALUATE, "--quick", "--scenes", "garment", "--garment-stitches", "3", "--lights",
                        "key-rim", "--methods", "native", "surface", "--ref-spp", "16", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "surface level of fleece: fitted" in r.stderr
    res = json.load(open(tmp_path / "results.json"))
    runs = {x["method"]: x for x in res["runs"]}
    assert runs["surface"]["failed"] is False and runs["surface"]["curve_keys"] == 0
    surface = json.load(open(tmp_path / "scenes" / "surface_fleece.json"))
    assert surface["format"] == "neuralyarn-surface 1" and surface["source"]["level"] == "yarns"
    # The pipeline, not the accuracy (measured in docs/benchmarks.md: fleece's surface level is 30 % dark under
    # this rig on a 10 x 10 sleeve): closures that the tables did not weight would leave only the transparent
    # share, and the sleeve black under these lights.
    assert -0.6 < runs["surface"]["mean_luminance_error"] < 0.2, runs["surface"]
    # Refused where there is no cloth.
    bad = subprocess.run(["bash", EVALUATE, "--quick", "--methods", "surface", "--out", str(tmp_path / "bad")],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 1 and "scene garment only" in bad.stderr


def test_the_plies_files_hold_their_yarns():
    """The yarn level (D27) draws the yarns the plies were twisted from: the file names them with their radius
    and plying, and every ply of the straight yarn lies at the plies' centre distance from the yarn's axis."""
    g = garment.garment_plies(2, 3)
    assert len(g["yarns"]) == 2 and g["plies_per_yarn"] == garment.PLIES_PER_YARN
    assert g["ply_twist"] == garment.ALPHA_YARN
    d = garment.geometry.ply_center_distance(garment.PLIES_PER_YARN, 1.0, garment.ALPHA_YARN)
    assert g["yarn_radius"] == pytest.approx(1.0 + d)
    s = garment.straight_yarn_plies(30.0)
    assert s["yarns"] == [[-15.0, 0.0, 0.0, 15.0, 0.0, 0.0]] and len(s["plies"]) == garment.PLIES_PER_YARN
    for p in s["plies"]:
        q = np.reshape(p, (-1, 3))
        assert np.allclose(np.hypot(q[:, 1], q[:, 2]), d, atol=1e-3)
        assert q[0, 0] == pytest.approx(-15.0) and q[-1, 0] == pytest.approx(15.0)


def test_the_yarn_close_up_at_every_level(tmp_path):
    """scene yarn: explicit fibers of three plies, the ply model on the three ply curves, the yarn model on one
    curve of the yarn's radius; each measured against the same reference."""
    r = subprocess.run(["bash", EVALUATE, "--quick", "--scenes", "yarn", "--lights", "grazing", "--methods",
                        "explicit", "native", "yarns", "--out", str(tmp_path)], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.load(open(tmp_path / "results.json"))
    runs = {x["method"]: x for x in res["runs"]}
    assert set(runs) == {"explicit", "native", "yarns"}
    for m, x in runs.items():
        assert x["failed"] is False and x["scene"] == "yarn" and x["flip"] is not None, (m, x)
    assert runs["native"]["curve_keys"] > runs["yarns"]["curve_keys"] > 0
    scenes = {m: open(tmp_path / "scenes" / f"yarn_fleece_grazing_{m}_seed1.xml").read() for m in ("native", "yarns")}
    assert 'model="' in scenes["yarns"] and "_yarn.json" in scenes["yarns"]
    r_yarn = garment.straight_yarn_plies(1.0)["yarn_radius"]
    radius = float(re.search(r'<hair\b[^>]*\sradius="([^"]+)"', scenes["yarns"]).group(1))
    assert radius == pytest.approx(r_yarn, rel=1e-4)
    # Bad requests: the yarn level on the one-ply close-up, a custom yarn without yarn model.
    bad = subprocess.run(["bash", EVALUATE, "--quick", "--scenes", "closeup", "--methods", "yarns", "--out",
                          str(tmp_path / "bad")], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 1 and "yarn" in bad.stderr


def test_the_patches_in_the_harness(tmp_path):
    """scenes knit and twill (garment.patch_plies: the examples' patches): every method draws the same plies file,
    framed whole in a square image, measured over the middle half of the frame."""
    knit = garment.patch_plies("knit")
    assert knit == garment.patch_plies("knit")  # deterministic
    pts = np.concatenate([np.reshape(p, (-1, 3)) for p in knit["plies"]])
    assert np.allclose(0.5 * (pts.min(axis=0) + pts.max(axis=0))[:2], 0.0, atol=0.5 * knit["size"] / 10)
    r = subprocess.run(["bash", EVALUATE, "--quick", "--scenes", "knit", "twill", "--lights", "key-rim", "--methods",
                        "explicit", "native", "--ref-spp", "16", "--out", str(tmp_path)], capture_output=True,
                       text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.load(open(tmp_path / "results.json"))
    assert {(x["scene"], x["method"]) for x in res["runs"]} == {(s, m) for s in ("knit", "twill")
                                                                for m in ("explicit", "native")}
    for x in res["runs"]:
        assert x["failed"] is False and x["region"] == "central" and x["flip"] is not None, x
        assert x["distance"] == res["scenes"][x["scene"]]["distance"] > 12.0
        assert res["scenes"][x["scene"]]["width"] == res["scenes"][x["scene"]]["height"]
        plies = json.load(open(tmp_path / "scenes" / f"{x['scene']}_plies.json"))["plies"]
        if x["method"] == "native":
            assert x["curve_keys"] == sum(len(p) // 3 for p in plies)
            # a wrong frame, light scale or model would be off by far more than the near-field error (~10 %)
            assert abs(x["mean_luminance_error"]) < 0.35, x
        else:
            assert x["curve_keys"] > 100 * sum(len(p) // 3 for p in plies)
