# SPDX-License-Identifier: Apache-2.0
"""The add-on inside Blender (the bpy wheel, 4.5, Cycles with OSL): operators, materials, renders, files.

Every test starts from an empty factory scene. Test data are written by the tests themselves (BCC through
the add-on's own writer, whose byte layout test_geometry.py checks against hand-made bytes; Leaf text by
hand). Bad input must end as an operator error (bpy.ops raises RuntimeError carrying the report) and leave
the file exactly as it was: same objects, curves data, materials, node groups, texts and images.

Renders are 64 x 64 at 4 samples on the CPU: enough to tell a finite, lit picture from NaN, black or the
error magenta (the fallbacks' numbers are test_osl_fallback.py's business). "Non-black" means the yarn
pixels (alpha > 0.5) have a mean luminance above 1e-3 under the demo lights, far above what an unlit or
failed shader gives (exactly 0) and far below what any preset gives (0.02-0.2, printed).
"""
from __future__ import annotations

import json
import math
import os
import struct

import pytest

np = pytest.importorskip("numpy")

from resources import PRESETS  # noqa: E402  (addon/ is on sys.path: conftest.py)
RES = 64


# ---------------------------------------------------------------------------------------------------------
# helpers


def snapshot(bpy) -> dict:
    """Everything an operator could leave behind."""
    return {
        "objects": sorted(o.name for o in bpy.data.objects),
        "curves": sorted(c.name for c in bpy.data.hair_curves),
        "materials": sorted(m.name for m in bpy.data.materials),
        "node_groups": sorted(g.name for g in bpy.data.node_groups),
        "texts": sorted(t.name for t in bpy.data.texts),
        "images": sorted(i.name for i in bpy.data.images),
    }


def curve_data(obj):
    """(number of curves, positions (n, 3), radii (n,)) of a Curves object."""
    d = obj.data
    n = len(d.points)
    pos = np.empty(n * 3, dtype=np.float32)
    d.position_data.foreach_get("vector", pos)
    rad = np.empty(n, dtype=np.float32)
    d.attributes["radius"].data.foreach_get("value", rad)
    return len(d.curves), pos.reshape(n, 3), rad


def write_bcc(addon, path, curves, **kw):
    addon.geometry.write_bcc(str(path), [np.asarray(c, dtype=float) for c in curves], **kw)


def helix(n=40, turns=2.0, r=3.0, pitch=4.0, phase=0.0):
    t = np.linspace(0.0, turns * 2 * math.pi, n)
    return np.stack([r * np.cos(t + phase), r * np.sin(t + phase), pitch * t / (2 * math.pi)], axis=1)


def render(bpy, scene, path, *, osl: bool):
    """Renders the scene to an EXR and returns its RGBA pixels (RES x RES x 4, float)."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.shading_system = osl
    scene.cycles.samples = 4
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = RES
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    px = np.empty(RES * RES * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(RES, RES, 4)


def yarn_luminance(px) -> float:
    mask = px[..., 3] > 0.5
    assert mask.sum() > 20, f"the yarns cover only {mask.sum()} of {RES * RES} pixels"
    rgb = px[mask][:, :3]
    return float((rgb @ np.array([0.2126, 0.7152, 0.0722])).mean())


def magenta_fraction(px) -> float:
    """The share of the lit yarn pixels in the error colour: magenta with no green at all, which both error
    paths give and no model does — stock Blender's emission (1, 0, 1) inside the add-on's node, and a patched
    Cycles' magenta diffuse, lit by the scene (a brightness threshold took its shaded side for a model)."""
    mask = px[..., 3] > 0.5
    rgb = px[mask][:, :3]
    lit = rgb.max(axis=1) > 0.0
    magenta = (rgb[:, 0] > 0.0) & (rgb[:, 2] > 0.0) & (rgb[:, 1] == 0.0)
    return float(magenta[lit].mean())


# ---------------------------------------------------------------------------------------------------------
# registration


def test_registers_node_and_operators(bpy, addon):
    assert bpy.types.Node.bl_rna_get_subclass_py("ShaderNodeNeuralYarnBsdf") is not None
    for op in ("import_bcc", "import_leaf", "add_knit", "add_weave", "make_plies", "assign_preset", "load_model"):
        assert hasattr(bpy.ops.neural_yarn, op), op
    assert hasattr(bpy.types, "VIEW3D_PT_neural_yarn")


# ---------------------------------------------------------------------------------------------------------
# BCC import


def test_import_bcc_catmull_rom_file(bpy, addon, empty, tmp_path):
    path = tmp_path / "two.bcc"
    write_bcc(addon, path, [helix(), helix(phase=math.pi)], curve_type="C0")
    r = bpy.ops.neural_yarn.import_bcc(filepath=str(path), scale=0.01, yarn_radius=0.25, up_axis="Z",
                                       samples_per_segment=4, preset="NONE")
    assert r == {"FINISHED"}
    obj = bpy.context.active_object
    assert obj.type == "CURVES" and obj.name == "two"
    n_curves, pos, rad = curve_data(obj)
    assert n_curves == 2
    # Catmull-Rom C0 files carry phantom end points: 40 control points = 37 segments x 4 samples + 1.
    assert len(pos) == 2 * (37 * 4 + 1)
    assert np.allclose(rad, 0.25 * 0.01)
    # Interpolating spline: the first evaluated point is the second control point, scaled.
    assert np.allclose(pos[0], helix()[1] * 0.01, atol=1e-6)
    assert obj.active_material is None


def test_import_bcc_y_up_and_closed_loops(bpy, addon, empty, tmp_path):
    ring = np.array([[math.cos(a), 0.0, math.sin(a)] for a in np.linspace(0, 2 * math.pi, 12, endpoint=False)])
    path = tmp_path / "ring.bcc"
    write_bcc(addon, path, [ring * 5.0], closed=[True], curve_type="PL", up=1)
    r = bpy.ops.neural_yarn.import_bcc(filepath=str(path), scale=1.0, yarn_radius=0.5, up_axis="Y",
                                       preset="fleece")
    assert r == {"FINISHED"}
    obj = bpy.context.active_object
    _, pos, _ = curve_data(obj)
    # Closed: Cycles has no cyclic curves, so the first point is repeated at the end.
    assert len(pos) == 13 and np.allclose(pos[0], pos[-1])
    # Y-up file: the ring lies in the file's x-z plane, which becomes Blender's x-y plane... (z -> -y)
    assert np.allclose(pos[:, 2], 0.0, atol=1e-5)
    assert obj.active_material.name == "Neural Yarn fleece"


def _bcc_variants(addon, tmp_path):
    good = addon.geometry.bcc_bytes([helix()], curve_type="C0")
    return {
        "truncated": (good[: len(good) - 17], r"truncated|ends|short|bytes"),
        "bad magic": (b"XYZ" + good[3:], r"not a BCC file|magic|BCC"),
        "bad curve type": (good[:4] + b"Q9" + good[6:], r"curve type|'Q9'"),
        "empty": (b"", r"empty|truncated|short|bytes"),
        # A NaN written over the coordinate 7.5 (the writer itself refuses non-finite points).
        "NaN point": (addon.geometry.bcc_bytes([np.array([[0, 0, 0], [1, 0, 0], [7.5, 1, 0], [2, 0, 0]], float)],
                                               curve_type="PL").replace(struct.pack("<f", 7.5),
                                                                        struct.pack("<f", float("nan"))),
                      r"non-finite|not finite|NaN|nan"),
    }


@pytest.mark.parametrize("case", ["truncated", "bad magic", "bad curve type", "empty", "NaN point"])
def test_import_malformed_bcc_reports_and_leaves_the_file_unchanged(bpy, addon, empty, tmp_path, case):
    bpy.ops.neural_yarn.add_weave(warps=2, wefts=2, preset="silk")  # something the user already has
    data, pattern = _bcc_variants(addon, tmp_path)[case]
    path = tmp_path / "bad.bcc"
    path.write_bytes(data)
    before = snapshot(bpy)
    with pytest.raises(RuntimeError, match=pattern) as e:
        bpy.ops.neural_yarn.import_bcc(filepath=str(path), preset="fleece")
    assert "bad.bcc" in str(e.value)
    assert snapshot(bpy) == before


def test_import_missing_file(bpy, addon, empty, tmp_path):
    before = snapshot(bpy)
    with pytest.raises(RuntimeError, match="nothing.bcc"):
        bpy.ops.neural_yarn.import_bcc(filepath=str(tmp_path / "nothing.bcc"))
    assert snapshot(bpy) == before


@pytest.mark.parametrize("scale, message", [(1e30, r"overflow|too large|scale"), (1e-12, r"scale|small|degenerate")])
def test_import_absurd_scale(bpy, addon, empty, tmp_path, scale, message):
    """Scales outside the operator's range are clamped by Blender; the reader refuses what still overflows."""
    path = tmp_path / "big.bcc"
    write_bcc(addon, path, [helix() * 1e10], curve_type="PL")
    before = snapshot(bpy)
    try:
        r = bpy.ops.neural_yarn.import_bcc(filepath=str(path), scale=scale, yarn_radius=1.0)
    except RuntimeError as e:
        assert "big.bcc" in str(e) or "big" in str(e)
        assert snapshot(bpy) == before
        return
    # Accepted: then every coordinate and radius must be finite and positive.
    assert r == {"FINISHED"}
    _, pos, rad = curve_data(bpy.context.active_object)
    assert np.isfinite(pos).all() and (rad > 0).all() and np.isfinite(rad).all()


# ---------------------------------------------------------------------------------------------------------
# Leaf patterns


def leaf_text(yarns) -> str:
    """The "Num Yarns" text layout: the yarn count, then per yarn its point count and one point per line."""
    lines = [f"Num Yarns: {len(yarns)}", ""]
    for y in yarns:
        lines.append(str(len(y)))
        lines += [" ".join(f"{v:.6f}" for v in p) for p in y]
        lines.append("")
    return "\n".join(lines)


