# SPDX-License-Identifier: GPL-3.0-or-later
"""Level of detail from a known camera (addon/geometry/lod.py): the ply's width in pixels, the level it gives,
and a sensible level with one warning for every camera the choice cannot use."""
import math

import numpy as np
import pytest

from geometry import lod

FOV = math.radians(40.0)


def view(z=-10.0, kind="PERSP", width=640, height=480, fov=FOV, ortho_scale=4.0):
    return lod.View(position=(0.0, 0.0, z), forward=(0.0, 0.0, 1.0), kind=kind, fov=fov, ortho_scale=ortho_scale,
                    width=width, height=height)


def line(z=0.0, n=5):
    return np.stack([np.linspace(-1, 1, n), np.zeros(n), np.full(n, z)], axis=1)


def test_ply_width_in_pixels_is_the_pinhole_projection():
    # 640 pixels span 2 d tan(20 deg) at depth d = 10: a ply of radius 0.01 is 0.02 / 7.28 * 640 = 1.76 px.
    px = lod.ply_pixels(line(), 0.01, view())
    assert px == pytest.approx(0.02 * 640 / (2 * 10 * math.tan(0.5 * FOV)), rel=1e-12)
    # The nearest point decides; twice as far is half as wide; orthographic ignores depth.
    pts = np.vstack([line(0.0), line(10.0)])
    assert lod.ply_pixels(pts, 0.01, view()) == pytest.approx(px)
    assert lod.ply_pixels(line(10.0), 0.01, view()) == pytest.approx(px / 2)
    assert lod.ply_pixels(line(10.0), 0.01, view(kind="ORTHO")) == pytest.approx(0.02 * 640 / 4.0)


def test_the_level_follows_the_footprint():
    r = 0.01
    near = lod.choose_level(line(-9.9), r, view())   # depth 0.1: 176 px, fibers 5 px wide
    mid = lod.choose_level(line(-9.0), r, view())    # depth 1: 17.6 px
    far = lod.choose_level(line(10.0), r, view())    # depth 20: 0.88 px
    assert (near.level, mid.level, far.level) == ("fibers", "plies", "yarns")
    assert near.warning is mid.warning is far.warning is None
    # The threshold itself: a ply exactly YARNS_BELOW_PLY_PIXELS wide stays plies, a hair narrower is yarns.
    d = 2 * r * 640 / (2 * lod.YARNS_BELOW_PLY_PIXELS * math.tan(0.5 * FOV))
    assert lod.choose_level(line(-10 + d * 0.999), r, view()).level == "plies"
    assert lod.choose_level(line(-10 + d * 1.001), r, view()).level == "yarns"
    # A requested level is kept (no camera needed), the surface level too; Auto never gives it, however far.
    assert lod.choose_level(line(), r, None, requested="plies") == lod.LevelChoice("plies", None, None)
    assert lod.choose_level(line(), r, view(), requested="surface") == lod.LevelChoice("surface", None, None)
    assert lod.choose_level(line(1e6), r, view()).level == "yarns"
    with pytest.raises(ValueError):
        lod.choose_level(line(), r, view(), requested="atoms")


@pytest.mark.parametrize("camera, pts, expect, words", [
    (None, line(), "plies", "no scene camera"),
    (view(width=0), line(), "plies", "resolution"),
    (view(fov=0.0), line(), "plies", "unusable camera"),
    (view(kind="ORTHO", ortho_scale=0.0), line(), "plies", "unusable camera"),
    (view(z=0.0), line(), "plies", "inside the cloth"),                     # the camera on the yarn
    (view(z=0.0), np.vstack([line(-5.0), line(5.0)]), "plies", "inside"),  # cloth on both sides
    (view(z=20.0), line(), "yarns", "behind the camera"),
])
def test_cameras_it_cannot_use_give_a_level_and_one_warning(camera, pts, expect, words):
    c = lod.choose_level(pts, 0.01, camera)
    assert c.level == expect and words in c.warning


def test_mixed_radii_choose_for_the_widest_and_say_so():
    pts = line(10.0)
    c = lod.choose_level(pts, np.array([0.01, 0.01, 0.05, 0.01, 0.01]), view())
    assert c.level == "plies" and c.ply_pixels == pytest.approx(lod.ply_pixels(pts, 0.05, view()))
    assert "mixed ply radii" in c.warning
    for bad in ([], [0.01, float("nan")], [0.0]):
        assert lod.choose_level(line(), np.array(bad), view()).level == "plies"


