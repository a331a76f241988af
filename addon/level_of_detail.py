# SPDX-License-Identifier: GPL-3.0-or-later
"""The level of detail of yarn objects from the scene camera (bpy side of geometry/lod.py, D27): each Curves
object of yarns carries its level (Auto or a fixed one) and its plies per yarn; applying the level builds the
geometry of that level only (ply curves in a new object, or the yarn curves themselves) and gives it the
preset's material of that level. A scene-wide override stands above the objects' own, as Simplify does."""

from __future__ import annotations

import bpy
import numpy as np

from . import fallback_nodes, nodes
from .geometry import lod, ply_center_distance
from .geometry.lod import YARN_MODEL_PLIES, YARN_MODEL_PLY_TWIST

LEVEL_ITEMS = [
    ("AUTO", "Auto", "From the scene camera: yarns where a ply is narrower than 2 pixels, else plies"),
    ("FIBERS", "Fibers", "Explicit fibers (drawn by neuralyarn cycles-scene, not the add-on: plies here)"),
    ("PLIES", "Plies", "Each ply a curve with the preset's ply model"),
    ("YARNS", "Yarns", "Each yarn one curve with the preset's yarn-level model"),
    ("SURFACE", "Surface", "A cloth surface (not built by the add-on yet: yarns here)"),
]
OVERRIDE_ITEMS = [("OBJECT", "Per Object", "Each yarn object's own level of detail")] + LEVEL_ITEMS


def view_of(scene) -> lod.View | None:
    """The scene camera as geometry/lod.py sees it; None without a (perspective or orthographic) camera."""
    cam = scene.camera
    if cam is None or cam.type != "CAMERA" or cam.data.type not in ("PERSP", "ORTHO"):
        return None
    m = cam.matrix_world
    forward = -(m.to_3x3() @ type(m.translation)((0.0, 0.0, 1.0)))
    pct = scene.render.resolution_percentage / 100.0
    return lod.View(position=tuple(m.translation), forward=tuple(forward), kind=cam.data.type, fov=cam.data.angle,
                    ortho_scale=cam.data.ortho_scale, width=int(scene.render.resolution_x * pct),
                    height=int(scene.render.resolution_y * pct))


def curve_points(obj) -> tuple[np.ndarray, np.ndarray]:
    """World positions (n, 3) and radii (n,) of a Curves object's points."""
    pts = obj.data.points
    pos = np.empty(len(pts) * 3)
    pts.foreach_get("position", pos)
    rad = np.empty(len(pts))
    pts.foreach_get("radius", rad)
    m = np.array(obj.matrix_world)
    world = pos.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
    scale = float(np.cbrt(abs(np.linalg.det(m[:3, :3])))) or 1.0
    return world, rad * scale


def choose_for_yarns(obj, scene, plies: int, requested: str = "auto") -> lod.LevelChoice:
    """The level for a Curves object of yarns that would be twisted into `plies` plies (the add-on's ply twist):
    plies or yarns (a yarn-level model exists only for the shipped plying; fibers are drawn by
    `neuralyarn cycles-scene`, not the add-on: both give plies with a warning)."""
    points, radii = curve_points(obj)
    ply_radius = radii / (1.0 + ply_center_distance(plies, 1.0, YARN_MODEL_PLY_TWIST)) if plies > 1 else radii
    c = lod.choose_level(points, ply_radius, view_of(scene), requested=requested)
    notes = [c.warning] if c.warning else []
    level = c.level
    if level == "yarns" and plies != YARN_MODEL_PLIES:
        notes.append(f"the yarn-level models are of {YARN_MODEL_PLIES}-ply yarns, these have {plies}: drawing plies")
        level = "plies"
    if level == "fibers":
        notes.append("the add-on draws no explicit fibers (neuralyarn cycles-scene does): drawing plies")
        level = "plies"
    return lod.LevelChoice(level, c.ply_pixels, "; ".join(notes) or None)


class NeuralYarnObjectSettings(bpy.types.PropertyGroup):
    """A yarn object's level of detail (Object.neural_yarn)."""

    level: bpy.props.EnumProperty(name="Level of Detail", items=LEVEL_ITEMS, default="AUTO",
                                  description="How this object's yarns are drawn (Apply Level of Detail builds it)")
    plies: bpy.props.IntProperty(name="Plies", default=YARN_MODEL_PLIES, min=1, max=16,
                                 description="Plies per yarn at the ply level (1: the curves are plies already)")
    plies_object: bpy.props.PointerProperty(name="Plies Object", type=bpy.types.Object,
                                            description="The ply curves built from this object's yarns")
    applied: bpy.props.StringProperty(name="Applied", description="The level last applied (plies or yarns)")
    chosen: bpy.props.StringProperty(name="Chosen", description="The level last applied, and why")


def requested_level(obj, scene) -> str:
    """The level asked for: the scene's override, else the object's own ("auto", "plies", ...)."""
    override = getattr(scene, "neural_yarn_lod", "OBJECT")
    return (obj.neural_yarn.level if override == "OBJECT" else override).lower()


def yarn_object_of(obj, scene):
    """The yarn object whose plies `obj` is, else `obj` itself: a plies object is set and applied through its yarns."""
    return next((o for o in scene.objects if o.type == "CURVES" and o.neural_yarn.plies_object == obj), obj)


def rendered_object(obj):
    """What renders a yarn object after apply_level: its plies where they are shown in its place, else itself."""
    p = obj.neural_yarn.plies_object
    return p if obj.hide_render and p is not None and not p.hide_render else obj


