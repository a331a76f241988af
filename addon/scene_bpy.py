# SPDX-License-Identifier: GPL-3.0-or-later
"""The Blender builder of a scene description (scene_description.py, written by `neuralyarn cycles-scene --out
X.json`): the same camera, pixel filter, integrator, lights, curves and materials as the Cycles XML of the
scene, so that the fallbacks and the baselines render in Blender exactly the scene that the patched Cycles
renders (docs/decisions.md D37).

The standalone camera is left-handed (x right, y up, looking along +z) and Blender's right-handed; the camera
here looks along +z with +y up, so Blender's image is the standalone's mirrored in x: render_mirrored()
flips it back."""

from __future__ import annotations

import math
import os

import mathutils
import numpy as np

import bpy

from . import curves_bpy, model_io, nodes, scene_description

#: The description's integrator fields and the Blender property each sets.
INTEGRATOR = {
    "max_bounce": "max_bounces", "max_diffuse_bounce": "diffuse_bounces", "max_glossy_bounce": "glossy_bounces",
    "max_transmission_bounce": "transmission_bounces", "transparent_max_bounce": "transparent_max_bounces",
    "min_bounce": "min_light_bounces", "sample_clamp_direct": "sample_clamp_direct",
    "sample_clamp_indirect": "sample_clamp_indirect", "use_adaptive_sampling": "use_adaptive_sampling",
    "filter_glossy": "blur_glossy", "light_sampling_threshold": "light_sampling_threshold", "seed": "seed",
}
PIXEL_FILTERS = {"box": "BOX", "gaussian": "GAUSSIAN", "blackman_harris": "BLACKMAN_HARRIS"}
#: What stock Blender cannot render, and why.
UNSUPPORTED = {"khungurn_fiber": "explicit fibers need the Khungurn fiber closure of the patched standalone Cycles"}


