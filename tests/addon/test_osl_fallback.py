# SPDX-License-Identifier: Apache-2.0
"""The OSL fallback (addon/fallback/: schema, lobes, osl and the template; osl/generate_osl.py its command
line) for the five shipped models.

Generator (plain Python): it refuses models without, or with corrupt or stale, "fallback" tables with a
ValueError before Blender sees anything, and fills every placeholder.

Rendering (the bpy wheel, Cycles on the CPU with OSL): for every shipped model, a scene built from
factory settings with one straight thick hair curve (radius 0.1, its axis turned 30 degrees toward the
camera, so every view has theta = -30 degrees in the yarn frame), an orthographic camera, a grey world and
a point light, and a material whose Script node holds the generated source. Pixels are sampled at their
centres (filter width 0.01), so every image row sees one known view direction: at height z on the curve,
phi = -asin(z / r). Asserted:
  * the script compiles and exposes the BSDF output; the render is finite everywhere;
  * lit by the point light (placed in the specular cone of the view) the curve is clearly brighter than by
    the grey world alone;
  * furnace (grey world, no light, transparent film): every row's alpha is 1 - P_T and its colour is
    0.5 (E_R + E_M_up + E_M_down) of the tables at that row's view, i.e. the built-in closures return
    exactly the energies they are weighted with, and the view-dependent lookup (frame, angles, bilinear
    interpolation) is the model's;
  * a close-up of the silhouette (phi from 50 to 88 degrees), where P_T rises to 0.4-0.99: the
    background shows through the curve exactly as much as P_T says.
"""
from __future__ import annotations

import copy

import json
import math
import os
import re
import subprocess
import sys
import time

import pytest

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir))
OSL_DIR = os.path.join(REPO, "osl")

# addon/ is on sys.path (conftest.py): the add-on's pure packages, as Blender runs them.
from fallback.lobes import glossy_node_inputs  # noqa: E402
from fallback.osl import generate_osl  # noqa: E402
from fallback.schema import fnv1a64_hex  # noqa: E402
from resources import PRESETS  # noqa: E402
RADIUS = 0.1
TILT = math.radians(30.0)   # the curve's axis against the image plane: theta = -30 degrees
WORLD = 0.5                 # grey world
RES = 64
SAMPLES = 64


def load_model(name: str) -> dict:
    with open(os.path.join(REPO, "models", name + ".json"), encoding="utf-8") as f:
        return json.load(f)


@pytest.fixture(scope="module")
def silk() -> dict:
    return load_model("silk")


# ---------------------------------------------------------------------------------------------------------
# generator


def test_generator_refuses_a_model_without_fallback(silk):
    m = copy.deepcopy(silk)
    del m["fallback"]
    with pytest.raises(ValueError, match=r"has no \"fallback\" tables; re-run `neuralyarn fallback MODEL`"):
        generate_osl(m)


@pytest.mark.parametrize("edit, message", [
    (lambda fb: fb.__setitem__("version", 1), r"fallback: version 1 is not supported"),
    (lambda fb: fb["P_T"].pop(), r"'P_T' has 323 values, expected 324"),
    (lambda fb: fb.__setitem__("theta_bins", 17), r"'P_T' has 324 values, expected 306"),
    (lambda fb: fb["E_R"].__setitem__(5, float("nan")), r"'E_R' entry 5 = nan is outside"),
    (lambda fb: fb["E_M_up"].__setitem__(7, None), r"'E_M_up' entry 7 is not a number"),
    (lambda fb: fb["P_T"].__setitem__(0, 1.2), r"'P_T' entry 0 = 1.2 is outside \[0, 1\]"),
    (lambda fb: fb["E_M_down"].__setitem__(1, -0.01), r"'E_M_down' entry 1 = -0.01 is outside \[0, 1.5\]"),
    (lambda fb: fb.__setitem__("twist_tilt_rad", float("inf")), r"'twist_tilt_rad' must be a finite number"),
    (lambda fb: fb.pop("twist_tilt_rad"), r"'twist_tilt_rad' must be a finite number"),
    (lambda fb: fb["W"].pop(), r"'W' has 5831 values, expected 5832"),
    (lambda fb: fb["W"].__setitem__(9, -1.0), r"'W' entry 9 = -1.0 is outside \[0, 100\]"),
    (lambda fb: fb["lobes"][0].__setitem__("alpha_x", 0.0), r"lobe 0 'alpha_x' must be a number in \[0.001, 1\]"),
    (lambda fb: fb["lobes"][4].__setitem__("closure", "hair"), r"lobe 4 must be an object whose 'closure' is one of"),
    (lambda fb: fb.__setitem__("lobes", []), r"'lobes' must be a list of 1 to 8 lobes"),
    (lambda fb: fb.__setitem__("phi_bins", "18"), r"'phi_bins' must be an integer"),
    (lambda fb: fb.__setitem__("kernel_flat_fnv1a64", "0123456789abcdef"), r"computed for another model"),
], ids=["version", "short", "bins", "nan", "null", "pt_above_one", "negative", "inf_scalar", "missing_scalar", "short_W",
            "negative_W", "alpha", "closure", "no_lobes",
        "string_bins", "stale"])