def test_import_leaf_tiles_and_welds(bpy, addon, empty, tmp_path):
    # One tile of a plain weave: a warp along y and a weft along x, each crossing one period (4 units), ending
    # where the next tile's copy begins, so tiling welds them into long yarns.
    x = np.linspace(0.0, 4.0, 9)
    weft = np.stack([x, np.zeros_like(x), 0.3 * np.sin(x * math.pi / 2)], axis=1)
    warp = np.stack([np.zeros_like(x) + 2.0, x, -0.3 * np.sin(x * math.pi / 2)], axis=1)
    path = tmp_path / "plain.txt"
    path.write_text(leaf_text([weft, warp]))
    r = bpy.ops.neural_yarn.import_leaf(filepath=str(path), tiles_x=3, tiles_y=2, period_x=4.0, period_y=4.0,
                                        yarn_radius=0.4, scale=0.01, preset="cotton")
    assert r == {"FINISHED"}
    obj = bpy.context.active_object
    n_curves, pos, rad = curve_data(obj)
    # 3 x 2 tiles: wefts welded along x into 2 rows, warps welded along y into 3 columns.
    assert n_curves == 2 + 3
    assert np.allclose(rad, 0.004)
    # Text tiles are Catmull-Rom ('C0') with phantom end points: the welded weft runs from the second to the
    # second-to-last of its 3 x 8 + 1 control points, x = 0.5 .. 11.5 (spacing 0.5), times the scale.
    assert pos[:, 0].min() == pytest.approx(0.005, abs=1e-6)
    assert pos[:, 0].max() == pytest.approx(0.115, abs=1e-6)


@pytest.mark.parametrize("text, message", [
    ("Num Yarns: 2\n\n2\n0 0 0\n1 0 0\n", r"yarn 1|2 yarns|end of file|expected"),
    ("Num Yarns: 1\n\n3\n0 0 0\n1 zero 0\n2 0 0\n", r"line 5|zero|number"),
    ("Num Yarns: -1\n", r"Num Yarns|-1"),
    ("hello\n", r"Num Yarns"),
])
def test_import_malformed_leaf(bpy, addon, empty, tmp_path, text, message):
    path = tmp_path / "broken.txt"
    path.write_text(text)
    before = snapshot(bpy)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.neural_yarn.import_leaf(filepath=str(path))
    assert snapshot(bpy) == before


# ---------------------------------------------------------------------------------------------------------
# generators and plies


def test_knit_weave_and_plies(bpy, addon, empty):
    assert bpy.ops.neural_yarn.add_knit(rows=3, stitches=4, preset="NONE") == {"FINISHED"}
    knit = bpy.context.active_object
    n_knit, pos, rad = curve_data(knit)
    assert n_knit == 3
    width = pos[:, 0].max() - pos[:, 0].min()
    # Four stitches of Crane's 2 pi at scale 0.002, plus the loops' bulge and the radius.
    assert 4 * 2 * math.pi * 0.002 * 0.8 < width < 4 * 2 * math.pi * 0.002 * 1.6
    assert np.allclose(rad, 0.5 * 0.002)

    assert bpy.ops.neural_yarn.make_plies(plies=3, ply_twist=0.5, preset="gabardine") == {"FINISHED"}
    plies = bpy.context.active_object
    n_plies, ppos, prad = curve_data(plies)
    assert n_plies == 3 * n_knit
    assert plies.active_material.name == "Neural Yarn gabardine"
    # Plies fit inside the yarn: radius below the yarn's, centres within the yarn radius of its axis.
    assert (prad < 0.5 * 0.002).all() and (prad > 0.2 * 0.002).all()
    assert knit.hide_render and not plies.hide_render

    for weave in ("plain", "twill", "satin", "basket"):
        assert bpy.ops.neural_yarn.add_weave(weave=weave, warps=6, wefts=5, preset="NONE") == {"FINISHED"}
        assert curve_data(bpy.context.active_object)[0] == 11, weave


def test_make_plies_needs_a_curves_object(bpy, addon, empty):
    with pytest.raises(RuntimeError):
        bpy.ops.neural_yarn.make_plies()


def test_operators_register_as_undo_steps(bpy, addon, empty):
    """Each operator is registered as one undo step (bl_options REGISTER + UNDO; background mode has no undo
    stack to exercise, so this checks the declaration)."""
    for cls in addon.operators.CLASSES:
        assert "UNDO" in cls.bl_options and "REGISTER" in cls.bl_options, cls.__name__


# ---------------------------------------------------------------------------------------------------------
# level of detail (addon/level_of_detail.py)


def _knit_seen_from(bpy, addon, distance_factor: float):
    """A 2 x 2 knit with the fleece material, framed by the add-on's camera and then moved `distance_factor`
    times as far along its view; returns the knit."""
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="fleece")
    knit = bpy.context.active_object
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 320, 240, 100
    addon.scene_setup.frame(scene, [knit])
    cam, centre = scene.camera, sum((knit.matrix_world @ type(scene.camera.location)(c) for c in knit.bound_box),
                                    type(scene.camera.location)()) / 8
    cam.location = centre + (cam.location - centre) * distance_factor
    bpy.context.view_layer.update()
    return knit


def _apply_lod(bpy, obj):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    obj.hide_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.neural_yarn.apply_lod() == {"FINISHED"}


def test_level_of_detail_builds_the_level_the_camera_needs(bpy, addon, empty):
    """Near: ply curves with the preset's ply material, the yarns hidden; far: the yarns themselves with the
    yarn-level material, the plies hidden (kept, not rebuilt when the camera comes back)."""
    knit = _knit_seen_from(bpy, addon, 1.0)
    _apply_lod(bpy, knit)
    plies = knit.neural_yarn.plies_object
    assert knit.neural_yarn.chosen.startswith("plies (ply ") and plies is not None
    assert len(plies.data.curves) == 3 * len(knit.data.curves)
    assert plies.active_material.name == "Neural Yarn fleece" and not plies.hide_render and knit.hide_render
    assert addon.level_of_detail.stale_levels(bpy.context.scene) == []
    bpy.context.scene.camera.location *= 60.0  # the knit a few pixels wide
    bpy.context.view_layer.update()
    assert addon.level_of_detail.stale_levels(bpy.context.scene) == [
        "knit: plies applied, the camera now asks for yarns"]  # said before a render (render_pre)
    _apply_lod(bpy, plies)  # the plies stand for their yarns
    assert addon.level_of_detail.stale_levels(bpy.context.scene) == []
    assert knit.neural_yarn.chosen.startswith("yarns (ply ")
    assert knit.active_material.name == "Neural Yarn fleece yarn" and not knit.hide_render and plies.hide_render
    node = next(n for n in knit.active_material.node_tree.nodes if n.bl_idname == addon.nodes.NODE_IDNAME)
    assert (node.preset, node.level, node.error) == ("fleece", "YARNS", "")
    bpy.context.scene.camera.location /= 60.0
    bpy.context.view_layer.update()
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.plies_object == plies and not plies.hide_render and knit.hide_render
    assert sum(o.name.startswith(knit.name + " plies") for o in bpy.data.objects) == 1
    knit.neural_yarn.plies = 2  # another plying: new plies, the old ones hidden, not deleted
    _apply_lod(bpy, knit)
    two = knit.neural_yarn.plies_object
    assert two != plies and len(two.data.curves) == 2 * len(knit.data.curves) and plies.hide_render


def _receding_knit(bpy, addon, rows=20, plies=3):
    """A knit of `rows` courses seen by the add-on's camera (its courses recede from it, their plies ~1.5x wider
    at the near end than at the far one) at 400 px wide, and each course's ply width there, twisted into `plies`."""
    bpy.ops.neural_yarn.add_knit(rows=rows, stitches=2, preset="fleece")
    knit = bpy.context.active_object
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 400, 100, 100
    addon.scene_setup.frame(scene, [knit])
    bpy.context.view_layer.update()
    points, ply_radius = addon.level_of_detail.ply_radii(knit, plies)
    px = addon.geometry.lod.curve_ply_pixels(points, np.diff(addon.curves_bpy.curve_offsets(knit)), ply_radius,
                                             addon.level_of_detail.view_of(scene))
    return knit, px


def test_level_of_detail_splits_a_receding_knit_into_near_plies_and_far_yarns(bpy, addon, empty):
    """Auto on a knit whose courses recede past the threshold: its near courses' plies and its far courses as yarns,
    two part objects with their levels' materials, the knit hidden; the same split again reuses them; a camera that
    needs no split hides them (the whole plies made); a moved split remakes both and removes the old ones."""
    lod, ld = addon.geometry.lod, addon.level_of_detail
    knit, px = _receding_knit(bpy, addon)
    scene = bpy.context.scene
    width = int(round(400 * lod.YARNS_BELOW_PLY_PIXELS / np.median(px)))
    scene.render.resolution_x = width
    bpy.context.view_layer.update()
    expect_far = tuple(int(k) for k in np.flatnonzero(px * width / 400 < lod.YARNS_BELOW_PLY_PIXELS))
    assert 4 <= len(expect_far) <= 16, px  # the courses recede: a split of the knit, not all or nothing
    _apply_lod(bpy, knit)
    s = knit.neural_yarn
    near, far = s.near_plies_object, s.far_yarns_object
    assert s.applied == "plies+yarns" and s.chosen.startswith("plies+yarns (ply ")
    assert f"{len(expect_far)} of 20" in s.chosen
    assert ld.part_yarns(far) == expect_far and len(far.data.curves) == len(expect_far)
    assert len(near.data.curves) == 3 * (20 - len(expect_far)) and s.plies_object is None
    assert near.active_material.name == "Neural Yarn fleece" and far.active_material.name == "Neural Yarn fleece yarn"
    assert knit.hide_render and not near.hide_render and not far.hide_render
    assert ld.rendered_objects(knit) == [(near, "plies"), (far, "yarns")] and ld.stale_levels(scene) == []
    # The far yarns are the knit's own curves, in place.
    src = addon.curves_bpy.read_curves_object(knit)
    got = addon.curves_bpy.read_curves_object(far)
    assert all(np.allclose(src[k].points, g.points, atol=1e-6) for k, g in zip(expect_far, got))
    n_objects = len(bpy.data.objects)
    _apply_lod(bpy, far)  # a part stands for its knit; the same split: nothing made again
    assert (s.near_plies_object, s.far_yarns_object, len(bpy.data.objects)) == (near, far, n_objects)
    scene.render.resolution_x = width * 10  # every course's ply wide: one level, the whole plies
    bpy.context.view_layer.update()
    assert ld.stale_levels(scene) == ["knit: plies+yarns applied, the camera now asks for plies"]
    _apply_lod(bpy, knit)
    assert s.chosen.startswith("plies (ply ") and len(s.plies_object.data.curves) == 60
    assert near.hide_render and far.hide_render and not s.plies_object.hide_render
    scene.render.resolution_x = int(width * 0.9)  # the threshold nearer: more far courses
    bpy.context.view_layer.update()
    _apply_lod(bpy, knit)
    assert len(ld.part_yarns(s.far_yarns_object)) > len(expect_far) and s.plies_object.hide_render
    assert sum(o.name.startswith("knit near plies") for o in bpy.data.objects) == 1
    assert sum(o.name.startswith("knit far yarns") for o in bpy.data.objects) == 1