def _material(name: str, m: dict, fallback: str):
    """The Blender material of a description's material; `fallback` ("OSL" or "NODES") is the neural yarn
    node's body."""
    kind = m["type"]
    if kind in UNSUPPORTED:
        raise scene_description.SceneDescriptionError(f"material '{kind}': {UNSUPPORTED[kind]}")
    if kind == "neural_yarn":
        model = (nodes.pack_model_text(model_io.parse_model(m["model_json"], "embedded model"), f"NY model {name}")
                 if "model_json" in m else nodes.pack_model_file(m["model"]))
        mat, node = nodes.make_material(name, model_text=model)
        node.fallback = fallback
        if node.error:
            raise scene_description.SceneDescriptionError(f"material '{name}': {node.error}")
        return mat
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    colour = (*m["colour"], 1.0)
    if kind == "diffuse":
        bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = colour
    elif kind == "sheen":
        # As the XML: Blender's node defaults (specular IOR level 0.5), sheen weight 1, white sheen tint.
        bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.inputs["Base Color"].default_value = colour
        bsdf.inputs["Sheen Weight"].default_value = 1.0
        bsdf.inputs["Sheen Tint"].default_value = (1.0, 1.0, 1.0, 1.0)
    else:
        bsdf = tree.nodes.new("ShaderNodeBsdfHairPrincipled")
        huang = kind == "principled_hair_huang"
        if hasattr(bsdf, "model"):  # Blender 4.0+ (3.x has Chiang only)
            bsdf.model = "HUANG" if huang else "CHIANG"
        elif huang:
            raise scene_description.SceneDescriptionError(f"Blender {bpy.app.version_string} has no Huang hair model")
        bsdf.parametrization = "COLOR"
        bsdf.inputs["Color"].default_value = colour
        if huang:
            bsdf.inputs["Aspect Ratio"].default_value = 1.0  # a ply's cross-section is round
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def cloth_surface_material(name: str, m: dict):
    """The surface level's material (docs/decisions.md D44) as the XML's: each closure weighted by an RGB curve of
    x = front |N.I| + back_start Backfacing, summed. The curves pass through the description's samples (vector
    handles: straight between them) and are not clipped (weights may exceed 1)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    new, link = tree.nodes.new, tree.links.new
    geo = new("ShaderNodeNewGeometry")
    dot = new("ShaderNodeVectorMath")
    dot.operation = "DOT_PRODUCT"
    link(geo.outputs["Normal"], dot.inputs[0])
    link(geo.outputs["Incoming"], dot.inputs[1])
    cos_v = new("ShaderNodeMath")
    cos_v.operation = "ABSOLUTE"
    link(dot.outputs["Value"], cos_v.inputs[0])
    back = new("ShaderNodeMath")
    back.operation = "MULTIPLY"
    link(geo.outputs["Backfacing"], back.inputs[0])
    back.inputs[1].default_value = m["back_start"]
    x = new("ShaderNodeMath")
    x.operation = "MULTIPLY_ADD"
    link(cos_v.outputs[0], x.inputs[0])
    x.inputs[1].default_value = m["front"]
    link(back.outputs[0], x.inputs[2])
    xxx = new("ShaderNodeCombineColor")
    for k in range(3):
        link(x.outputs[0], xxx.inputs[k])
    total = None
    for c in m["closures"]:
        curves = new("ShaderNodeRGBCurve")
        curves.inputs["Fac"].default_value = 1.0
        mapping = curves.mapping
        mapping.use_clip = False
        n = len(c["weight"])
        for ch in range(3):  # curves[0..2]: R, G, B (curves[3], the combined one, stays the identity)
            points = mapping.curves[ch].points
            points[0].location = (0.0, c["weight"][0][ch])
            points[1].location = (1.0, c["weight"][-1][ch])
            for i in range(1, n - 1):
                points.new(i / (n - 1), c["weight"][i][ch])
            for p in points:
                p.handle_type = "VECTOR"
        mapping.update()
        link(xxx.outputs[0], curves.inputs["Color"])
        kind = c["closure"]
        if kind == "ggx":
            bsdf = new("ShaderNodeBsdfGlossy")
            bsdf.distribution = "GGX"
            bsdf.inputs["Roughness"].default_value = math.sqrt(c["alpha"])
        else:
            bsdf = new({"transparent": "ShaderNodeBsdfTransparent", "diffuse": "ShaderNodeBsdfDiffuse",
                        "translucent": "ShaderNodeBsdfTranslucent"}[kind])
        link(curves.outputs["Color"], bsdf.inputs["Color"])
        if total is None:
            total = bsdf.outputs[0]
        else:
            add = new("ShaderNodeAddShader")
            link(total, add.inputs[0])
            link(bsdf.outputs[0], add.inputs[1])
            total = add.outputs[0]
    out = new("ShaderNodeOutputMaterial")
    link(total, out.inputs["Surface"])
    return mat


def build(desc: dict, *, fallback: str = "NODES", samples: int = 64):
    """Builds the description into the current (empty) file's scene and returns the scene. Raises
    SceneDescriptionError for what stock Blender cannot render."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.shading_system = fallback == "OSL"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    scene.cycles_curves.shape = "THICK"
    scene.cycles.pixel_filter_type = PIXEL_FILTERS[desc["film"]["filter_type"]]
    scene.cycles.filter_width = desc["film"]["filter_width"]
    for key, prop in INTEGRATOR.items():
        setattr(scene.cycles, prop, desc["integrator"][key])

    c = desc["camera"]
    scene.render.resolution_x, scene.render.resolution_y = c["width"], c["height"]
    scene.render.resolution_percentage = 100
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    # The field of view spans the shorter side (the standalone's auto viewplane).
    cam.data.sensor_fit = "VERTICAL" if c["width"] >= c["height"] else "HORIZONTAL"
    cam.data.angle = c["fov"]
    cam.data.clip_start, cam.data.clip_end = 0.01, 1e4
    cam.location = c["position"]
    cam.rotation_euler = (0.0, math.pi, 0.0)  # looks along +z, +y up, right = -x: the image is mirrored in x
    scene.collection.objects.link(cam)
    scene.camera = cam

    world = bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*desc["background"]["colour"], 1.0)
    bg.inputs["Strength"].default_value = desc["background"]["strength"]

    for k, light in enumerate(desc["lights"]):
        point = light["type"] == "point"
        data = bpy.data.lights.new(f"light{k}", "POINT" if point else "SUN")
        # Blender's light sync passes the energy (W, or W/m^2 for a sun) to Cycles as its strength.
        data.energy = light["strength"]
        obj = bpy.data.objects.new(f"light{k}", data)
        if point:
            data.shadow_soft_size = light["radius"]
            if hasattr(data, "use_soft_falloff"):
                data.use_soft_falloff = False  # Blender 4.0+'s default; the standalone's light has none
            obj.location = light["position"]
        else:
            # A sun shines along -Z of its object: +Z toward the light. The angle is the full angular diameter.
            data.angle = light["angle"]
            obj.rotation_mode = "QUATERNION"
            obj.rotation_quaternion = mathutils.Vector(light["direction"]).to_track_quat("Z", "Y")
        if hasattr(data, "use_mis"):
            data.use_mis = light["use_mis"]
        else:
            data.cycles.use_multiple_importance_sampling = light["use_mis"]
        obj.visible_camera = light["visible_to_camera"]
        scene.collection.objects.link(obj)

    for o in desc["objects"]:
        mat = _material(o["name"], o["material"], fallback)
        cv = o["curves"]
        keys = cv["keys"]
        radii = np.repeat(np.asarray(cv["radius"], dtype=np.float32), keys)
        data = curves_bpy._new_curves_data(o["name"], keys, np.asarray(cv["points"], dtype=np.float32).reshape(-1, 3),
                                           radii)
        data.materials.append(mat)
        scene.collection.objects.link(bpy.data.objects.new(o["name"], data))
    for o in desc.get("meshes", []):
        v = np.asarray(o["mesh"]["vertices"], dtype=np.float64).reshape(-1, 3)
        t = np.asarray(o["mesh"]["triangles"], dtype=np.int64).reshape(-1, 3)
        data = bpy.data.meshes.new(o["name"])
        data.from_pydata(v.tolist(), [], t.tolist())  # flat shaded, as the XML's triangles
        data.update()
        data.materials.append(cloth_surface_material(o["name"], o["material"]))
        scene.collection.objects.link(bpy.data.objects.new(o["name"], data))
    return scene


def render_mirrored(scene, out: str) -> None:
    """Renders the scene to the OpenEXR file `out` (32-bit float RGBA) in the standalone's handedness."""
    tmp = out + ".mirrored.exr"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = tmp
    bpy.ops.render.render(write_still=True, scene=scene.name)
    img = bpy.data.images.load(tmp)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        px = px.reshape(h, w, 4)[:, ::-1].copy()  # mirror back to the standalone's handedness
        img.pixels.foreach_set(px.ravel())
        img.filepath_raw = out
        img.file_format = "OPEN_EXR"
        img.save()
    finally:
        bpy.data.images.remove(img)
        os.remove(tmp)
