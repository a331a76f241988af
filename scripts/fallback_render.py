# SPDX-License-Identifier: Apache-2.0
"""Renders a standalone-Cycles reference scene (`neuralyarn cycles-scene` / examples/make_examples.py XML)
in Blender (the bpy wheel) with the add-on's fallback instead of the native closure, for
scripts/bench_fallback.sh:

    .venv/bin/python scripts/fallback_render.py SCENE.xml OUT.exr --preset P --body osl|nodes|diffuse
                     [--samples N] [--seed S]

The scene is rebuilt element by element: <camera width height>, <film> (the pixel filter), the perspective
camera's translation and fov (vertical, as the standalone's auto viewplane for width >= height), point
lights (tfm translation,
strength = Blender's energy, size = radius: what Blender's own light sync passes to Cycles), distant lights
(a sun: the transform's -Z, strength = its energy, angle), the
background's strength and colour, the integrator's settings, and the <hair> curves with their radii.
--body diffuse gives the curves a grey Diffuse BSDF instead (the scene-equivalence check; the XML is then
expected to hold the same diffuse shader). The standalone camera is left-handed (x right, y up, looking
along +z) and Blender's right-handed, so Blender's image is the standalone's mirrored: it is flipped back
before writing. Exits 1 with a message on a scene it cannot read.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np

import bpy
import mathutils

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))


#: <integrator> attributes of the standalone, the Blender property each sets, and the standalone's default
#: (intern/cycles/scene/integrator.cpp, Cycles 4.3).
INTEGRATOR = (
    ("max_bounce", "max_bounces", 7),
    ("max_diffuse_bounce", "diffuse_bounces", 7),
    ("max_glossy_bounce", "glossy_bounces", 7),
    ("max_transmission_bounce", "transmission_bounces", 7),
    ("transparent_max_bounce", "transparent_max_bounces", 7),
    ("min_bounce", "min_light_bounces", 0),
    ("sample_clamp_direct", "sample_clamp_direct", 0.0),
    ("sample_clamp_indirect", "sample_clamp_indirect", 10.0),
    ("use_adaptive_sampling", "use_adaptive_sampling", True),
    ("filter_glossy", "blur_glossy", 0.0),
    ("light_sampling_threshold", "light_sampling_threshold", 0.0),
)

#: The standalone's <film filter_type> names and Blender's.
PIXEL_FILTERS = {"box": "BOX", "gaussian": "GAUSSIAN", "blackman_harris": "BLACKMAN_HARRIS"}


def xml_value(text: str, like):
    """An attribute as the standalone's XML reader takes it, of the type of `like` (a bool is "true" or a
    non-zero integer)."""
    if isinstance(like, bool):
        return text.strip().lower() == "true" or (text.strip().lstrip("-").isdigit() and int(text) != 0)
    return float(text) if isinstance(like, float) else int(text)


def floats(text: str) -> np.ndarray:
    return np.array([float(v) for v in text.split()], dtype=np.float64)


def load_addon():
    """The add-on of this checkout (addon/), registered, through addon/batch.py's own loader."""
    sys.path.insert(0, os.path.join(ROOT, "addon"))
    import batch  # addon/batch.py: bpy and the standard library only, no relative imports
    return batch.addon_module()