def test_the_shipped_yarn_models_are_of_the_plying_the_choice_assumes():
    import glob
    import json
    import os
    root = os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "models")
    files = glob.glob(os.path.join(root, "*_yarn.json"))
    assert len(files) == 5
    for f in files:
        s = json.load(open(f))["structure"]
        assert (s["plies"], s["ply_twist"]) == (lod.YARN_MODEL_PLIES, lod.YARN_MODEL_PLY_TWIST), f


def test_a_receding_object_is_split_by_each_curves_own_footprint():
    """Ten curves at depths 1 to 40 from the camera (17.6 px down to 0.44 px): each curve's width at its own nearest
    point, as ply_pixels gives it for one curve; Auto keeps the object's level (that of its nearest curve) and draws
    the curves under YARNS_BELOW_PLY_PIXELS as yarns once they are SPLIT_MIN_FAR_SHARE of them."""
    r, cam = 0.01, view()
    curves = [line(z, n=3 + k) for k, z in enumerate(np.linspace(-9.0, 30.0, 10))]
    pts, counts = np.vstack(curves), [len(c) for c in curves]
    per = lod.curve_ply_pixels(pts, counts, r, cam)
    assert per == pytest.approx([lod.ply_pixels(c, r, cam) for c in curves], rel=1e-12)
    c = lod.choose_level(pts, r, cam, curve_counts=counts)
    expect_far = tuple(k for k in range(10) if per[k] < lod.YARNS_BELOW_PLY_PIXELS)
    assert c.level == "plies" and c.ply_pixels == pytest.approx(per.max()) and 0 < len(expect_far) < 10
    assert c.far == expect_far
    # Without the curves, or a fixed level asked for: one level for the whole object.
    assert lod.choose_level(pts, r, cam).far == ()
    assert lod.choose_level(pts, r, cam, curve_counts=counts, requested="plies").far == ()
    # A curve wholly behind the camera has no width (it is not seen); an object on both sides of the camera is the
    # camera inside the cloth: plies, whole, with the warning.
    behind = line(-20.0)
    per = lod.curve_ply_pixels(np.vstack([pts, behind]), counts + [5], r, cam)
    assert np.isnan(per[-1]) and np.all(np.isfinite(per[:-1]))
    inside = lod.choose_level(np.vstack([pts, behind]), r, cam, curve_counts=counts + [5])
    assert (inside.level, inside.far) == ("plies", ()) and "inside" in inside.warning
    # Per-point radii: a curve's own widest ply decides.
    radii = np.concatenate([np.full(n, 2 * r if k == 9 else r) for k, n in enumerate(counts)])
    assert lod.curve_ply_pixels(pts, counts, radii, cam)[9] == pytest.approx(2 * lod.ply_pixels(curves[9], r, cam))
    with pytest.raises(ValueError):
        lod.curve_ply_pixels(pts, counts[:-1], r, cam)


def test_no_split_where_every_curve_is_far_by_its_own_radius():
    """A thin near curve and a thick far one: the object is plies by the thick ply's width at the nearest point, but
    each curve by its own is under the threshold; a split would leave no near yarns: the object stays whole."""
    cam = view()
    near, far = line(-9.0), line(30.0)  # depths 1 and 40
    radii = np.concatenate([np.full(5, 0.0005), np.full(5, 0.01)])
    pts = np.vstack([near, far])
    assert np.all(lod.curve_ply_pixels(pts, [5, 5], radii, cam) < lod.YARNS_BELOW_PLY_PIXELS)
    c = lod.choose_level(pts, radii, cam, curve_counts=[5, 5])
    assert (c.level, c.far) == ("plies", ())


def test_a_split_waits_for_a_tenth_of_the_yarns_and_never_comes_from_a_flat_view():
    r, cam = 0.01, view()
    near = [line(-9.0) for _ in range(19)]  # 17.6 px each
    far = [line(30.0)]                       # 0.44 px
    pts, counts = np.vstack(near + far), [5] * 20
    assert lod.choose_level(pts, r, cam, curve_counts=counts).far == ()  # 1 of 20: under a tenth
    pts, counts = np.vstack(near[:9] + far), [5] * 10
    assert lod.choose_level(pts, r, cam, curve_counts=counts).far == (9,)  # 1 of 10
    # Orthographic: every curve is as wide as the others; a far object is yarns whole, not split.
    assert lod.choose_level(pts, r, view(kind="ORTHO"), curve_counts=counts).far == ()
    whole = lod.choose_level(np.vstack(far * 3), r, cam, curve_counts=[5] * 3)
    assert (whole.level, whole.far) == ("yarns", ())
    # A camera it cannot use: plies, whole, with the warning.
    assert lod.choose_level(pts, r, None, curve_counts=counts) == lod.LevelChoice(
        "plies", None, "no scene camera: drawing plies")