def test_level_of_detail_never_draws_plies_of_other_curves(bpy, addon, empty):
    """Plies are made of the yarns as they are: after the yarns are edited, a render says the plies are stale and
    Apply makes new ones (the old hidden, kept); a copy of the knit makes its own instead of showing the original's;
    the plies are the knit's children."""
    knit = _knit_seen_from(bpy, addon, 1.0)
    _apply_lod(bpy, knit)
    plies = knit.neural_yarn.plies_object
    assert plies.parent == knit and addon.level_of_detail.stale_levels(bpy.context.scene) == []
    pos = np.empty(len(knit.data.points) * 3, dtype=np.float32)
    knit.data.position_data.foreach_get("vector", pos)
    pos[2] += 0.01  # one point of one yarn moved
    knit.data.position_data.foreach_set("vector", pos)
    assert addon.level_of_detail.stale_levels(bpy.context.scene) == [
        "knit: its plies were made of other curves (or another number of plies)"]
    _apply_lod(bpy, knit)
    new = knit.neural_yarn.plies_object
    assert new != plies and plies.hide_render and not new.hide_render and plies.name in bpy.data.objects
    copy = knit.copy()  # as Shift+D: the pointers copied
    bpy.context.scene.collection.objects.link(copy)
    _apply_lod(bpy, copy)
    assert copy.neural_yarn.plies_object not in (None, new, plies) and not new.hide_render
    assert addon.level_of_detail.yarn_object_of(new, bpy.context.scene) == knit


def test_level_of_detail_parts_follow_their_knit_and_belong_to_it(bpy, addon, empty, monkeypatch):
    """The parts are the knit's children (moving it moves them; the same split is still theirs); a copy of the knit
    neither reuses nor removes the original's parts; a split whose build fails changes nothing."""
    ld = addon.level_of_detail
    knit, px = _receding_knit(bpy, addon)
    scene = bpy.context.scene
    scene.render.resolution_x = int(round(400 * addon.geometry.lod.YARNS_BELOW_PLY_PIXELS / np.median(px)))
    bpy.context.view_layer.update()
    _apply_lod(bpy, knit)
    s = knit.neural_yarn
    near, far = s.near_plies_object, s.far_yarns_object
    assert near.parent == knit and far.parent == knit and ld.yarn_object_of(far, scene) == knit
    before = np.array(addon.curves_bpy.read_curves_object(far)[0].points)
    knit.location.x += 0.25  # along the courses: the same footprints, the same split
    bpy.context.view_layer.update()
    assert np.allclose(np.array(addon.curves_bpy.read_curves_object(far)[0].points), before + [0.25, 0, 0],
                       atol=1e-5)
    _apply_lod(bpy, knit)
    assert (s.near_plies_object, s.far_yarns_object) == (near, far)
    # A copy (Shift+D copies the pointers): it makes parts of its own and leaves the original's alone.
    copy = knit.copy()
    scene.collection.objects.link(copy)
    copy.location += (knit.location - scene.camera.location) * 0.1  # a tenth farther: more far yarns
    bpy.context.view_layer.update()
    _apply_lod(bpy, copy)
    assert copy.neural_yarn.far_yarns_object not in (None, far) and copy.neural_yarn.near_plies_object != near
    assert far.name in bpy.data.objects and near.name in bpy.data.objects and not far.hide_render
    assert ld.yarn_object_of(far, scene) == knit and ld.yarn_object_of(copy.neural_yarn.far_yarns_object, scene) == copy
    # A copy that was never applied is stale, though its pointers show the original's parts for the same split.
    twin = knit.copy()
    scene.collection.objects.link(twin)
    assert f"{twin.name}: plies+yarns applied, the camera now asks for another split" in " ".join(
        ld.stale_levels(scene))
    bpy.data.objects.remove(twin)
    # A build that fails leaves every object as it was and adds none: the far part of a moved split, and the whole
    # plies after a split (whose parts a failure must not have hidden).
    names = sorted(o.name for o in bpy.data.objects)
    shown = {o.name: o.hide_render for o in bpy.data.objects}

    def fail(*_a, **_k):
        raise addon.geometry.GeometryError("no memory for them")
    for attr, width in (("make_yarns_part", 0.9), ("make_plies_object", 10.0)):
        scene.render.resolution_x = int(width * int(round(400 / np.median(px))))
        bpy.context.view_layer.update()
        assert ld.applied_name(ld.decide_level(knit, scene)) == ("plies+yarns" if width < 1 else "plies")
        with monkeypatch.context() as m:
            m.setattr(addon.operators, attr, fail)
            for o in bpy.context.view_layer.objects:
                o.select_set(False)
            knit.hide_set(False)
            knit.select_set(True)
            bpy.context.view_layer.objects.active = knit
            with pytest.raises(RuntimeError, match="no memory for them"):  # the operator's error report
                bpy.ops.neural_yarn.apply_lod()
            knit.hide_set(True)
        assert sorted(o.name for o in bpy.data.objects) == names, attr
        assert {o.name: o.hide_render for o in bpy.data.objects} == shown, attr
        assert (s.near_plies_object, s.far_yarns_object, s.applied) == (near, far, "plies+yarns")
    # A yarn object of zero scale has no plies to make: a clear error, nothing changed.
    knit.scale.z = 0.0
    bpy.context.view_layer.update()
    with pytest.raises(ValueError, match="zero scale"):
        ld.apply_level(bpy.context, knit, "plies")


def test_level_of_detail_splits_only_what_it_can_draw_as_yarns(bpy, addon, empty):
    """No split where the far yarns could not be drawn at the yarn level (another plying, an edited material: each
    says why), nor for a fixed level or an object whose Split by Distance is off: plies, whole."""
    knit, px = _receding_knit(bpy, addon, plies=2)
    scene = bpy.context.scene
    scene.render.resolution_x = int(round(400 * addon.geometry.lod.YARNS_BELOW_PLY_PIXELS / np.median(px)))
    bpy.context.view_layer.update()
    knit.neural_yarn.plies = 2  # its far half under the threshold: a split, if 2-ply yarns had a yarn-level model
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.chosen.startswith("plies (ply ") and "far yarns stay plies" in knit.neural_yarn.chosen
    assert knit.neural_yarn.far_yarns_object is None
    knit.neural_yarn.plies = 3
    node = next(n for n in knit.active_material.node_tree.nodes if n.bl_idname == addon.nodes.NODE_IDNAME)
    node.inputs[addon.fallback_nodes.GROUP_INPUT_TINT].default_value = (1.0, 0.5, 0.5, 1.0)
    _apply_lod(bpy, knit)
    assert "not a plain preset material" in knit.neural_yarn.chosen and knit.neural_yarn.far_yarns_object is None
    knit.neural_yarn.level = "PLIES"
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.chosen == "plies" and knit.neural_yarn.far_yarns_object is None
    node.inputs[addon.fallback_nodes.GROUP_INPUT_TINT].default_value = (1.0, 1.0, 1.0, 1.0)
    knit.neural_yarn.level = "AUTO"  # a plain material, 3 plies, Auto: split, unless the artist turned it off
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.applied == "plies+yarns"
    knit.neural_yarn.split = False
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.chosen.startswith("plies (ply ") and knit.neural_yarn.far_yarns_object.hide_render


class _Recorder:
    """A UILayout stand-in that records what is drawn: (kind, data, name or text)."""

    def __init__(self):
        self.drawn, self.active = [], True

    def column(self, **kw):
        return self

    row = column

    def prop(self, data, name, **kw):
        self.drawn.append(("prop", data, name))

    def label(self, text="", **kw):
        self.drawn.append(("label", None, text))

    def operator(self, idname, **kw):
        self.drawn.append(("operator", None, idname))


def test_level_of_detail_panel_shows_the_yarns_settings_for_their_plies(bpy, addon, empty):
    knit = _knit_seen_from(bpy, addon, 1.0)
    _apply_lod(bpy, knit)
    bpy.context.view_layer.objects.active = knit.neural_yarn.plies_object
    layout = _Recorder()
    addon.ui.VIEW3D_PT_neural_yarn.draw_level_of_detail(bpy.context, layout)
    props = [(d, n) for kind, d, n in layout.drawn if kind == "prop"]
    assert (bpy.context.scene, "neural_yarn_lod") in props
    assert (knit.neural_yarn, "level") in props and (knit.neural_yarn, "plies") in props
    assert (knit.neural_yarn, "split") in props
    assert ("label", None, f"Applied: {knit.neural_yarn.chosen}") in layout.drawn
    assert ("operator", None, "neural_yarn.apply_lod") in layout.drawn


def test_level_of_detail_never_twists_plies_again(bpy, addon, empty):
    """Plies made by Twist Plies and then cut loose from their yarns (the yarns deleted) are plies: applying a
    level to them keeps their curves, it does not twist each ply into three more."""
    knit = _knit_seen_from(bpy, addon, 1.0)
    bpy.ops.neural_yarn.make_plies()
    plies = bpy.context.active_object
    n = len(plies.data.curves)
    bpy.data.objects.remove(knit)
    bpy.context.view_layer.update()
    _apply_lod(bpy, plies)
    assert plies.neural_yarn.chosen.startswith("plies (ply ") and plies.neural_yarn.plies_object is None
    assert len(plies.data.curves) == n and not plies.hide_render
    assert sum(o.type == "CURVES" for o in bpy.data.objects) == 1


def test_level_of_detail_builds_no_plies_for_a_far_knit(bpy, addon, empty):
    knit = _knit_seen_from(bpy, addon, 60.0)
    before = len(bpy.data.objects)
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.chosen.startswith("yarns") and knit.neural_yarn.plies_object is None
    assert len(bpy.data.objects) == before


def test_level_of_detail_scene_override_and_fixed_levels(bpy, addon, empty):
    knit = _knit_seen_from(bpy, addon, 1.0)
    scene = bpy.context.scene
    scene.neural_yarn_lod = "YARNS"  # over the object's Auto, near as it is
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.chosen == "yarns" and knit.neural_yarn.plies_object is None
    scene.neural_yarn_lod = "OBJECT"
    knit.neural_yarn.level, knit.neural_yarn.plies = "PLIES", 1  # the curves are plies themselves
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.chosen == "plies" and knit.neural_yarn.plies_object is None
    assert knit.active_material.name == "Neural Yarn fleece" and not knit.hide_render