def test_generator_refuses_corrupt_tables(silk, edit, message):
    m = copy.deepcopy(silk)
    edit(m["fallback"])
    with pytest.raises(ValueError, match=message):
        generate_osl(m)


def test_generator_refuses_tables_of_a_changed_model(silk):
    """The tables belong to the kernel array they were computed for (FNV-1a 64, as the C++ loader checks)."""
    m = copy.deepcopy(silk)
    m["kernel_flat"][-1] = m["kernel_flat"][-1] * 0.5 + 0.25
    with pytest.raises(ValueError, match=r"re-run `neuralyarn fallback MODEL`"):
        generate_osl(m)
    assert fnv1a64_hex([]) == "cbf29ce484222325"
    assert fnv1a64_hex([1.0, -0.0, 2.5]) == "9a4c6dab8532d978"  # as tests/cpp/test_fallback.cpp


def test_generator_fills_the_template(silk):
    src = generate_osl(silk)
    assert not re.search(r"@[A-Z0-9_]+@", src), "a placeholder was left"
    assert "shader neural_yarn_fallback_silk(" in src
    assert generate_osl(silk, shader_name="my yarn").count("shader my_yarn(") == 1
    fb = silk["fallback"]
    # Every table value is written with float precision, in order.
    body = src[src.index("float P_T[324] = {") + len("float P_T[324] = {"):]
    values = [float(x) for x in body[:body.index("}")].replace("\n", " ").split(",")]
    assert values == [float("%.9g" % v) for v in fb["P_T"]]
    body = src[src.index("float W[5832] = {") + len("float W[5832] = {"):]
    values = [float(x) for x in body[:body.index("}")].replace("\n", " ").split(",")]
    assert values == [float("%.9g" % v) for v in fb["W"]]
    # One weighted closure per lobe, in the tables' order, with the lobes' roughnesses.
    calls = re.findall(r"ny_weight\(W, (\d+), [^)]*\) \* (\w+)\(([^)]*)\)", src)
    assert [int(k) for k, _, _ in calls] == list(range(len(fb["lobes"])))
    for (_, closure, args), lobe in zip(calls, fb["lobes"]):
        if lobe["closure"] == "ggx":
            assert closure == "microfacet"
            ax, ay = (float(a) for a in args.split(", ")[3:5])
            assert math.isclose(ax, lobe["alpha_x"], rel_tol=1e-8) and math.isclose(ay, lobe["alpha_y"], rel_tol=1e-8)
        else:
            assert closure == lobe["closure"] and args == "n"
    assert [lobe["closure"] for lobe in fb["lobes"]] == ["ggx"] * 4 + ["diffuse", "translucent"]
    # The Glossy node's (Roughness, Anisotropy) give Cycles' alphas back (roughness squared, then split).
    for ax, ay in ((0.016, 1.0), (0.3, 0.3), (0.001, 1.0)):
        rough, aniso = glossy_node_inputs(ax, ay)
        r = rough * rough
        assert math.isclose(r * (1 - aniso), ax, rel_tol=1e-9) and math.isclose(r / (1 - aniso), ay, rel_tol=1e-9)
        assert 0.0 <= aniso <= 0.99