def _plain_preset(mat) -> str | None:
    """The preset of a material that is nothing but one preset's Neural Yarn node (white, unlinked tint) into the
    material output, as the add-on makes it: only such a material can be exchanged for the same preset at another
    level without losing an artist's edits."""
    if mat is None or mat.node_tree is None:
        return None
    ours = [n for n in mat.node_tree.nodes if n.bl_idname == nodes.NODE_IDNAME]
    others = [n for n in mat.node_tree.nodes if n.bl_idname not in (nodes.NODE_IDNAME, "ShaderNodeOutputMaterial")]
    if len(ours) != 1 or others or ours[0].preset == "CUSTOM":
        return None
    tint = ours[0].inputs[fallback_nodes.GROUP_INPUT_TINT]
    if tint.is_linked or tuple(tint.default_value)[:3] != (1.0, 1.0, 1.0):
        return None
    return ours[0].preset


def _show(obj, shown: bool) -> None:
    obj.hide_render = not shown
    try:
        obj.hide_set(not shown)
    except RuntimeError:  # not in the view layer
        pass


def _set_material(obj, mat) -> None:
    if obj.active_material != mat:
        obj.data.materials.clear()
        obj.data.materials.append(mat)


def decide_level(obj, scene, requested: str | None = None) -> lod.LevelChoice:
    """The level apply_level would build for a yarn object now (`requested`, else the scene's override or the
    object's own), with its notes; changes nothing."""
    choice = choose_for_yarns(obj, scene, obj.neural_yarn.plies, requested or requested_level(obj, scene))
    notes = [choice.warning] if choice.warning else []
    level, mat = choice.level, obj.active_material
    ours = mat is not None and mat.node_tree is not None and any(
        n.bl_idname == nodes.NODE_IDNAME for n in mat.node_tree.nodes)
    if level == "yarns" and ours and _plain_preset(mat) is None:
        notes.append(f"material '{mat.name}' is not a plain preset material, whose yarn-level model the add-on "
                     "knows: drawing plies")
        level = "plies"
    return lod.LevelChoice(level, choice.ply_pixels, "; ".join(notes) or None)


def apply_level(context, obj, requested: str | None = None) -> lod.LevelChoice:
    """Decides the level of a yarn object (decide_level) and builds it: at the ply level the object's plies object
    (made once, with the preset's ply material; the yarns hidden), at the yarn level the yarns themselves with the
    preset's yarn-level material (the plies hidden, not deleted). Only a material that is nothing but a preset's
    node is exchanged between levels. Records the level in obj.neural_yarn (applied, chosen: with why) and
    returns the decision."""
    from . import operators  # noqa: PLC0415 (operators imports this module)

    scene = context.scene
    s = obj.neural_yarn
    choice = decide_level(obj, scene, requested)
    level, mat = choice.level, obj.active_material
    preset = _plain_preset(mat)
    plies_obj = s.plies_object if s.plies_object is not None and s.plies_object.name in scene.objects else None
    if level == "plies" and s.plies > 1:
        if plies_obj is not None and len(plies_obj.data.curves) != s.plies * len(obj.data.curves):
            _show(plies_obj, False)  # made for another number of plies: kept, hidden, and made anew
            plies_obj = None
        if plies_obj is None:
            plies_obj = operators.make_plies_object(context, obj, s.plies, YARN_MODEL_PLY_TWIST, 24,
                                                    None if preset else mat)
            s.plies_object = plies_obj
        if preset:
            _set_material(plies_obj, operators.preset_material(preset, "plies"))
        _show(plies_obj, True)
        _show(obj, False)
    else:
        if plies_obj is not None:
            _show(plies_obj, False)
        if preset:
            _set_material(obj, operators.preset_material(preset, level))
        _show(obj, True)
    px = f" (ply {choice.ply_pixels:.3g} px wide)" if choice.ply_pixels is not None else ""
    s.applied = level
    s.chosen = level + px + (f"; warning: {choice.warning}" if choice.warning else "")
    return choice


def stale_levels(scene) -> list[str]:
    """"<object>: <applied> applied, the camera now asks for <level>" for each yarn object whose applied level is
    no longer what its setting gives for the scene's camera and render size."""
    out = []
    for obj in scene.objects:
        if obj.type == "CURVES" and obj.neural_yarn.applied:
            now = decide_level(obj, scene).level
            if now != obj.neural_yarn.applied:
                out.append(f"{obj.name}: {obj.neural_yarn.applied} applied, the camera now asks for {now}")
    return out


@bpy.app.handlers.persistent
def _render_pre(scene, *_args):
    stale = stale_levels(scene)
    if stale:  # a render_pre handler must not rebuild geometry: it says so instead
        print("Neural Yarn: warning: level of detail out of date (Apply Level of Detail): " + "; ".join(stale))


def register():
    bpy.utils.register_class(NeuralYarnObjectSettings)
    bpy.types.Object.neural_yarn = bpy.props.PointerProperty(type=NeuralYarnObjectSettings)
    bpy.types.Scene.neural_yarn_lod = bpy.props.EnumProperty(
        name="Level of Detail", items=OVERRIDE_ITEMS, default="OBJECT",
        description="Scene-wide level of detail for every yarn object (Per Object: each object's own)")
    if _render_pre not in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.append(_render_pre)


def unregister():
    if _render_pre in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.remove(_render_pre)
    del bpy.types.Scene.neural_yarn_lod
    del bpy.types.Object.neural_yarn
    bpy.utils.unregister_class(NeuralYarnObjectSettings)