def test_level_of_detail_draws_a_default_knit_as_its_surface(bpy, addon, empty, tmp_path):
    """Asked for, the surface level draws a Knitted Swatch of the default shape as one quad over its stitches and
    rows (its face toward the knit's face), with the preset's fitted stock closures, the yarns hidden; rendered, it
    is lit, finite and covers about what the yarns cover."""
    knit = _knit_seen_from(bpy, addon, 3.0)
    scene = bpy.context.scene
    yarn_px = render(bpy, scene, tmp_path / "yarns.exr", osl=False)
    knit.neural_yarn.level = "SURFACE"
    _apply_lod(bpy, knit)
    surface = knit.neural_yarn.surface_object
    assert knit.neural_yarn.chosen == "surface" and knit.hide_render and not surface.hide_render
    assert surface.type == "MESH" and surface.parent == knit and len(surface.data.polygons) == 2
    assert all(p.normal.z > 0.99 for p in surface.data.polygons)  # the knit's face is +z
    mat = surface.active_material
    assert mat.name == "Neural Yarn fleece surface"
    curves = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeRGBCurve"]
    assert len(curves) == len(addon.level_of_detail.surface_material_of("fleece")["material"]["closures"]) >= 4
    px = render(bpy, scene, tmp_path / "surface.exr", osl=False)
    assert np.isfinite(px).all() and yarn_luminance(px) > 1e-3
    covered, yarn_covered = (px[..., 3] > 0.5).mean(), (yarn_px[..., 3] > 0.5).mean()
    assert 0.5 * yarn_covered < covered < 2.0 * yarn_covered, (covered, yarn_covered)
    knit.hide_set(False)
    knit.select_set(True)
    bpy.ops.neural_yarn.assign_preset(preset="cotton")  # another preset: the same quad, that preset's fit
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.surface_object == surface and surface.active_material.name == "Neural Yarn cotton surface"
    knit.neural_yarn.level = "AUTO"  # another level hides the surface; the surface selected stands for its knit
    _apply_lod(bpy, surface)
    assert surface.hide_render and [o.hide_render for o, _ in addon.level_of_detail.rendered_objects(knit)] == [False]


def test_level_of_detail_surface_faces_the_purl_side_and_refuses_other_cloth(bpy, addon, empty):
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="fleece", purl=True)
    purl = bpy.context.active_object
    purl.neural_yarn.level = "SURFACE"
    _apply_lod(bpy, purl)
    assert all(p.normal.z < -0.99 for p in purl.neural_yarn.surface_object.data.polygons)
    for op, kw in (("add_knit", {"yarn_radius": 0.4}), ("add_weave", {"warps": 4, "wefts": 4})):
        getattr(bpy.ops.neural_yarn, op)(preset="fleece", **kw)
        other = bpy.context.active_object
        other.neural_yarn.level = "SURFACE"
        _apply_lod(bpy, other)
        assert other.neural_yarn.chosen.startswith("yarns; warning: the surface level is fitted on"), op
        assert other.neural_yarn.surface_object is None


def test_level_of_detail_keeps_an_edited_material_at_the_ply_level(bpy, addon, empty):
    """A material with an artist's edit (here its tint) has no yarn-level twin the add-on could swap in without
    losing the edit: the object stays at the ply level, says why, and its material is untouched."""
    knit = _knit_seen_from(bpy, addon, 60.0)
    mat = knit.active_material
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == addon.nodes.NODE_IDNAME)
    node.inputs["Tint"].default_value = (0.5, 0.8, 1.0, 1.0)
    _apply_lod(bpy, knit)
    chosen = knit.neural_yarn.chosen
    assert chosen.startswith("plies") and "not a plain preset material" in chosen
    assert knit.active_material == mat and knit.neural_yarn.plies_object.active_material == mat
    assert tuple(node.inputs["Tint"].default_value) == pytest.approx((0.5, 0.8, 1.0, 1.0))


# ---------------------------------------------------------------------------------------------------------
# materials


@pytest.mark.parametrize("preset", PRESETS)
def test_assign_each_preset(bpy, addon, empty, preset):
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="NONE")
    r = bpy.ops.neural_yarn.assign_preset(preset=preset)
    assert r == {"FINISHED"}
    mat = bpy.context.active_object.active_material
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeNeuralYarnBsdf")
    assert node.error == "" and node.built == "NODES"  # EEVEE/Cycles SVM default: stock nodes
    assert node.preset == preset
    # The model is packed as a Text data block holding the shipped file's JSON verbatim.
    with open(os.path.join(addon.resources.resource_dir("models"), preset + ".json"), encoding="utf-8") as f:
        assert node.model.as_string() == f.read()
    # Assigning again reuses the material and the text.
    bpy.ops.neural_yarn.assign_preset(preset=preset)
    assert len([m for m in bpy.data.materials if m.name.startswith(f"Neural Yarn {preset}")]) == 1
    assert len([t for t in bpy.data.texts if t.name.startswith(f"NY model {preset}")]) == 1


def test_assign_preset_without_selection_reports(bpy, addon, empty):
    with pytest.raises(RuntimeError, match="select one or more Curves objects"):
        bpy.ops.neural_yarn.assign_preset(preset="silk")


def test_corrupt_packed_model_renders_error_colour(bpy, addon, empty, tmp_path):
    mat, node = addon.nodes.make_material("custom", preset="silk")
    text = bpy.data.texts.new("broken.json")
    text.from_string('{"format": "neuralyarn-model", "version": 2, "T": ')
    node.preset = "CUSTOM"
    node.model = text
    assert node.built == "ERROR" and "broken.json" in node.error
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="NONE")
    obj = bpy.context.active_object
    obj.data.materials.append(mat)
    addon_batch_frame(bpy, obj)
    px = render(bpy, bpy.context.scene, tmp_path / "error.exr", osl=False)
    assert magenta_fraction(px) > 0.9


def test_load_model_operator(bpy, addon, empty, tmp_path):
    mat, node = addon.nodes.make_material("custom", preset="fleece")
    mat.node_tree.nodes.active = node
    ctx = {"node": node}
    # A corrupt file: error report naming it, node unchanged.
    bad = tmp_path / "corrupt.json"
    bad.write_text("{ not json")
    with bpy.context.temp_override(**ctx):
        with pytest.raises(RuntimeError, match="corrupt.json"):
            bpy.ops.neural_yarn.load_model(filepath=str(bad))
    assert node.preset == "fleece" and node.built == "NODES"
    with bpy.context.temp_override(**ctx):
        with pytest.raises(RuntimeError, match="missing.json"):
            bpy.ops.neural_yarn.load_model(filepath=str(tmp_path / "missing.json"))
    # A good bake (here: a shipped file under another name) becomes a packed CUSTOM model.
    good = tmp_path / "my_bake.json"
    good.write_text(open(os.path.join(addon.resources.resource_dir("models"), "cotton.json")).read())
    with bpy.context.temp_override(**ctx):
        assert bpy.ops.neural_yarn.load_model(filepath=str(good)) == {"FINISHED"}
    assert node.preset == "CUSTOM" and node.model.name.startswith("NY model my_bake.json")
    assert node.error == ""


def test_fallback_follows_the_shading_system(bpy, addon, empty, needs_osl):
    """Auto: OSL inside when the scene renders with OSL on the CPU, stock nodes otherwise (render_pre)."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    mat, node = addon.nodes.make_material("m", preset="polyester")
    assert node.built == "NODES"
    assert not any(n.bl_idname == "ShaderNodeScript" for n in node.node_tree.nodes)
    scene.cycles.shading_system = True
    scene.cycles.device = "CPU"
    assert addon.nodes.sync(scene) == 1
    assert node.built == "OSL"
    assert any(n.bl_idname == "ShaderNodeScript" for n in node.node_tree.nodes)
    assert addon.nodes.sync(scene) == 0  # nothing to do the second time
    scene.cycles.shading_system = False
    assert addon.nodes.sync(scene) == 1 and node.built == "NODES"
    node.fallback = "OSL"
    assert node.built == "OSL"


# ---------------------------------------------------------------------------------------------------------
# renders


def addon_batch_frame(bpy, obj):
    """The add-on's camera and lights around `obj` (scene_setup.frame, as batch.py's demo scenes)."""
    import importlib
    importlib.import_module("neural_yarn.scene_setup").frame(bpy.context.scene, [obj])


@pytest.mark.parametrize("osl", [False, True], ids=["svm", "osl"])
@pytest.mark.parametrize("preset", PRESETS)
def test_render_each_preset(bpy, addon, empty, tmp_path, preset, osl, request):
    if osl:
        request.getfixturevalue("needs_osl")
    bpy.ops.neural_yarn.add_knit(rows=3, stitches=3, preset=preset)
    obj = bpy.context.active_object
    addon_batch_frame(bpy, obj)
    px = render(bpy, bpy.context.scene, tmp_path / f"{preset}.exr", osl=osl)
    node = next(n for n in obj.active_material.node_tree.nodes if n.bl_idname == "ShaderNodeNeuralYarnBsdf")
    assert node.built == ("OSL" if osl else "NODES")
    assert np.isfinite(px).all()
    lum = yarn_luminance(px)
    print(f"{preset} ({'OSL' if osl else 'nodes'}): mean yarn luminance {lum:.4f}")
    assert lum > 1e-3
    assert magenta_fraction(px) < 0.01


def test_packed_file_renders_without_model_files(bpy, addon, empty, tmp_path, monkeypatch, has_osl):
    """Save, reload and render with the shipped models/ unreachable: everything comes from the .blend."""
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=3, preset="silk")
    obj = bpy.context.active_object
    addon_batch_frame(bpy, obj)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.shading_system = has_osl  # saved with OSL on: the OSL body (script text) must be packed too
    scene.cycles.device = "CPU"
    blend = tmp_path / "swatch.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    reference = render(bpy, scene, tmp_path / "before.exr", osl=has_osl)

    monkeypatch.setattr(addon.resources, "_candidates", lambda sub: [str(tmp_path / "no" / sub)])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    node = next(n for m in bpy.data.materials if m.node_tree for n in m.node_tree.nodes
                if n.bl_idname == "ShaderNodeNeuralYarnBsdf")
    assert node.model is not None and node.error == ""
    after = render(bpy, scene, tmp_path / "after.exr", osl=has_osl)
    assert np.isfinite(after).all()
    assert np.allclose(after, reference, atol=1e-4), "the reloaded file renders differently"
    # Switching to stock nodes rebuilds the inside from the packed model, still without model files.
    after_nodes = render(bpy, scene, tmp_path / "nodes.exr", osl=False)
    assert node.built == "NODES" and yarn_luminance(after_nodes) > 1e-3


# ---------------------------------------------------------------------------------------------------------
# batch entry point (in-process; tests/addon/blender34_smoke.py runs it through a real `blender -b`)


def test_batch_run_writes_an_image(bpy, addon, empty, tmp_path):
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    out = tmp_path / "weave.png"
    bpy.ops.wm.read_factory_settings(use_empty=True)
    batch.run(["--preset", "cotton", "--scene", "weave", "--out", str(out), "--resolution", "48", "32",
               "--samples", "2", "--osl"])
    img = bpy.data.images.load(str(out))
    assert tuple(img.size) == (48, 32)
    px = np.empty(48 * 32 * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    assert px.reshape(-1, 4)[:, :3].max() > 0.02


@pytest.mark.parametrize("argv, message", [
    (["--preset", "wool", "--out", "x.png"], "unknown preset 'wool'"),
    (["--out", "/nonexistent/dir/x.png"], "does not exist"),
    (["--out", "x.bmp2"], "unknown image extension"),
    (["--model", "/nonexistent/m.json", "--out", "x.png"], "m.json"),
    (["--scene", "bcc:/nonexistent/y.bcc", "--out", "x.png"], "could not be made"),
    (["--plies", "0", "--out", "x.png"], "--plies must be between 1 and 16"),
    (["--scene", "sock", "--out", "x.png"], r"^--scene: unknown scene 'sock' \(auto, knit"),
    (["--samples", "many", "--out", "x.png"], "argument --samples: invalid int value"),
    (["--out"], "argument --out: expected one argument"),
])
def test_batch_errors(bpy, addon, empty, tmp_path, argv, message):
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    argv = [a if a != "x.png" and a != "x.bmp2" else str(tmp_path / a) for a in argv]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with pytest.raises(batch.BatchError, match=message):
        batch.run(argv)


# ---------------------------------------------------------------------------------------------------------
# data blocks shared between materials (issue 20, A1)


def _model_text_with(bpy, addon, preset, name, edit):
    data = json.loads(open(os.path.join(addon.resources.resource_dir("models"), f"{preset}.json")).read())
    edit(data)
    text = bpy.data.texts.new(name)
    text.from_string(json.dumps(data))
    return text


def _table_pixels(bpy, node, suffix):
    img = next(n.image for n in node.node_tree.nodes
               if n.bl_idname == "ShaderNodeTexImage" and n.image.name.endswith(suffix))
    px = np.empty(len(img.pixels), dtype=np.float32)
    img.pixels.foreach_get(px)
    return img, px.reshape(-1, 4)[:, :3]


def test_a_custom_model_renders_with_its_own_fallback_tables(bpy, addon, empty):
    """Same kernel, other fallback tables (a transparency table of 1): its own images and OSL text, and
    the first material's are left alone."""
    _mat1, fleece = addon.nodes.make_material("a", preset="fleece")

    def clear(data):
        data["fallback"]["P_T"] = [1.0] * len(data["fallback"]["P_T"])

    _mat2, custom = addon.nodes.make_material("b", model_text=_model_text_with(bpy, addon, "fleece", "clear.json",
                                                                                 clear))
    assert fleece.built == custom.built == "NODES"
    img1, px1 = _table_pixels(bpy, fleece, " P_T")
    img2, px2 = _table_pixels(bpy, custom, " P_T")
    assert img1 != img2
    assert np.all(px2 == 1.0)
    assert px1.min() < 0.9  # fleece's own table, untouched
    fleece.fallback = "OSL"
    script1 = next(n for n in fleece.node_tree.nodes if n.bl_idname == "ShaderNodeScript").script
    source1 = script1.as_string()
    custom.fallback = "OSL"
    script2 = next(n for n in custom.node_tree.nodes if n.bl_idname == "ShaderNodeScript").script
    assert script2 != script1
    assert script1.as_string() == source1