def test_generator_command_line(tmp_path):
    out = tmp_path / "silk.osl"
    r = subprocess.run([sys.executable, os.path.join(OSL_DIR, "generate_osl.py"), os.path.join(REPO, "models", "silk.json"),
                        "-o", str(out)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert out.read_text().startswith("/* SPDX-License-Identifier")
    bad = tmp_path / "bad.json"
    m = load_model("silk")
    del m["fallback"]
    bad.write_text(json.dumps(m))
    r = subprocess.run([sys.executable, os.path.join(OSL_DIR, "generate_osl.py"), str(bad)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 1
    assert "bad.json" in r.stderr and "neuralyarn fallback" in r.stderr


# ---------------------------------------------------------------------------------------------------------
# rendering


def lookup(fb: dict, key: str, theta: float, phi: float, channel: int = 0) -> float:
    """The shader's bilinear lookup (clamped at the edges), in Python."""
    def cell(x, n):
        f = min(max((x + math.pi / 2) * n / math.pi - 0.5, 0.0), n - 1.0)
        i0 = min(int(math.floor(f)), n - 1)
        return i0, min(i0 + 1, n - 1), f - i0

    nt, np_ = fb["theta_bins"], fb["phi_bins"]
    i0, i1, a = cell(theta, nt)
    j0, j1, b = cell(phi, np_)
    stride, c = (1, 0) if key == "P_T" else (3, channel)
    t = fb[key]

    def v(i, j):
        return t[(i * np_ + j) * stride + c]

    return (1 - a) * (1 - b) * v(i0, j0) + (1 - a) * b * v(i0, j1) + a * (1 - b) * v(i1, j0) + a * b * v(i1, j1)


class Scene:
    """The test scene in a fresh factory-settings file; render() returns RGBA rows (bottom to top)."""

    def __init__(self, bpy, source: str, tmp_path, body: str = "script", preset: str = ""):
        import numpy as np

        self.bpy, self.np, self.tmp = bpy, np, tmp_path
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = self.scene = bpy.context.scene
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.shading_system = True
        scene.cycles.samples = SAMPLES
        scene.cycles.use_adaptive_sampling = False
        scene.cycles.use_denoising = False
        scene.cycles.filter_width = 0.01  # one view direction per pixel: its centre
        scene.cycles.seed = 1
        scene.render.resolution_x = scene.render.resolution_y = RES
        scene.render.resolution_percentage = 100
        scene.render.film_transparent = True
        scene.render.image_settings.file_format = "OPEN_EXR"
        scene.render.image_settings.color_depth = "32"
        scene.render.image_settings.color_mode = "RGBA"
        scene.view_settings.view_transform = "Standard"

        # One straight thick curve through the origin, its axis in the xy plane, turned by TILT toward the
        # camera (which looks along +y): the tangent t = (cos, sin, 0) gives theta = asin(-sin TILT).
        # (Made by the add-on's helper, which also works in Blender 3.4, where Curves cannot be resized.)
        from neural_yarn import curves_bpy
        import numpy as np

        ends = np.array([[s * math.cos(TILT), s * math.sin(TILT), 0.0] for s in (-1.0, 1.0)], dtype=np.float32)
        curves = curves_bpy._new_curves_data("yarn", [2], ends, np.full(2, RADIUS, dtype=np.float32))
        self.curve = bpy.data.objects.new("yarn", curves)
        scene.collection.objects.link(self.curve)

        cam = bpy.data.cameras.new("camera")
        cam.type = "ORTHO"
        self.camera = bpy.data.objects.new("camera", cam)
        self.camera.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looks along +y, image up = +z
        scene.collection.objects.link(self.camera)
        scene.camera = self.camera

        world = bpy.data.worlds.new("grey")
        world.use_nodes = True
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (WORLD, WORLD, WORLD, 1.0)
        scene.world = world
        light = bpy.data.lights.new("key", "POINT")
        light.energy = 1000.0
        light.shadow_soft_size = 0.2
        self.light = bpy.data.objects.new("key", light)
        # In the specular cone of the view (theta = +30 degrees: l.t = 1/2), 45 degrees above the camera's
        # direction: the surface fibers' R lobe reflects it toward the camera from the curve's upper half.
        self.light.location = tuple(2.0 * x for x in (0.739, -0.280, 0.612))
        scene.collection.objects.link(self.light)

        if body == "script":
            self.material_from_script(source)
        else:
            # The add-on's Neural Yarn BSDF node with the given fallback inside (OSL or stock nodes).
            from neural_yarn import nodes as ny_nodes

            mat, node = ny_nodes.make_material("yarn", preset=preset)
            node.fallback = body
            assert node.built == body, node.error
            self.compiled, self.reports, self.sockets = True, [], ["BSDF"]
            curves.materials.append(mat)

    def material_from_script(self, source: str):
        bpy = self.bpy
        text = bpy.data.texts.new("neural_yarn_fallback.osl")
        text.from_string(source)
        mat = bpy.data.materials.new("yarn")
        mat.use_nodes = True
        nodes = mat.node_tree.nodes
        for n in list(nodes):
            nodes.remove(n)
        script = nodes.new("ShaderNodeScript")
        script.mode = "INTERNAL"
        script.script = text
        import cycles.osl

        reports = []
        self.compiled = cycles.osl.update_script_node(script, lambda kind, msg: reports.append((kind, msg)))
        self.reports = reports
        self.sockets = [s.name for s in script.outputs]
        out = nodes.new("ShaderNodeOutputMaterial")
        if "BSDF" in script.outputs:
            mat.node_tree.links.new(script.outputs["BSDF"], out.inputs["Surface"])
        self.curve.data.materials.append(mat)

    def frame(self, center_z: float, scale: float):
        self.camera.location = (0.0, -3.0, center_z)
        self.camera.data.ortho_scale = scale
        self.center_z, self.scale = center_z, scale

    def row_height(self, row: int) -> float:
        return self.center_z + ((row + 0.5) / RES - 0.5) * self.scale

    def render(self, name: str, *, light: bool):
        bpy, np = self.bpy, self.np
        self.light.hide_render = not light
        path = str(self.tmp / (name + ".exr"))
        self.scene.render.filepath = path
        bpy.ops.render.render(write_still=True)
        img = bpy.data.images.load(path)
        px = np.empty(RES * RES * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        bpy.data.images.remove(img)
        return px.reshape(RES, RES, 4)


# "script": the generated OSL in a plain Script node; "NODES" / "OSL": the add-on's Neural Yarn BSDF node
# with that fallback inside (the stock-node body must give the same numbers as the OSL shader).
BODIES = [("script", p) for p in PRESETS] + [("NODES", p) for p in PRESETS] + [("OSL", "gabardine")]


@pytest.mark.parametrize("body, preset", BODIES)
def test_fallback_renders_the_tables(bpy, addon, body, preset, tmp_path, request):
    import numpy as np

    if body != "NODES":
        request.getfixturevalue("needs_osl")

    t0 = time.monotonic()
    model = load_model(preset)
    fb = model["fallback"]
    scene = Scene(bpy, generate_osl(model), tmp_path, body, preset)
    assert scene.compiled, f"the generated OSL did not compile: {scene.reports}"
    assert "BSDF" in scene.sockets
    theta = -TILT
    cols = slice(8, 56)  # away from the curve's ends

    # Whole cross-section, lit and in the furnace.
    scene.frame(0.0, 0.5)
    lit = scene.render("lit", light=True)
    furnace = scene.render("furnace", light=False)
    for img in (lit, furnace):
        assert np.isfinite(img).all(), "NaN or Inf in the render"
    on_curve = furnace[:, cols, 3] > 0.5
    assert on_curve.sum() > 20 * 48, "the curve does not cover the expected rows"
    lum = lambda img: float((img[:, cols, :3] @ np.array([0.2126, 0.7152, 0.0722]))[on_curve].mean())  # noqa: E731
    assert lum(furnace) > 0.005, "the curve is black"
    # The light (in the view's specular cone) adds clearly to what the grey world gives.
    print(f"{preset}: mean luminance on the curve {lum(furnace):.4f} (grey world), {lum(lit):.4f} (+ point light)")
    assert lum(lit) > 1.2 * lum(furnace), "the point light does not light the curve"

    # Colour: the tables' energies. Blender 3.x's Cycles evaluates GGX with the separable Smith masking
    # G1(i) G1(o) (4.0 changed it to the height-correlated form the weights were fitted with,
    # model/cycles_lobes.h), which reflects a few per cent less: there the stock-node body is darker by
    # a measured up to 7.8 % (of value + 0.02), a 3.x limit documented in osl/README.md.
    colour_tol = 0.05 if bpy.app.version >= (4, 0, 0) else 0.10
    rows = [r for r in range(RES) if abs(scene.row_height(r)) < 0.9 * RADIUS]
    assert len(rows) >= 20
    worst_alpha = worst_rel = 0.0
    for r in rows:
        phi = -math.asin(scene.row_height(r) / RADIUS)
        got = furnace[r, cols].mean(axis=0)
        worst_alpha = max(worst_alpha, abs(got[3] - 1.0 + lookup(fb, "P_T", theta, phi)))
        # Alpha: 1 - P_T (P_T < 0.05 here). Measured: within 0.003 on 4.5. Blender 3.4.1 renders the stock-node
        # body up to 1.6 % more transparent at |phi| = 15-65 degrees, where P_T < 2e-3, although the texture
        # coordinates and the P_T lookup there equal 4.5's to 1e-4 and each closure alone gives alpha 1 (an
        # unexplained difference of 3.4's Cycles when transparent and other closures are summed; see
        # osl/README.md): tolerance 0.02 on 3.x.
        alpha_tol = 0.01 if bpy.app.version >= (4, 0, 0) else 0.02
        assert got[3] == pytest.approx(1.0 - lookup(fb, "P_T", theta, phi), abs=alpha_tol), f"row {r}"
        for c in range(3):
            expect = WORLD * sum(lookup(fb, k, theta, phi, c) for k in ("E_R", "E_M_up", "E_M_down"))
            worst_rel = max(worst_rel, abs(got[c] - expect) / (expect + 0.02))
            # The tolerance is of (value + 0.02), the measure printed below. At 768 samples per row a row's noise
            # alone reached 6.4 % (silk's stock-node body at phi 48 degrees with D60's lobes: 1.7 % with seed 2),
            # so 3072 per row: on 4.5 within 0.6-2.0 % (silk worst), well inside 5 %.
            assert abs(got[c] - expect) <= colour_tol * (expect + 0.02), (
                f"row {r} (phi {math.degrees(phi):.0f}) channel {c}: {got[c]:.5f} against {expect:.5f}")

    # Close-up of the upper silhouette: rows from phi = -50 to -90 degrees.
    scene.frame(0.0885, 0.03)
    edge = scene.render("edge", light=False)
    assert np.isfinite(edge).all()
    seen, worst_edge = [], 0.0
    for r in range(RES):
        z = scene.row_height(r)
        if z > 0.9985 * RADIUS:  # within ~0.15 pixel of the silhouette: half-covered pixels
            continue
        phi = -math.asin(z / RADIUS)
        pt = lookup(fb, "P_T", theta, phi)
        alpha = float(edge[r, :, 3].mean())
        # Measured: within 0.008 (P_T itself ranges over 0 .. 0.91 in these rows).
        assert alpha == pytest.approx(1.0 - pt, abs=0.03), f"row {r} (phi {math.degrees(phi):.1f}): P_T {pt:.3f}"
        seen.append(pt)
        worst_edge = max(worst_edge, abs(alpha - 1.0 + pt))
    print(f"{preset}: furnace rows: alpha within {worst_alpha:.4f} of 1 - P_T, colour within {100 * worst_rel:.2f} % "
          f"(of value + 0.02); silhouette: alpha within {worst_edge:.3f} of 1 - P_T, P_T up to {max(seen):.2f}; "
          f"{time.monotonic() - t0:.1f} s")
    assert max(seen) > 0.3, "the close-up does not reach views where the yarn is see-through"
    assert time.monotonic() - t0 < 30.0