def build(xml_path: str, preset: str, body: str, samples: int, seed: int):
    root = ET.parse(xml_path).getroot()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ny = load_addon()
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.shading_system = body == "osl"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.seed = seed
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    # The scene's pixel filter (<film>; without one, the standalone's default: a box one pixel wide), not
    # Blender's default (Blackman-Harris, 1.5 pixels), which spreads a silhouette over more rows.
    film = root.find("film")
    film = film.attrib if film is not None else {}
    filter_type = film.get("filter_type", "box")
    if filter_type not in PIXEL_FILTERS:
        raise SystemExit(f"{xml_path}: unknown <film filter_type=\"{filter_type}\"> (known: {', '.join(PIXEL_FILTERS)})")
    scene.cycles.pixel_filter_type = PIXEL_FILTERS[filter_type]
    scene.cycles.filter_width = float(film.get("filter_width", 1.0))
    scene.cycles_curves.shape = "THICK"

    cam_el = root.find("camera")
    scene.render.resolution_x = int(cam_el.get("width"))
    scene.render.resolution_y = int(cam_el.get("height"))
    scene.render.resolution_percentage = 100
    tr = root.find("transform")
    persp = tr.find("camera") if tr is not None else None
    if persp is None or persp.get("type", "perspective") != "perspective":
        raise SystemExit(f"{xml_path}: expected <transform translate=...><camera type=\"perspective\" fov=.../>")
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.sensor_fit = "VERTICAL" if scene.render.resolution_x >= scene.render.resolution_y else "HORIZONTAL"
    cam.data.angle = float(persp.get("fov"))
    cam.data.clip_start, cam.data.clip_end = 0.01, 1e4
    cam.location = tuple(floats(tr.get("translate")))
    cam.rotation_euler = (0.0, math.pi, 0.0)  # look along +z, +y up, right = -x: the image is mirrored in x
    scene.collection.objects.link(cam)
    scene.camera = cam

    # Every integrator setting the standalone reads, with its default where the scene omits it (not
    # Blender's: they differ in bounces, clamping, adaptive sampling, glossy blur and the light threshold).
    integ = root.find("integrator")
    for attr, prop, default in INTEGRATOR:
        text = integ.get(attr) if integ is not None else None
        setattr(scene.cycles, prop, default if text is None else xml_value(text, default))

    world = bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    bg_el = root.find("background/background")
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*floats(bg_el.get("color", "1 1 1")), 1.0)
    bg.inputs["Strength"].default_value = float(bg_el.get("strength", 1.0))

    for k, light_el in enumerate(root.iter("light")):
        kind = light_el.get("light_type")
        if kind not in ("point", "distant"):
            raise SystemExit(f"{xml_path}: only point and distant lights are supported")
        tfm = floats(light_el.get("tfm")).reshape(3, 4)
        strength = floats(light_el.get("strength"))
        light = bpy.data.lights.new(f"light{k}", "POINT" if kind == "point" else "SUN")
        light.energy = float(strength.max())  # Blender's sync passes energy (W, or W/m^2 for a sun) as strength
        light.color = tuple(strength / strength.max())
        obj = bpy.data.objects.new(f"light{k}", light)
        if kind == "point":
            light.shadow_soft_size = float(light_el.get("size", 0.0))
            if hasattr(light, "use_soft_falloff"):
                light.use_soft_falloff = False  # Blender 4.0+'s default; the standalone light has none
            obj.location = tuple(tfm[:, 3])
        else:
            # Both shine along -Z of their transform; the angle is the disc's full angular diameter in both.
            light.angle = float(light_el.get("angle", 0.0))
            m = np.eye(4)
            m[:3, :] = tfm
            obj.matrix_world = mathutils.Matrix(m.tolist())
        obj.visible_camera = light_el.get("use_camera", "true") != "false"
        scene.collection.objects.link(obj)

    if body == "diffuse":
        mat = bpy.data.materials.new("diffuse")
        mat.use_nodes = True
        nt = mat.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        nt.links.new(d.outputs[0], out.inputs["Surface"])
    else:
        mat, node = ny.nodes.make_material(f"yarn {preset}", preset=preset)
        node.fallback = body.upper()
        if node.error:
            raise SystemExit(f"{preset}: {node.error}")

    hairs = list(root.iter("hair"))
    if not hairs:
        raise SystemExit(f"{xml_path}: no <hair> element")
    sizes, P, R = [], [], []
    for h in hairs:
        nkeys = [int(v) for v in h.get("nkeys").split()]
        p = floats(h.get("P")).reshape(-1, 3)
        r = floats(h.get("radius"))
        r = np.full(len(p), r[0]) if len(r) == 1 else r
        sizes += nkeys
        P.append(p)
        R.append(r)
    data = ny.curves_bpy._new_curves_data("yarn", sizes, np.concatenate(P).astype(np.float32),
                                          np.concatenate(R).astype(np.float32))
    data.materials.append(mat)
    obj = bpy.data.objects.new("yarn", data)
    scene.collection.objects.link(obj)
    return scene


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", help="the XML scene, or with --open-blend a .blend saved by --save-blend")
    ap.add_argument("out")
    ap.add_argument("--preset", required=True)
    ap.add_argument("--body", choices=("osl", "nodes", "diffuse"), required=True)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    ap.add_argument("--save-blend", help="also save the scene as this .blend (models and images packed)")
    ap.add_argument("--open-blend", action="store_true",
                    help="SCENE is a .blend: open it (the add-on registered) and render it as saved")
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]  # (blender -P ... -- args)
    args = ap.parse_args(argv)
    if args.open_blend:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        load_addon()
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.scene))
        scene = bpy.context.scene
    else:
        scene = build(args.scene, args.preset, args.body, args.samples, args.seed)
        if args.save_blend:
            bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save_blend))
    if args.threads > 0:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = args.threads
    print(f"fallback_render: Blender {bpy.app.version_string}, Cycles OSL {bpy.app.build_options.cycles_osl}")
    tmp = args.out + ".mirrored.exr"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = tmp
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(tmp)
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    px = px.reshape(h, w, 4)[:, ::-1].copy()  # mirror back to the standalone's handedness
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = args.out
    img.file_format = "OPEN_EXR"
    img.save()
    os.remove(tmp)
    print(f"fallback_render: wrote {args.out} ({scene.cycles.samples} spp)")


if __name__ == "__main__":
    try:
        main()
    except SystemExit as e:
        if e.code not in (None, 0):
            print(f"fallback_render: {e.code}", file=sys.stderr)
            sys.stdout.flush()
            os._exit(1)
    sys.stdout.flush()
    os._exit(0)  # the bpy 4.5 wheel can hang at exit after a render (see tests/addon/install_smoke.py)