def test_a_material_switched_to_another_preset_is_not_reused_for_its_old_one(bpy, addon, empty):
    """Issue 20, A2: "Neural Yarn fleece" switched to silk in the node is renamed after silk, and asking for
    fleece again gives a fleece material."""
    fleece = addon.operators.preset_material("fleece")
    node = next(n for n in fleece.node_tree.nodes if n.bl_idname == addon.nodes.NODE_IDNAME)
    node.preset = "silk"
    assert fleece.name == "Neural Yarn silk"
    again = addon.operators.preset_material("fleece")
    assert again != fleece
    assert [n.preset for n in again.node_tree.nodes if n.bl_idname == addon.nodes.NODE_IDNAME] == ["fleece"]
    assert addon.operators.preset_material("silk") == fleece  # the switched one serves silk now
    # A name the artist chose is kept.
    fleece.name = "My scarf"
    node.preset = "cotton"
    assert fleece.name == "My scarf"


# ---------------------------------------------------------------------------------------------------------
# model files: the add-on refuses what the C++ loader refuses (issue 20, A3)

_CLI = os.environ.get("NY_CLI") or os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "build",
                                                 "cpp_core", "neuralyarn")


def _corruptions():
    """(name, edit of the JSON text) pairs; each leaves a model the C++ loader refuses."""
    def flat(edit):
        def apply(data):
            edit(data["kernel_flat"])
            return json.dumps(data)
        return apply

    def raw(edit):
        return lambda data: edit(json.dumps(data))

    def swap_offsets(f):
        f[14], f[15] = f[15], f[14]

    def near_field(band, key="through_bands"):
        """The model's near field with its last band of `key` replaced."""
        def apply(data):
            nf = dict(data["near_field"])
            nf[key] = nf[key][:-1] + [band]
            return json.dumps(dict(data, near_field=nf))
        return apply

    def stale_tables(data):
        data["fallback"]["kernel_flat_fnv1a64"] = "0123456789abcdef"
        return json.dumps(data)

    def entry_row(row, key="through_entry"):
        """The model's entry h (D73) with its last band's last row replaced."""
        def apply(data):
            nf = dict(data["near_field"])
            nf[key] = nf[key][:-1] + [nf[key][-1][:-1] + [row]]
            return json.dumps(dict(data, near_field=nf))
        return apply

    def entry_without_offsets(data):
        nf = {k: v for k, v in data["near_field"].items() if k != "reflected_bands"}
        return json.dumps(dict(data, near_field=nf))

    return [
        ("NaN in the kernel", raw(lambda t: t.replace('"kernel_flat": [5.0,', '"kernel_flat": [NaN,', 1))),
        ("Infinity in the kernel", flat(lambda f: f.__setitem__(40, 1e999))),
        ("short kernel", flat(lambda f: f.__delitem__(slice(-5, None)))),
        ("kernel layout 2 in a version 4 file", flat(lambda f: f.__setitem__(0, 2.0))),
        ("size field", flat(lambda f: f.__setitem__(1, f[1] + 1))),
        ("kappa_R 1.5", flat(lambda f: f.__setitem__(7, 1.5))),
        ("offsets out of order", flat(swap_offsets)),
        ("an R network of two outputs", flat(_two_output_r)),
        ("negative R azimuth density", flat(lambda f: f.__setitem__(len(f) - 4, -0.5))),
        ("TT share above 1", flat(lambda f: f.__setitem__(len(f) - 1, 1.5))),
        ("a layout 3 array in a version 4 file", lambda data: json.dumps(_as_version3(data, version=4))),
        ("R free path beyond 2 ply radii", lambda data: json.dumps(
            dict(data, r_free_path=3.0, kernel_flat=data["kernel_flat"][:26] + [3.0] + data["kernel_flat"][27:]))),
        ("R free path other than the kernel's", lambda data: json.dumps(dict(data, r_free_path=0.05))),
        ("an R free path with a layout 4 array", lambda data: json.dumps(dict(_as_layout4(data), r_free_path=0.0))),
        ("a kernel weight changed", flat(lambda f: f.__setitem__(60, f[60] + 0.25))),
        ("R node frames in a ply's array", lambda data: json.dumps(_as_layout6(data, frames=[1.0, 0.0] * 12))),
        ("R node frames in a ply's file", lambda data: json.dumps(dict(
            _as_layout6(data, frames=[1.0, 0.0] * 12),
            r_surface_frames={"spread": 0.6, "frames": [[1.0, 0.0] * 3] * 4}))),
        ("an R node frame that is not a rotation", lambda data: json.dumps(_as_layout6(data, frames=[1.1, 0.0] * 12))),
        ("stale fallback tables", stale_tables),
        ("no fallback bins", lambda data: _edit(["fallback", "theta_bins"], 0)(data)),
        ("1025 fallback bins", lambda data: _edit(["fallback", "phi_bins"], 1025)(data)),
        ("a near field band of eight quantiles", near_field([-0.1, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7])),
        ("a decreasing near field band", near_field([-0.1, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.65])),
        ("a near field band beyond 1000 radii", near_field([-2000.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8])),
        ("an entry-side near field band of eight quantiles",
         near_field([-0.1, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7], key="reflected_bands")),
        ("a near field of four bands", lambda data: json.dumps(dict(data, near_field=dict(
            data["near_field"], through_bands=data["near_field"]["through_bands"][:4])))),
        ("a pre-D72 near field decreasing", lambda data: json.dumps(dict(data, near_field={
            "axial_exit_through": [0.1, 0.2, 0.3, 0.4, 0.5, 0.45]}))),
        ("an entry h row of eight quantiles", entry_row([-0.9, -0.5, -0.2, 0.0, 0.1, 0.2, 0.3, 0.4])),
        ("an entry h beyond the width", entry_row([-0.9, -0.5, -0.2, 0.0, 0.1, 0.2, 0.3, 0.4, 1.5])),
        ("a decreasing entry h row", entry_row([-0.9, -0.5, -0.2, 0.0, 0.1, 0.2, 0.3, 0.4, 0.35], "reflected_entry")),
        ("an entry h band of nine rows", lambda data: json.dumps(dict(data, near_field=dict(
            data["near_field"], through_entry=[band[:9] for band in data["near_field"]["through_entry"]])))),
        ("an entry side's h without its offsets", entry_without_offsets),
    ]


def _two_output_r(f):
    """The R network's output width (its header's last width, RGB since D65) set to 2: neither 3 -> 1 nor 3 -> 3."""
    o = int(f[15])
    f[o + int(f[o]) + 1] = 2.0


