# SPDX-License-Identifier: Apache-2.0
"""One scene description, two writers (docs/decisions.md D37): `neuralyarn cycles-scene` writes a scene as Cycles
XML and as the description that the add-on's Blender builder reads (addon/scene_bpy.py, through
scripts/fallback_render.py with the bpy wheel). The two files of one call say the same, and Blender builds what the
description says: the same pixels at silhouettes, every integrator setting, the lights, the model."""
import json
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir))
BUILD = os.environ.get("NY_BUILD_DIR", os.path.join(ROOT, "build"))
CLI = os.path.join(BUILD, "cpp_core", "neuralyarn")
FALLBACK_RENDER = os.path.join(ROOT, "scripts", "fallback_render.py")
sys.path.insert(0, os.path.join(ROOT, "scripts"))


def cycles_scene(*args) -> str:
    r = subprocess.run([CLI, "cycles-scene", *map(str, args)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout


def floats(text: str) -> list[float]:
    return [float(v) for v in text.split()]


@pytest.mark.parametrize("args", [
    ["--preset", "silk", "--lights", "key-rim", "--unit-scale", "0.01", "--seed", "3"],
    ["--preset", "cotton", "--lights", "axis", "--layers", "2", "--artist-bounces"],
    ["--preset", "fleece", "--white-furnace", "--model", os.path.join(ROOT, "models", "fleece.json")],
])
def test_the_xml_and_the_description_of_one_call_agree(tmp_path, args):
    """Camera, film, integrator, background, lights and curves, field by field (the XML read as Cycles' XML
    reader reads it; a distant light's direction is its transform's third column)."""
    xml, desc = tmp_path / "s.xml", tmp_path / "s.json"
    out = cycles_scene(*args, "--width", "48", "--height", "24", "--out", xml, "--out", desc)
    assert out.count("wrote ") == 2
    root, d = ET.parse(xml).getroot(), json.loads(desc.read_text())
    assert d["format"] == "neuralyarn-scene 1"
    cam = root.find("camera").attrib
    assert (int(cam["width"]), int(cam["height"])) == (d["camera"]["width"], d["camera"]["height"])
    tr = root.find("transform")
    assert floats(tr.get("translate")) == pytest.approx(d["camera"]["position"], rel=1e-6)
    assert float(tr.find("camera").get("fov")) == pytest.approx(d["camera"]["fov"], rel=1e-6)
    assert root.find("film").attrib == {"filter_type": d["film"]["filter_type"],
                                        "filter_width": f"{d['film']['filter_width']:g}"}
    integ = root.find("integrator").attrib
    assert set(integ) == set(d["integrator"])
    for k, v in d["integrator"].items():
        assert (integ[k] == "true") == v if isinstance(v, bool) else float(integ[k]) == pytest.approx(v), k
    bg = root.find("background/background").attrib
    assert float(bg["strength"]) == d["background"]["strength"]
    assert floats(bg["color"]) == d["background"]["colour"]
    lights = list(root.iter("light"))
    assert len(lights) == len(d["lights"])
    for el, light in zip(lights, d["lights"]):
        assert el.get("light_type") == light["type"]
        tfm = np.array(floats(el.get("tfm"))).reshape(3, 4)
        assert floats(el.get("strength")) == pytest.approx([light["strength"]] * 3, rel=1e-6)
        if light["type"] == "point":
            assert tfm[:, 3] == pytest.approx(light["position"], rel=1e-6, abs=1e-9)
            assert float(el.get("size")) == pytest.approx(light["radius"], rel=1e-6)
        else:
            assert tfm[:, 2] == pytest.approx(light["direction"], abs=1e-6)
            assert float(el.get("angle")) == pytest.approx(light["angle"], rel=1e-6)
            assert el.get("use_camera") == ("true" if light["visible_to_camera"] else "false")
    hairs = list(root.iter("hair"))
    assert len(hairs) == len(d["objects"]) == 1
    curves = d["objects"][0]["curves"]
    assert [int(v) for v in hairs[0].get("nkeys").split()] == curves["keys"]
    assert floats(hairs[0].get("radius")) == pytest.approx(curves["radius"][:1], rel=1e-6)
    assert floats(hairs[0].get("P")) == pytest.approx(curves["points"], rel=1e-6, abs=1e-9)
    # The report the harness reads (scripts/evaluate.py: WRITTEN): the scene's own counts and camera.
    import evaluate as ev
    for line in out.splitlines():
        m = ev.WROTE.fullmatch(line)
        assert m, line
        assert (int(m.group(2)), int(m.group(3))) == (len(curves["keys"]), sum(curves["keys"]))
        assert [float(m.group(k)) for k in (4, 5, 6, 7)] == pytest.approx([*d["camera"]["position"], d["camera"]["fov"]])


def fallback_render(scene, exr, *args, timeout=300):
    return subprocess.run([sys.executable, FALLBACK_RENDER, str(scene), str(exr), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def both_renderers(tmp_path, width: int, height: int, *scene_args, spp: int = 64):
    """The images of one `cycles-scene SCENE_ARGS` call rendered by the standalone Cycles (its XML) and by Blender
    (its description): (standalone, blender)."""
    from images import read_exr

    xml, desc = tmp_path / "s.xml", tmp_path / "s.json"
    cycles_scene(*scene_args, "--width", width, "--height", height, "--out", xml, "--out", desc)
    standalone, blender = tmp_path / "standalone.exr", tmp_path / "blender.exr"
    r = subprocess.run([os.path.join(BUILD, "cycles", "bin", "cycles"), "--background", "--quiet", "--samples", str(spp),
                        "--width", str(width), "--height", str(height), "--output", str(standalone), str(xml)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    r = fallback_render(desc, blender, "--samples", spp)
    assert r.returncode == 0, r.stderr
    return read_exr(str(standalone)), read_exr(str(blender))


def test_blender_renders_the_scenes_pixel_filter(tmp_path):
    """The description states the pixel filter (Cycles' box, one pixel wide) and the builder applies it, so a
    silhouette falls on the same pixels in Blender as in the standalone Cycles. A grey diffuse curve (albedo
    0.5, `cycles-scene --diffuse`) under the uniform environment: a row reads 1 - 0.5 x the ply's coverage of
    it, 0.538 where the silhouette crosses (the box covers 0.924 of it). With Blender's default filter
    (Blackman-Harris, 1.5 pixels) the row outside the silhouette read 0.958 in Blender and 1.0 in the
    standalone. 64 spp over 80 columns put the rows' noise near 0.002."""
    from evaluate import CLOSEUP_DISTANCE, CLOSEUP_FOV, central_region

    standalone, blender = both_renderers(tmp_path, 160, 80, "--preset", "fleece", "--diffuse", "--lights", "environment")
    rows, cols = central_region(CLOSEUP_DISTANCE, CLOSEUP_FOV, 160, 80)
    a, b = (x[:, cols, :3].mean(axis=(1, 2)) for x in (standalone, blender))
    for y in (rows.start - 2, rows.start - 1, rows.stop, rows.stop + 1):  # outside, silhouette, both sides
        assert abs(a[y] - b[y]) < 0.01, (y, a[y], b[y])
    assert abs(a[rows.start - 1] - 0.538) < 0.01  # the box's coverage 0.924 of the silhouette row


def test_blender_and_the_standalone_agree_under_the_point_lights(tmp_path):
    """The key-rim rig's sphere lights as the standalone renders them: light sampling only, no MIS, so no ray
    hits them and the camera never sees the spheres. Blender's lights default to MIS and show the sphere
    (radiance ~50 against a frame mean ~0.05): the builder once left that on, and the rim light shone through
    a knit's holes in Blender only. A grey diffuse ply, 64 spp: the whole frame's mean within 3 %."""
    a, b = (x[..., :3] for x in both_renderers(tmp_path, 96, 48, "--preset", "fleece", "--diffuse", "--lights", "key-rim",
                                               "--camera-distance", 30))
    assert b.max() < 10.0 * a.max(), (a.max(), b.max())
    assert b.mean() == pytest.approx(a.mean(), rel=0.03), (a.mean(), b.mean())


INSPECT = """
import bpy, json, math, os, sys
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
s = bpy.context.scene
c = s.cycles
keys = {keys!r}
lights = [o for o in s.objects if o.type == "LIGHT"]
mats = [m for m in bpy.data.materials if m.users]
nodes = [n for m in mats for n in m.node_tree.nodes if n.bl_idname != "ShaderNodeOutputMaterial"]
print(json.dumps({{
    "cycles": {{k: getattr(c, k) for k in keys}},
    "filter": [c.pixel_filter_type, c.filter_width],
    "resolution": [s.render.resolution_x, s.render.resolution_y],
    "camera": [list(s.camera.location), s.camera.data.angle],
    "lights": [[o.data.type, o.data.energy, list(o.location), list(o.matrix_world.col[2])[:3],
                getattr(o.data, "shadow_soft_size", 0.0), getattr(o.data, "angle", 0.0), o.visible_camera,
                o.data.cycles.use_multiple_importance_sampling]
               for o in lights],
    "nodes": [n.bl_idname for n in nodes],
    # (the add-on is not registered here: its node's properties are read as stored)
    "model": [n["model"].as_string() for n in nodes if "model" in n.keys() and n["model"] is not None],
    "colour": [list(n.inputs[k].default_value)[:3] for n in nodes for k in ("Color", "Base Color") if k in n.inputs],
}}))
sys.stdout.flush()
os._exit(0)
"""


def built(tmp_path, name: str, *scene_args):
    """What Blender holds after building the description of `cycles-scene SCENE_ARGS` (saved, reopened)."""
    desc, blend = tmp_path / f"{name}.json", tmp_path / f"{name}.blend"
    cycles_scene(*scene_args, "--width", 32, "--height", 16, "--out", desc)
    r = fallback_render(desc, tmp_path / f"{name}.exr", "--samples", 1, "--save-blend", blend)
    assert r.returncode == 0, r.stderr
    keys = ["max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "transparent_max_bounces",
            "min_light_bounces", "sample_clamp_direct", "sample_clamp_indirect", "use_adaptive_sampling",
            "blur_glossy", "light_sampling_threshold", "seed"]
    r = subprocess.run([sys.executable, "-c", INSPECT.format(keys=keys), str(blend)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(desc.read_text()), json.loads(r.stdout.strip().splitlines()[-1])


def test_blender_takes_the_integrator_lights_and_camera_from_the_description(tmp_path):
    """Every integrator setting from the description, not Blender's defaults (which blur glossy bounces by 1,
    skip lights under 0.01 of a path's light, clamp indirect light at 10, sample adaptively), for two
    integrators; the camera and the point lights where the description puts them, with their power and size."""
    for name, args in (("default", ["--lights", "key-rim", "--seed", "9"]),
                       ("artist", ["--lights", "key-rim", "--artist-bounces", "--unit-scale", "0.5"])):
        d, got = built(tmp_path, name, "--preset", "fleece", "--diffuse", *args)
        i = d["integrator"]
        assert got["cycles"] == {
            "max_bounces": i["max_bounce"], "diffuse_bounces": i["max_diffuse_bounce"],
            "glossy_bounces": i["max_glossy_bounce"], "transmission_bounces": i["max_transmission_bounce"],
            "transparent_max_bounces": i["transparent_max_bounce"], "min_light_bounces": i["min_bounce"],
            "sample_clamp_direct": 0.0, "sample_clamp_indirect": 0.0, "use_adaptive_sampling": False,
            "blur_glossy": 0.0, "light_sampling_threshold": 0.0, "seed": i["seed"]}, name
        assert got["filter"] == ["BOX", 1.0] and got["resolution"] == [32, 16]
        assert got["camera"][0] == pytest.approx(d["camera"]["position"]) and got["camera"][1] == pytest.approx(0.9)
        assert len(got["lights"]) == 2
        for (kind, energy, location, _, size, _, visible, mis), light in zip(got["lights"], d["lights"]):
            assert kind == "POINT" and energy == pytest.approx(light["strength"], rel=1e-6)
            assert (visible, mis) == (light["visible_to_camera"], light["use_mis"]) == (False, False)
            assert location == pytest.approx(light["position"], rel=1e-6)
            assert size == pytest.approx(light["radius"], rel=1e-6)
    assert got["cycles"]["max_bounces"] == 12 and got["cycles"]["transparent_max_bounces"] == 64


def test_a_sun_shines_from_the_descriptions_direction(tmp_path):
    d, got = built(tmp_path, "sun", "--preset", "fleece", "--diffuse", "--lights", "sun-30-axis")
    ((kind, energy, _, z_axis, _, angle, visible, mis),) = got["lights"]
    assert kind == "SUN" and energy == pytest.approx(math.pi, rel=1e-6) and not visible and mis
    assert z_axis == pytest.approx(d["lights"][0]["direction"], abs=1e-6)  # +Z of the sun: toward the light
    assert angle == pytest.approx(math.radians(2.0), rel=1e-6)


def test_blender_renders_the_scenes_own_model_and_the_baselines(tmp_path):
    """A yarn beyond the presets (a tiny bake of a fiber parameter file): the node holds the model file that the
    description names (the fallbacks once took a preset's shipped model, and rendered presets only). The
    baselines as Blender's own nodes with the description's colour."""
    params = os.path.join(ROOT, "tests", "data", "good_custom.json")
    model = tmp_path / "my_wool.json"
    bake = subprocess.run([CLI, "bake", "--params", params, "--paths", "2e5", "--bins", "12x48x24x48", "--t-steps", "50",
                           "--r-steps", "50", "--m-steps", "50", "--t-samples", "2000", "--r-samples", "2000",
                           "--m-samples", "20000", "--fit-samples", "1000", "--out", str(model)],
                          capture_output=True, text=True, timeout=600)
    assert bake.returncode == 0, bake.stderr
    _, got = built(tmp_path, "custom", "--params", params, "--model", model)
    assert len(got["model"]) == 1
    assert json.loads(got["model"][0]) == json.loads(model.read_text())
    for method, node in (("chiang", "ShaderNodeBsdfHairPrincipled"), ("huang", "ShaderNodeBsdfHairPrincipled"),
                         ("sheen", "ShaderNodeBsdfPrincipled")):
        _, got = built(tmp_path, method, "--preset", "fleece", "--baseline", method, "--baseline-colour", 0.2, 0.4, 0.6)
        assert got["nodes"] == [node], method
        assert got["colour"][0] == pytest.approx([0.2, 0.4, 0.6], abs=1e-6), method


def test_explicit_fibers_are_refused_in_stock_blender(tmp_path):
    desc = tmp_path / "fibers.json"
    cycles_scene("--preset", "fleece", "--ply-length", 1, "--width", 16, "--height", 8, "--out", desc)
    r = fallback_render(desc, tmp_path / "x.exr")
    assert r.returncode == 1
    assert "explicit fibers need the Khungurn fiber closure" in r.stderr and "Traceback" not in r.stderr


def test_blender_renders_the_surface_level_as_the_standalone(tmp_path):
    """The surface level (docs/decisions.md D44) is stock closures: stock Blender must render its description as
    the standalone renders the XML — the sleeve's mid-surface, each closure weighted by the file's RGB curves of
    the view (a version-2 description: with meshes). A small fit (2e5 paths) of fleece's yarn-level model on the
    flat knit, the 3 x 3 sleeve under the key-rim rig, 64 spp each: the frame's mean per channel within 3 % (the
    two renderers' sampling noise; measured 0.1-0.2 % at 256 spp). Without the mesh the frame would be black."""
    import evaluate as ev

    flat, surface, material = tmp_path / "flat.json", tmp_path / "surface.json", tmp_path / "material.json"
    flat.write_text(json.dumps(ev.flat_knit_plies(ev.SURFACE_FIT["rows"], ev.SURFACE_FIT["stitches"])))
    r = subprocess.run([CLI, "surface", "--plies", flat, "--model", os.path.join(ROOT, "models", "fleece_yarn.json"),
                        "--paths", "2e5", "--quiet", "--out", surface, "--material-out", material,
                        "--pattern", '{"kind": "plain_knit"}'], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    os.makedirs(tmp_path / "scenes")
    framing = ev.garment_framing(str(tmp_path), 3, 96 / 64)
    a, b = (x[..., :3] for x in both_renderers(tmp_path, 96, 64, "--preset", "fleece", "--lights", "key-rim", *framing,
                                               "--level", "surface", "--surface", surface))
    desc = json.loads((tmp_path / "s.json").read_text())
    assert desc["format"] == "neuralyarn-scene 2"
    # The add-on's shipped form of the material (`--material-out`) is the description's, closure for closure.
    shipped = json.loads(material.read_text())
    assert shipped["format"] == "neuralyarn-cloth-surface 1" and shipped["pattern"] == {"kind": "plain_knit"}
    assert shipped["material"] == desc["meshes"][0]["material"]
    assert a.mean() > 1e-3 and (a.sum(axis=-1) > 1e-4).mean() > 0.1  # the sleeve is lit and in the frame
    assert b.mean(axis=(0, 1)) == pytest.approx(a.mean(axis=(0, 1)), rel=0.03)