def _core_fallback(model: str, out, theta_bins: int, phi_bins: int) -> str:
    """The model's text with fallback tables of the given size, as the core computes them."""
    import subprocess
    r = subprocess.run([_CLI, "fallback", model, "--out", str(out), "--theta-bins", str(theta_bins),
                        "--phi-bins", str(phi_bins)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return out.read_text()


def _as_layout5(data, fnv):
    """A layout 6 array without R node frames (a ply's, as the core writes it since D51) as layout 5 wrote it: the
    frames' offset dropped, the offsets one less; its fallback tables name the new array by its hash. The
    corruptions above and the layout helpers below edit a layout 5 array."""
    f = data["kernel_flat"]
    assert f[0] == 6.0 and f[27] == 0.0, "a ply's layout 6 array"
    old = f[:27] + f[28:]
    for k in (14, 15, 16, 17, 20):
        old[k] -= 1
    old[0], old[1] = 5.0, float(len(old))
    return dict(data, kernel_flat=old, fallback=dict(data["fallback"], kernel_flat_fnv1a64=fnv(old)))


def _as_layout4(data, fnv=None):
    """The model as a file before the R free path: a layout 4 array (the header without it, offsets one
    less), no "r_free_path" (the core reads it as 0); its fallback tables name that array by its hash `fnv`
    (left as they are without one)."""
    f = data["kernel_flat"]
    old = f[:26] + f[27:]
    for k in (14, 15, 16, 17, 20):
        old[k] -= 1
    old[0], old[1] = 4.0, float(len(old))
    out = {k: v for k, v in data.items() if k != "r_free_path"}
    out["kernel_flat"] = old
    if fnv:
        out["fallback"] = dict(data["fallback"], kernel_flat_fnv1a64=fnv(old))
    return out


def _as_layout6(data, fnv=None, frames=None):
    """The model with a layout 6 array (the R node frames' offset after the free path, offsets one more): as
    the core writes a ply's model now; `frames` (24 numbers) puts R node frames in the array (and nowhere
    else). Its fallback tables name the new array by its hash `fnv` (left as they are without one)."""
    f = data["kernel_flat"]
    new = f[:27] + [28.0 if frames else 0.0] + (frames or []) + f[27:]
    for k in (14, 15, 16, 17, 20):
        new[k] += 1 + len(frames or [])
    new[0], new[1] = 6.0, float(len(new))
    out = dict(data, kernel_flat=new)
    if fnv:
        out["fallback"] = dict(data["fallback"], kernel_flat_fnv1a64=fnv(new))
    return out


def _as_version3(data, version=3, fnv=None):
    """The model as a version 3 file wrote it: layout 3 (no TT fields in the header, azimuth rows without the
    TT share, the table under "r_azimuth"), the TT share dropped; its fallback tables name that array by its
    hash `fnv` (left out without one)."""
    f = data["kernel_flat"]
    header, az, bins = 27, int(f[20]), int(f[23])
    old = f[:24]
    for k in (14, 15, 16, 17, 20):
        old[k] -= header - 24
    old += f[header:az]
    for r in range(az, len(f), bins + 3):
        old += f[r:r + bins]
    old[0], old[1] = 3.0, float(len(old))
    out = {k: v for k, v in data.items() if k not in ("fallback", "r_shape", "r_free_path")}
    out.update(version=version, kernel_flat=old, r_azimuth=data["r_shape"])
    if fnv:
        out["fallback"] = dict(data["fallback"], kernel_flat_fnv1a64=fnv(old))
    return out


@pytest.mark.parametrize("case", [c[0] for c in _corruptions()] +
                         ["the shipped model", "the shipped model as layout 5", "a version 3 file", "a layout 4 file",
                          "a layout 6 file",
                          "1 x 1 fallback tables"])
def test_model_files_the_core_refuses_are_refused(bpy, addon, tmp_path, case):
    if not os.path.isfile(_CLI):
        pytest.skip(f"the core's CLI is not built at {_CLI}")
    import subprocess
    shipped = os.path.join(addon.resources.resource_dir("models"), "cotton.json")
    data = json.loads(open(shipped).read())
    fnv = addon.fallback.schema.fnv1a64_hex
    if data["kernel_flat"][0] == 6.0:  # re-fitted since D65: the cases are written against a layout 5 array
        data = _as_layout5(data, fnv)
    accepted = {"the shipped model": lambda: open(shipped).read(),
                "the shipped model as layout 5": lambda: json.dumps(data),
                "a version 3 file": lambda: json.dumps(_as_version3(data, fnv=fnv)),
                "a layout 4 file": lambda: json.dumps(_as_layout4(data, fnv=fnv)),
                "a layout 6 file": lambda: json.dumps(_as_layout6(data, fnv=fnv)),
                "1 x 1 fallback tables": lambda: _core_fallback(shipped, tmp_path / "one.json", 1, 1)}
    text = accepted[case]() if case in accepted else dict(_corruptions())[case](data)
    path = tmp_path / "model.json"
    path.write_text(text)
    core = subprocess.run([_CLI, "cycles-scene", "--preset", "cotton", "--model", str(path), "--out",
                           str(tmp_path / "scene.xml")], capture_output=True, text=True)
    if case in accepted:
        assert core.returncode == 0, core.stderr
        addon.model_io.parse_model(text, "model.json")
        return
    assert core.returncode != 0, f"the core accepts '{case}': the corruption tests nothing"
    with pytest.raises(addon.model_io.ModelFileError):
        addon.model_io.parse_model(text, "model.json")


def _edit(path, value):
    """An edit of the model's JSON object: set (or with value None delete) the key at `path`."""
    def apply(data):
        d = data
        for k in path[:-1]:
            d = d[k]
        if value is None:
            del d[path[-1]]
        else:
            d[path[-1]] = value
        return json.dumps(data)
    return apply


# Every message of model_io.parse_model and its fallback-table check, each from one edit of the shipped
# cotton model (issue 19: a test that kills the mutant which drops the add-on's alpha < 0 check, and its
# siblings).
_REJECTIONS = [
    ("not JSON", lambda data: json.dumps(data)[:-1], "not valid JSON"),
    ("format", _edit(["format"], "something-else"), "not a neural yarn model file"),
    ("version", _edit(["version"], 99), "model format version 99 is not supported"),
    ("no preset", _edit(["preset"], None), "missing 'preset' object with a 'name'"),
    ("negative alpha", _edit(["preset", "alpha"], -0.1), "preset 'alpha' must be a finite number >= 0"),
    ("no kernel", _edit(["kernel_flat"], None), "missing 'kernel_flat'"),
    ("no fallback", _edit(["fallback"], None), "has no \"fallback\" tables"),
    ("fallback not an object", _edit(["fallback"], [1, 2]), "fallback: must be an object"),
    ("fallback version", _edit(["fallback", "version"], 99), "fallback: version 99 is not supported"),
    ("fallback bins", _edit(["fallback", "theta_bins"], 0), "fallback: 'theta_bins' must be an integer in \\[1, 1024\\]"),
    ("P_T above 1", lambda data: _edit(["fallback", "P_T"], [1.5] + data["fallback"]["P_T"][1:])(data),
     "fallback: 'P_T' entry 0 = 1.5 is outside"),
    ("E_R short", lambda data: _edit(["fallback", "E_R"], data["fallback"]["E_R"][:-1])(data),
     "fallback: 'E_R' has 971 values, expected 972"),
    ("R network of two outputs", lambda data: (_two_output_r(data["kernel_flat"]), json.dumps(data))[1],
     "'kernel_flat' has a malformed R network \\(3 -> 1 or 3 -> 3, exp head\\)"),
    ("near field not an object", _edit(["near_field"], [0.1]), "'near_field' must be an object"),
    ("entry-side near field decreasing",
     _edit(["near_field", "reflected_bands"], [[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.45]] * 5),
     "'near_field' 'reflected_bands' decreases"),
    ("near field out of range",
     _edit(["near_field", "through_bands"], [[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 2000.0]] * 5),
     "'near_field' 'through_bands' holds a value that is not a finite number"),
    ("near field of three bands", _edit(["near_field", "through_bands"], [[0.0] * 9] * 3),
     "'near_field' 'through_bands' must hold five bands"),
    ("near field without its far side", _edit(["near_field", "through_bands"], None),
     "'near_field' must hold 'through_bands'"),
    ("pre-D72 near field decreasing", _edit(["near_field"], {"axial_exit_through": [0.1, 0.2, 0.3, 0.4, 0.5, 0.45]}),
     "'near_field' 'axial_exit_through' must hold six non-decreasing quantiles"),
    ("entry h beyond the width", _edit(["near_field", "through_entry"], [[[0.0] * 8 + [1.5]] * 10] * 5),
     "'near_field' 'through_entry' holds a value that is not a number in \\[-1, 1\\]"),
    ("entry h of nine rows", _edit(["near_field", "through_entry"], [[[0.0] * 9] * 9] * 5),
     "'near_field' 'through_entry' must hold ten rows per band"),
    ("entry h of four bands", _edit(["near_field", "reflected_entry"], [[[0.0] * 9] * 10] * 4),
     "'near_field' 'reflected_entry' must hold five bands"),
    ("entry h rows of eight quantiles", _edit(["near_field", "through_entry"], [[[0.0] * 8] * 10] * 5),
     "'near_field' 'through_entry' must hold nine quantiles per row"),
    ("entry h decreasing", _edit(["near_field", "reflected_entry"], [[[0.1] * 8 + [0.0]] * 10] * 5),
     "'near_field' 'reflected_entry' decreases"),
    ("entry h without its side's offsets", _edit(["near_field", "reflected_bands"], None),
     "'near_field' 'reflected_entry' needs the offsets of its side \\('reflected_bands'\\) as well"),
]


def test_a_near_field_from_before_d72_is_read(addon):
    """A model from before D72 holds six unsigned quantiles ('axial_exit_through'); the core converts them
    (kernel/exit_placement.h), so the add-on must take the file, not refuse it."""
    data = json.loads(open(os.path.join(addon.resources.resource_dir("models"), "cotton.json")).read())
    data["near_field"] = {"axial_exit_through": [0.18, 0.94, 2.8, 5.85, 8.6, 17.1],
                          "axial_exit_reflected": [0.01, 0.05, 0.2, 0.9, 2.0, 8.0]}
    addon.model_io.parse_model(json.dumps(data), "model.json")
    data["near_field"]["axial_exit_through"][5] = 5.0
    with pytest.raises(addon.model_io.ModelFileError, match="'axial_exit_through' must hold six non-decreasing"):
        addon.model_io.parse_model(json.dumps(data), "model.json")


@pytest.mark.parametrize("case", [c[0] for c in _REJECTIONS])
def test_every_model_file_rejection_names_its_key(addon, case):
    data = json.loads(open(os.path.join(addon.resources.resource_dir("models"), "cotton.json")).read())
    _, edit, message = next(c for c in _REJECTIONS if c[0] == case)
    with pytest.raises(addon.model_io.ModelFileError, match="^model.json: " + message):
        addon.model_io.parse_model(edit(data), "model.json")


@pytest.mark.parametrize("op", ["knit", "plies"])
def test_a_refused_object_leaves_no_material_behind(bpy, addon, empty, monkeypatch, op):
    """Issue 20, B6: the curves are refused at creation (here: Blender cannot make the Curves data); the
    preset's material, texts, images and node group must not stay in the file."""
    if op == "plies":
        bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="NONE")
    before = snapshot(bpy)

    def refuse(name, *args, **kw):
        raise addon.geometry.GeometryError(f"{name}: refused for the test")

    monkeypatch.setattr(addon.curves_bpy, "_new_curves_data", refuse)
    with pytest.raises(RuntimeError, match="refused for the test"):
        if op == "knit":
            bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="cotton")
        else:
            bpy.ops.neural_yarn.make_plies(preset="cotton")
    assert snapshot(bpy) == before


def test_presets_tried_do_not_stay_in_the_saved_file(bpy, addon, empty, tmp_path):
    """Issue 20, B7: switching a node through every preset packed every model; the saved file keeps only the
    model (and fallback data) in use, and the reopened file renders the last one."""
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="NONE")
    mat, node = addon.nodes.make_material("m", preset="fleece")
    bpy.context.active_object.data.materials.append(mat)
    for preset in PRESETS[1:]:
        node.preset = preset
        node.fallback = "OSL"
        node.fallback = "NODES"
    path = str(tmp_path / "tried.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    models = sorted(t.name for t in bpy.data.texts if t.name.startswith("NY model"))
    assert models == [f"NY model {PRESETS[-1]}.json"]
    assert not [t.name for t in bpy.data.texts if t.name.endswith(".osl")]  # NODES in use: no OSL text
    node = next(n for n in bpy.data.materials["m"].node_tree.nodes if n.bl_idname == addon.nodes.NODE_IDNAME)
    assert node.model is not None and node.model.name == models[0]
    # The file holds the tables of the model in use only.
    assert len({i.name.rsplit(" ", 1)[0] for i in bpy.data.images if i.name.startswith("NY ")}) == 1


def test_no_legacy_curve_is_left_in_the_file(bpy, addon, empty, tmp_path):
    """Issue 20, B5: Blender 3.4 makes Curves objects by converting a temporary legacy Curve, which kept a
    user and was saved with every object (a glove .blend 26.7 MB instead of 7.9 MB). Blender 4 makes them
    directly: there this checks that nothing else leaves one either."""
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="NONE")
    bpy.ops.neural_yarn.add_weave(warps=2, wefts=2, preset="NONE")
    path = str(tmp_path / "clean.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert [c.name for c in bpy.data.curves] == []
    assert len(bpy.data.hair_curves) == 2


# ---------------------------------------------------------------------------------------------------------
# what the artist sees (issue 20, C10, C13)


def test_swatches_are_added_at_the_3d_cursor_and_imports_keep_their_coordinates(bpy, addon, empty, tmp_path):
    bpy.context.scene.cursor.location = (1.0, -2.0, 3.0)
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="NONE")
    assert tuple(bpy.context.active_object.location) == pytest.approx((1.0, -2.0, 3.0))
    bpy.ops.neural_yarn.add_weave(warps=2, wefts=2, preset="NONE")
    assert tuple(bpy.context.active_object.location) == pytest.approx((1.0, -2.0, 3.0))
    path = tmp_path / "h.bcc"
    write_bcc(addon, path, [helix()], curve_type="PL")
    bpy.ops.neural_yarn.import_bcc(filepath=str(path), preset="NONE")
    assert tuple(bpy.context.active_object.location) == pytest.approx((0.0, 0.0, 0.0))


def test_frame_for_render_renders_with_this_blenders_defaults(bpy, addon, empty, tmp_path):
    """A swatch, Frame for Render, F12 with the scene's own settings (denoiser included): an image in which
    the yarn shows. Debian's Blender 3.4 has no OpenImageDenoise: F12 failed there until Denoise was off."""
    with pytest.raises(RuntimeError, match="no yarn curves"):
        bpy.ops.neural_yarn.frame_render()
    bpy.ops.neural_yarn.add_knit(rows=3, stitches=3, preset="fleece")
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.use_denoising = True  # what a new file has
    assert bpy.ops.neural_yarn.frame_render() == {"FINISHED"}
    assert scene.camera is not None and scene.cycles.transparent_max_bounces >= 64
    if not addon.scene_setup.has_denoiser():
        assert not scene.cycles.use_denoising
    scene.cycles.samples = 2
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 48, 32, 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "framed.exr")
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(tmp_path / "framed.exr"))
    px = np.empty(len(img.pixels), dtype=np.float32)
    img.pixels.foreach_get(px)
    alpha = px.reshape(-1, 4)[:, 3]
    assert (alpha > 0.5).mean() > 0.2  # the camera sees the swatch: a fifth of the frame or more


def test_batch_plies_twists_the_demo_yarns(bpy, addon, empty, tmp_path):
    """--plies 3: the knit demo's yarns become 3 plies each (the main job's knit, scripts/showcase.py).

    At 32 px the Auto level of detail would render yarns (no ply curves), so the ply level is asked for."""
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    out = tmp_path / "knit.png"
    common = ["--out", str(out), "--resolution", "32", "--samples", "1", "--lod", "plies"]
    batch.run(["--scene", "knit", *common])
    single = len(bpy.context.active_object.data.curves)
    batch.run(["--scene", "knit", "--plies", "3", *common])
    plied = bpy.context.active_object
    assert len(plied.data.curves) == 3 * single
    assert plied.active_material is not None and plied.active_material.name.startswith("Neural Yarn fleece")


def test_batch_applies_a_files_level_of_detail_for_its_own_camera(bpy, addon, empty, tmp_path, capsys):
    """A file whose knit had its level applied (plies, near) is rendered far away by batch: the level is applied
    again for the render's camera and size (yarns, the yarn-level material of --preset), the plies hidden; with
    --lod plies the file's Auto is overridden."""
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    knit = _knit_seen_from(bpy, addon, 1.0)
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.chosen.startswith("plies")
    bpy.context.scene.camera.location *= 60.0
    path = str(tmp_path / "knit.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    out = str(tmp_path / "far.png")
    common = ["--blend", path, "--out", out, "--resolution", "32", "--samples", "1", "--preset", "silk"]
    batch.run(common)
    assert "level of detail: knit: yarns (ply " in capsys.readouterr().out
    knit = bpy.data.objects["knit"]
    assert knit.active_material.name == "Neural Yarn silk yarn" and not knit.hide_render
    assert knit.neural_yarn.plies_object.hide_render
    batch.run(common + ["--lod", "plies"])
    assert "level of detail: knit: plies\n" in capsys.readouterr().out
    knit = bpy.data.objects["knit"]
    assert knit.hide_render and knit.neural_yarn.plies_object.active_material.name == "Neural Yarn silk"


def test_batch_renders_a_split_knit_with_each_parts_material(bpy, addon, empty, tmp_path, capsys):
    """A receding knit saved with Auto applied at a size that needs no split: batch applies it again for a render
    size that does, logs the split and gives the near plies and the far yarns it made --preset's material of their
    level; the image is lit."""
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    knit, px = _receding_knit(bpy, addon)
    width = int(round(400 * addon.geometry.lod.YARNS_BELOW_PLY_PIXELS / np.median(px)))
    bpy.context.scene.render.resolution_x = 10 * width
    _apply_lod(bpy, knit)
    assert knit.neural_yarn.applied == "plies"
    path = str(tmp_path / "knit.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    out = str(tmp_path / "split.png")
    batch.run(["--blend", path, "--out", out, "--resolution", str(width), "100", "--samples", "1",
               "--preset", "silk"])
    assert "level of detail: knit: plies+yarns (ply " in capsys.readouterr().out
    s = bpy.data.objects["knit"].neural_yarn
    assert s.near_plies_object.active_material.name == "Neural Yarn silk"
    assert s.far_yarns_object.active_material.name == "Neural Yarn silk yarn"
    img = bpy.data.images.load(out)
    px = np.empty(len(img.pixels), dtype=np.float32)
    img.pixels.foreach_get(px)
    assert px.reshape(-1, 4)[:, :3].max() > 0.05  # something lit is drawn


# ---------------------------------------------------------------------------------------------------------
# labels and tooltips (issue 20, C12)


def test_every_setting_has_a_tooltip(bpy, addon):
    missing = []
    for cls in addon.operators.CLASSES:
        op = getattr(bpy.ops.neural_yarn, cls.bl_idname.split(".")[1])
        missing += [f"{cls.bl_idname}.{p.identifier}" for p in op.get_rna_type().properties
                    if p.identifier != "rna_type" and not p.is_hidden and not p.description]
    node = addon.nodes.NeuralYarnBsdfNode
    missing += [f"node.{p.identifier}" for p in node.bl_rna.properties
                if p.identifier in node.__annotations__ and not p.description]
    assert missing == []


def test_import_scales_show_their_default(bpy, addon):
    for op in (bpy.ops.neural_yarn.import_bcc, bpy.ops.neural_yarn.import_leaf):
        scale = op.get_rna_type().properties["scale"]
        assert f"{scale.default:.{scale.precision}f}" != "0.00" and scale.precision >= 3


def test_the_node_shows_its_models_twist(bpy, addon, empty):
    """'Twist alpha' showed 0.24 for every preset; it shows the model's own alpha unless overridden."""
    _mat, node = addon.nodes.make_material("m", preset="silk")
    assert node.twist == pytest.approx(0.0)
    node.preset = "cotton"
    assert node.twist == pytest.approx(0.06, abs=1e-6)
    node.twist_override = True
    node.twist = 0.4
    node.preset = "fleece"
    assert node.twist == pytest.approx(0.4)


class _Layout:
    def __init__(self):
        self.props = []

    def prop(self, data, name, **kw):
        self.props.append(name)


@pytest.mark.parametrize("weave, shown, hidden", [
    ("plain", [], ["twill_up", "satin_harness", "basket_n"]),
    ("twill", ["twill_up", "twill_down"], ["satin_harness", "basket_n"]),
    ("satin", ["satin_harness", "satin_move"], ["twill_up", "basket_n"]),
    ("basket", ["basket_n"], ["twill_up", "satin_move"]),
])
def test_the_weave_panel_shows_the_settings_of_its_weave(bpy, addon, weave, shown, hidden):
    import types
    fake = types.SimpleNamespace(layout=_Layout(), weave=weave,
                                 WEAVE_SETTINGS=addon.operators.NEURALYARN_OT_add_weave.WEAVE_SETTINGS)
    addon.operators.NEURALYARN_OT_add_weave.draw(fake, None)
    assert all(n in fake.layout.props for n in shown + ["warps", "preset"])
    assert not any(n in fake.layout.props for n in hidden)


def test_batch_refuses_a_bad_extension_before_building_anything(bpy, addon, empty, tmp_path):
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    before = snapshot(bpy)
    with pytest.raises(batch.BatchError, match="unknown image extension '.bmp2'"):
        batch.run(["--scene", "knit", "--out", str(tmp_path / "x.bmp2")])
    assert snapshot(bpy) == before


@pytest.mark.parametrize("op", ["import_bcc", "import_leaf"])
def test_import_without_a_file_says_so(bpy, addon, empty, op):
    with pytest.raises(RuntimeError, match="no file given: choose a file to import"):
        getattr(bpy.ops.neural_yarn, op)(filepath="")


def test_a_model_file_on_one_line_packs_quickly(bpy, addon, empty, tmp_path):
    """Issue 20, D15: a model file written on one line froze Blender for seconds (its Text data block); it is
    packed re-indented, with the same values."""
    src = os.path.join(addon.resources.resource_dir("models"), "cotton.json")
    data = json.loads(open(src).read())
    path = tmp_path / "oneline.json"
    path.write_text(json.dumps(data, separators=(",", ":")))
    text = addon.nodes.pack_model_file(str(path))
    # (Measured: 3.6 s for the one 0.5 MB line, 0.03 s re-indented; the test checks the cause, not a time.)
    assert max(len(line.body) for line in text.lines) <= addon.nodes.MAX_PACKED_LINE
    packed = addon.nodes.parse_text(text)
    assert packed.data["kernel_flat"] == data["kernel_flat"] and packed.data["fallback"] == data["fallback"]


# ---------------------------------------------------------------------------------------------------------
# frame farms (issue 20; the farm itself: test_farm.py)


def test_batch_renders_frames_on_the_farm(bpy, addon, empty, tmp_path):
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    argv = ["--scene", "knit", "--frames", "1-3", "--resolution", "24", "--samples", "1", "--out",
            str(tmp_path / "knit_##.png")]
    if bpy.app.binary_path:  # a Blender executable: its Python has no Dask, so the driver must be named
        with pytest.raises(batch.BatchError, match="--farm-python"):
            batch.run(argv)
        return
    pytest.importorskip("distributed")
    outs = batch.run(argv).split(";")
    assert [os.path.basename(o) for o in outs] == ["knit_01.png", "knit_02.png", "knit_03.png"]
    for o in outs:
        img = bpy.data.images.load(o)
        assert tuple(img.size) == (24, 24)
        bpy.data.images.remove(img)
    mtimes = [os.path.getmtime(o) for o in outs]
    batch.run(argv)  # everything done: nothing rendered again
    assert [os.path.getmtime(o) for o in outs] == mtimes
    with pytest.raises(batch.BatchError, match="--frames: 'x' is not a frame"):
        batch.run(argv[:3] + ["x"] + argv[4:])


def test_eevee_sees_stock_nodes_while_the_node_holds_osl(bpy, addon, empty):
    """Issue 20, C8: with OSL inside, EEVEE and Material Preview drew the yarn black. The material then
    has an EEVEE output fed by the stock-node fallback, Cycles keeps the node; back to nodes, it goes."""
    mat, node = addon.nodes.make_material("m", preset="silk")
    tree = mat.node_tree
    outputs = lambda: sorted(n.target for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")  # noqa
    assert outputs() == ["ALL"]
    node.fallback = "OSL"
    assert node.built == "OSL" and outputs() == ["CYCLES", "EEVEE"]
    eevee = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n.target == "EEVEE")
    preview = eevee.inputs["Surface"].links[0].from_node
    kinds = {n.bl_idname for n in preview.node_tree.nodes}
    assert "ShaderNodeScript" not in kinds and any(k.startswith("ShaderNodeBsdf") for k in kinds)
    assert any(n.bl_idname == "ShaderNodeScript" for n in node.node_tree.nodes)
    node.preset = "cotton"  # the preview follows the model
    images = {n.image.name for n in preview.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"}
    assert images and all(name.startswith("NY cotton") for name in images)
    node.fallback = "NODES"
    assert outputs() == ["ALL"]


# ---------------------------------------------------------------------------------------------------------
# Blender's built-in Neural Yarn BSDF node (issue 22 (b); a Blender built with cycles_patch/ has it). In
# stock Blender the conversion is refused and changes nothing; the rest runs inside the patched Blender:
#     build/blender-full/blender -b --factory-startup --python-exit-code 1 -P tests/addon/run_in_blender.py \
#         -- -q -k builtin tests/addon/test_addon_bpy.py


@pytest.fixture
def needs_builtin(bpy, addon):
    if not addon.nodes.builtin_available():
        pytest.skip(f"Blender {bpy.app.version_string} has no built-in Neural Yarn BSDF node (patched Blender only)")


@pytest.fixture
def without_builtin(addon):
    if addon.nodes.builtin_available():
        pytest.skip("this Blender has the built-in node")


def test_builtin_node_conversion_is_refused_where_there_is_none(bpy, addon, empty, without_builtin):
    mat, node = addon.nodes.make_material("m", preset="silk")
    before = snapshot(bpy)
    with pytest.raises(ValueError, match="no built-in Neural Yarn BSDF node"):
        addon.nodes.convert_node(node, "BUILTIN")
    assert snapshot(bpy) == before
    assert [n.bl_idname for n in mat.node_tree.nodes].count(addon.nodes.NODE_IDNAME) == 1
    assert not bpy.ops.neural_yarn.convert_node.poll()


def test_material_of_a_preset_packs_that_preset_only(bpy, addon, empty):
    """A new node packs the default preset in its init; a material made for another preset (or a custom model)
    does not leave that Text behind among the file's Texts."""
    addon.nodes.make_material("a", preset="silk")
    assert {t.name for t in bpy.data.texts} == {"NY model silk.json"}
    addon.nodes.make_material("b", preset="cotton", level="yarns")
    assert {t.name for t in bpy.data.texts} == {"NY model silk.json", "NY model cotton_yarn.json"}
    fleece = addon.nodes.pack_preset("fleece")  # packed before, unused: not the node's to remove
    addon.nodes.make_material("c", preset="gabardine")
    assert fleece.name in bpy.data.texts and fleece.users == 0


def test_builtin_node_preset_is_recognised_by_content_not_name(bpy, addon, empty):
    """Converting back to the add-on's node restores the preset menu only for a Text that holds the
    shipped model exactly; an edited one stays a custom model."""
    text = addon.nodes.pack_preset("silk")
    assert addon.nodes._preset_of(text) == ("silk", "plies")
    edited = bpy.data.texts.new(text.name)  # "NY model silk.json.001"
    edited.from_string(text.as_string() + " ")  # the same JSON values, not the shipped file
    assert addon.nodes._preset_of(edited) is None
    other = bpy.data.texts.new("my model.json")
    other.from_string(text.as_string())
    assert addon.nodes._preset_of(other) is None


def test_builtin_node_round_trip_keeps_model_tint_links_and_name(bpy, addon, empty, needs_builtin):
    mat, node = addon.nodes.make_material("m", preset="silk")
    tree = mat.node_tree
    rgb = tree.nodes.new("ShaderNodeRGB")
    tree.links.new(rgb.outputs[0], node.inputs["Tint"])
    node.name, text = "Yarn", node.model
    texts = {t.name for t in bpy.data.texts}
    assert texts == {"NY model silk.json"}  # not the default preset the node packed before it took silk
    built, warnings = addon.nodes.convert_node(node, "BUILTIN")
    assert built.bl_idname == addon.nodes.BUILTIN_IDNAME and built.name == "Yarn" and not warnings
    assert built.model == text
    assert built.inputs["Tint"].links[0].from_node == rgb
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    assert out.inputs["Surface"].links[0].from_node == built
    back, _ = addon.nodes.convert_node(built, "ADDON")
    assert back.bl_idname == addon.nodes.NODE_IDNAME and back.name == "Yarn"
    assert (back.preset, back.level, back.model) == ("silk", "PLIES", text) and back.built == "NODES"
    assert back.inputs["Tint"].links[0].from_node == rgb
    assert out.inputs["Surface"].links[0].from_node == back
    assert {t.name for t in bpy.data.texts} == texts  # no default preset packed on the way


def test_builtin_node_renders_as_the_addon_node_and_keeps_its_model_in_the_file(bpy, addon, empty, tmp_path,
                                                                               needs_builtin):
    """Both nodes compile to the same closure from the same packed model: the same pixels. Saving purges the
    add-on's unused Texts, never the model a built-in node uses."""
    bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="cotton")
    bpy.ops.neural_yarn.frame_render()
    scene = bpy.context.scene
    addon_px = render(bpy, scene, tmp_path / "addon.exr", osl=False)
    node = next(addon.nodes.iter_nodes())
    addon.nodes.convert_node(node, "BUILTIN")
    builtin_px = render(bpy, scene, tmp_path / "builtin.exr", osl=False)
    assert yarn_luminance(builtin_px) > 1e-3 and magenta_fraction(builtin_px) == 0.0
    assert float(np.abs(builtin_px - addon_px).max()) <= 1e-5
    path = str(tmp_path / "builtin.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    builtin = [n for m in bpy.data.materials if m.node_tree for n in m.node_tree.nodes
               if n.bl_idname == addon.nodes.BUILTIN_IDNAME]
    assert len(builtin) == 1 and builtin[0].model is not None
    assert builtin[0].model.name == "NY model cotton.json"


BUILTIN_BLEND = os.path.join(os.path.dirname(__file__), os.pardir, "data", "builtin_neural_yarn_node.blend")


def test_a_builtin_node_from_a_patched_blender_is_named_and_a_batch_render_refused(bpy, addon, empty, tmp_path,
                                                                                   without_builtin):
    """A file saved in a patched Blender with its built-in node (tests/data/builtin_neural_yarn_node.blend, written
    by tests/addon/make_builtin_node_blend.py) opened in a Blender without it: the node is undefined there and
    its material would render black without a word from Blender. The add-on names it, and a batch render
    refuses instead of writing a wrong image."""
    if bpy.app.version < (4, 3, 0):
        pytest.skip(f"Blender {bpy.app.version_string} cannot read a file of Blender 4.3")
    import importlib
    batch = importlib.import_module("neural_yarn.batch")
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(BUILTIN_BLEND))
    assert addon.nodes.unrenderable_builtin_nodes() == [
        "material 'built-in yarn', node 'Neural Yarn BSDF'",
        "material 'grouped yarn', group 'yarn group', node 'Neural Yarn BSDF'"]
    out = tmp_path / "x.png"
    with pytest.raises(batch.BatchError, match="material 'built-in yarn'.*only a patched Blender has"):
        batch.run(["--blend", os.path.abspath(BUILTIN_BLEND), "--keep-materials", "--samples", "1", "--out", str(out)])
    assert not out.exists()
    bpy.ops.wm.read_factory_settings(use_empty=True)  # the add-on's own node is not taken for it
    addon.nodes.make_material("m", preset="silk")
    assert addon.nodes.unrenderable_builtin_nodes() == []
