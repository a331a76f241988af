# SPDX-License-Identifier: GPL-3.0-or-later
"""The level of detail of yarn objects from the scene camera (bpy side of geometry/lod.py, D27): each Curves
object of yarns carries its level (Auto or a fixed one) and its plies per yarn; applying the level builds the
geometry of that level only (ply curves in a new object, or the yarn curves themselves) and gives it the
preset's material of that level. A scene-wide override stands above the objects' own, as Simplify does."""

from __future__ import annotations

import functools
import json
import math
import zlib

import bpy
import numpy as np

from . import curves_bpy, fallback_nodes, nodes, resources, scene_bpy, scene_description
from .geometry import GeometryError, lod, ply_center_distance
from .geometry.lod import YARN_MODEL_PLIES, YARN_MODEL_PLY_TWIST

LEVEL_ITEMS = [
    ("AUTO", "Auto", f"From the scene camera: yarns where a ply is narrower than {lod.YARNS_BELOW_PLY_PIXELS:g} px, "
                     "else plies"),
    ("FIBERS", "Fibers", "Explicit fibers (drawn by neuralyarn cycles-scene, not the add-on: plies here)"),
    ("PLIES", "Plies", "Each ply a curve with the preset's ply model"),
    ("YARNS", "Yarns", "Each yarn one curve with the preset's yarn-level model"),
    ("SURFACE", "Surface", "A cloth surface with the preset's fitted stock closures (a Knitted Swatch of the default "
                           "shape only; never chosen by Auto: less accurate than the yarns)"),
]
OVERRIDE_ITEMS = [("OBJECT", "Per Object", "Each yarn object's own level of detail")] + LEVEL_ITEMS
#: The object key under which a generated swatch keeps its pattern, size and face (operators.py writes it).
SWATCH_KEY = "neural_yarn_swatch"
#: The format of a shipped surface-level material (`neuralyarn surface --material-out`).
CLOTH_SURFACE_FORMAT = "neuralyarn-cloth-surface 1"
#: The object key under which what apply_level makes of a yarn object's curves (its plies, the parts of its split,
#: D67) keeps what it was made from: the yarns' indices, the plies per yarn and a checksum of the curves.
PART_KEY = "neural_yarn_part"
#: The level a split object is applied at: its near yarns as plies, the far ones as yarns.
SPLIT_LEVEL = "plies+yarns"
#: A yarn object's settings that point at what apply_level (or Twist Plies) made of it, and the level each draws.
POINTERS = {"plies_object": "plies", "near_plies_object": "plies", "far_yarns_object": "yarns",
            "surface_object": "surface"}


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


def ply_radii(obj, plies: int) -> tuple[np.ndarray, np.ndarray]:
    """A yarn Curves object's points (world space) and the radius of the plies it would be twisted into at each (its
    own radii where `plies` is 1: its curves are plies)."""
    points, radii = curve_points(obj)
    return points, radii / (1.0 + ply_center_distance(plies, 1.0, YARN_MODEL_PLY_TWIST)) if plies > 1 else radii


def choose_for_yarns(obj, scene, plies: int, requested: str = "auto") -> lod.LevelChoice:
    """The level for a Curves object of yarns that would be twisted into `plies` plies (the add-on's ply twist):
    plies or yarns (a yarn-level model exists only for the shipped plying; fibers are drawn by
    `neuralyarn cycles-scene`, not the add-on: both give plies with a warning), and under Auto the yarns it draws
    as yarns where it splits the object (`far`)."""
    points, ply_radius = ply_radii(obj, plies)
    counts = np.diff(curves_bpy.curve_offsets(obj)) if obj.neural_yarn.split else None
    c = lod.choose_level(points, ply_radius, view_of(scene), requested=requested, curve_counts=counts)
    notes = [c.warning] if c.warning else []
    level, far = c.level, c.far
    if (level == "yarns" or far) and plies != YARN_MODEL_PLIES:
        what = "drawing plies" if level == "yarns" else f"the {len(far)} far yarns stay plies"
        notes.append(f"the yarn-level models are of {YARN_MODEL_PLIES}-ply yarns, these have {plies}: {what}")
        level = "plies" if level == "yarns" else level
        far = ()
    if level == "fibers":
        notes.append("the add-on draws no explicit fibers (neuralyarn cycles-scene does): drawing plies")
        level = "plies"
    return lod.LevelChoice(level, c.ply_pixels, "; ".join(notes) or None, far)


class NeuralYarnObjectSettings(bpy.types.PropertyGroup):
    """A yarn object's level of detail (Object.neural_yarn)."""

    level: bpy.props.EnumProperty(name="Level of Detail", items=LEVEL_ITEMS, default="AUTO",
                                  description="How this object's yarns are drawn (Apply Level of Detail builds it)")
    plies: bpy.props.IntProperty(name="Plies", default=YARN_MODEL_PLIES, min=1, max=16,
                                 description="Plies per yarn at the ply level (1: the curves are plies already)")
    split: bpy.props.BoolProperty(
        name="Split by Distance", default=True,
        description="Auto: where this object's yarns lie at different distances, draw its far yarns as yarns and "
                    "its near ones as plies (faster; where the two levels' colours differ, the boundary can show)")
    plies_object: bpy.props.PointerProperty(name="Plies Object", type=bpy.types.Object,
                                            description="The ply curves built from this object's yarns")
    near_plies_object: bpy.props.PointerProperty(
        name="Near Plies Object", type=bpy.types.Object,
        description="Where Auto split this object: the ply curves of its yarns near the camera")
    far_yarns_object: bpy.props.PointerProperty(
        name="Far Yarns Object", type=bpy.types.Object,
        description="Where Auto split this object: its yarns far from the camera, drawn with the yarn-level model")
    part_of: bpy.props.PointerProperty(
        name="Part Of", type=bpy.types.Object,
        description="On a part of a split: the yarn object it draws part of (a copy of that object does not own it)")
    surface_object: bpy.props.PointerProperty(name="Surface Object", type=bpy.types.Object,
                                              description="The cloth surface built for this swatch")
    applied: bpy.props.StringProperty(name="Applied",
                                      description="The level last applied (plies, yarns, plies+yarns or surface)")
    chosen: bpy.props.StringProperty(name="Chosen", description="The level last applied, and why")


def requested_level(obj, scene) -> str:
    """The level asked for: the scene's override, else the object's own ("auto", "plies", ...)."""
    override = getattr(scene, "neural_yarn_lod", "OBJECT")
    return (obj.neural_yarn.level if override == "OBJECT" else override).lower()


def _made_objects(obj) -> list:
    """The objects apply_level made for a yarn object: its plies, its split's two parts and its surface."""
    return [o for o in (getattr(obj.neural_yarn, name) for name in POINTERS) if o is not None]


def yarn_object_of(obj, scene):
    """The yarn object whose plies, part or surface `obj` is, else `obj` itself: they are set and applied through
    it."""
    owner = obj.neural_yarn.part_of if obj.type == "CURVES" else None
    if owner is not None and owner.name in scene.objects:
        return owner
    return next((o for o in scene.objects if o.type == "CURVES" and obj in _made_objects(o)), obj)


def rendered_objects(obj) -> list:
    """What renders a yarn object after apply_level, with the level each draws: (its plies, "plies"), its split's
    near plies and far yarns, its surface, or (itself, its applied level)."""
    if not obj.hide_render:
        return [(obj, obj.neural_yarn.applied if obj.neural_yarn.applied in lod.LEVELS else "plies")]
    levels = ((getattr(obj.neural_yarn, name), level) for name, level in POINTERS.items())
    return [(o, level) for o, level in levels if o is not None and not o.hide_render]


def _part_tag(part) -> dict:
    try:
        tag = json.loads(part.get(PART_KEY)) if part is not None and isinstance(part.get(PART_KEY), str) else None
    except ValueError:
        return {}
    return tag if isinstance(tag, dict) else {}


def part_yarns(part) -> tuple | None:
    """The indices of the yarns a part of a split object draws, None for anything else."""
    yarns = _part_tag(part).get("yarns")
    return tuple(yarns) if isinstance(yarns, list) else None


def _geometry_key(obj) -> str:
    """A checksum of a Curves object's curves in its own space (points, radii, where each curve starts): a part made
    from them is still theirs while it holds; moving the object moves its parts (they are its children)."""
    data = obj.data
    pos = np.empty(len(data.points) * 3, dtype=np.float32)
    data.position_data.foreach_get("vector", pos)
    key = zlib.crc32(pos.tobytes())
    attr = data.attributes.get("radius")
    if attr is not None:
        rad = np.empty(len(data.points), dtype=np.float32)
        attr.data.foreach_get("value", rad)
        key = zlib.crc32(rad.tobytes(), key)
    return f"{zlib.crc32(curves_bpy.curve_offsets(obj).tobytes(), key):08x}"


def _owns(obj, part) -> bool:
    """Whether `part` was made of `obj`'s curves (not of those of an object `obj` was copied from)."""
    return part is not None and part.neural_yarn.part_of == obj and part_yarns(part) is not None


def _made_for(obj, other, scene):
    """`other` (a pointer of obj's settings) where apply_level may reuse, show or hide it for obj: in the scene and
    made for obj, not for an object obj was copied from (a copy copies the pointers). A surface is obj's child;
    curves made before they named their object (part_of) are obj's where they carry its name, as the add-on names
    them ("<object> plies", "<object> near plies", ...)."""
    if other is None or other.name not in scene.objects:
        return None
    if other.type == "MESH":
        return other if other.parent == obj else None
    owner = other.neural_yarn.part_of
    if owner is not None:
        return other if owner == obj else None
    return other if other.name.startswith(obj.name + " ") else None


def _is_part(obj, part, yarns: tuple, plies: int, geometry: str) -> bool:
    """Whether `part` is what `obj`'s yarns `yarns`, twisted into `plies` plies (1: as they are), make now (`geometry`:
    _geometry_key(obj))."""
    return part is not None and part.neural_yarn.part_of == obj and \
        _part_tag(part) == {"yarns": list(yarns), "plies": plies, "geometry": geometry}


def adopt(obj, made, yarns: tuple, plies: int, geometry: str | None = None, *, parent: bool = True):
    """Makes `made` (new curves in world space from obj's yarns `yarns`, twisted into `plies`) obj's: tagged with what
    it was made from (`geometry`: _geometry_key(obj), if known) and its object (part_of); with `parent`, a child of obj
    (moving obj moves it) in obj's collections (those a library links in cannot take it: it stays where it was
    made)."""
    made[PART_KEY] = json.dumps({"yarns": list(yarns), "plies": plies,
                                 "geometry": _geometry_key(obj) if geometry is None else geometry})
    made.neural_yarn.part_of = obj
    if parent:
        made.parent = obj
        made.matrix_parent_inverse = obj.matrix_world.inverted()  # it was made where obj is now
        targets = [c for c in obj.users_collection if getattr(c, "library", None) is None]
        if targets:
            for collection in targets:
                if made.name not in collection.objects:
                    collection.objects.link(made)
            for collection in list(made.users_collection):
                if collection not in targets:
                    collection.objects.unlink(made)
    return made


def _remove(made) -> None:
    if made.type == "CURVES":
        curves_bpy.remove_curves_object(made)
    else:
        data = made.data
        bpy.data.objects.remove(made)
        if data is not None and data.users == 0:
            bpy.data.meshes.remove(data)


@functools.lru_cache(maxsize=None)
def surface_material_of(preset: str) -> dict:
    """A preset's shipped surface-level material, checked: {"pattern": the swatch shape it was fitted on, "material":
    the description's cloth_surface material}. Raises ValueError naming the file and the problem, FileNotFoundError
    when it is missing."""
    path = resources.surface_material_path(preset)
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not JSON ({e})") from None
    if not isinstance(data, dict) or data.get("format") != CLOTH_SURFACE_FORMAT:
        raise ValueError(f"{path}: not a surface material (format '{CLOTH_SURFACE_FORMAT}')")
    pattern = data.get("pattern")
    if not isinstance(pattern, dict) or pattern.get("kind") != "plain_knit":
        raise ValueError(f"{path}: 'pattern' must name the plain knit it was fitted on")
    material = scene_description.parse_cloth_surface(data.get("material"), f"{path}: material")
    return {"pattern": pattern, "material": material}


def _swatch(obj) -> dict | None:
    raw = obj.get(SWATCH_KEY)
    try:
        swatch = json.loads(raw) if isinstance(raw, str) else None
    except ValueError:
        return None
    return swatch if isinstance(swatch, dict) and isinstance(swatch.get("pattern"), dict) else None


def _surface_refusal(obj) -> str | None:
    """Why the surface level cannot draw this object (None: it can): it is fitted on the Knitted Swatch of the
    default shape, with 3-ply yarns, per preset; drawn on anything else it would render a fit of other cloth."""
    swatch = _swatch(obj)
    if swatch is None:
        return "the surface level is fitted on the add-on's Knitted Swatch only"
    if obj.neural_yarn.plies != YARN_MODEL_PLIES:
        return f"the surface level is fitted on {YARN_MODEL_PLIES}-ply yarns, these have {obj.neural_yarn.plies}"
    preset = _plain_preset(obj.active_material)
    if preset is None:
        return "the surface level is a preset's fit, and the material is not a plain preset material"
    try:
        shipped = surface_material_of(preset)
    except (OSError, ValueError) as e:
        return str(e)
    fitted = {k: v for k, v in shipped["pattern"].items() if k not in ("plies", "ply_twist")}
    if swatch["pattern"] != fitted:
        return f"the surface level is fitted on the Knitted Swatch's default shape (yarn radius {fitted['yarn_radius']:g})"
    return None


def _surface_material(preset: str):
    """The material "Neural Yarn <preset> surface" (reused while it is still the one this add-on made)."""
    name = f"Neural Yarn {preset} surface"
    for mat in bpy.data.materials:
        if (mat.name == name or mat.name.startswith(name + ".")) and mat.get("neural_yarn_surface") == preset:
            return mat
    mat = scene_bpy.cloth_surface_material(name, surface_material_of(preset)["material"])
    mat["neural_yarn_surface"] = preset
    return mat


def _make_surface_object(obj):
    """A quad over the swatch's stitches and rows in its mid-plane (z = 0 of its object: one period per stitch and
    per row, the area the fit holds for), facing the knit's face (its purl side flips it), parented to it; apply_level
    gives it its material."""
    swatch = _swatch(obj)
    p, k = swatch["pattern"], swatch["scale"]
    x1 = 2.0 * math.pi * swatch["stitches"] * k
    y0, y1 = -0.5 * p["w"] * k, ((swatch["rows"] - 1) * p["w"] + 0.5 * p["w"]) * k
    tris = [(0, 2, 1), (0, 3, 2)] if swatch["purl"] else [(0, 1, 2), (0, 2, 3)]
    mesh = bpy.data.meshes.new(f"{obj.name} surface")
    mesh.from_pydata([(0.0, y0, 0.0), (x1, y0, 0.0), (x1, y1, 0.0), (0.0, y1, 0.0)], [], tris)
    mesh.update()
    surface = bpy.data.objects.new(f"{obj.name} surface", mesh)
    surface.parent = obj  # follows the swatch; its own transform is the identity
    for collection in obj.users_collection:
        collection.objects.link(surface)
    return surface


def _plain_preset(mat) -> str | None:
    """The preset of a material that is nothing but one preset's Neural Yarn node (white, unlinked tint, the model's
    own twist) into the material output, as the add-on makes it: only such a material can be exchanged for the same
    preset at another level without losing an artist's edits."""
    if mat is None or mat.node_tree is None:
        return None
    ours = [n for n in mat.node_tree.nodes if n.bl_idname == nodes.NODE_IDNAME]
    others = [n for n in mat.node_tree.nodes if n.bl_idname not in (nodes.NODE_IDNAME, "ShaderNodeOutputMaterial")]
    if len(ours) != 1 or others or ours[0].preset == "CUSTOM" or ours[0].twist_override:
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
    level, far, mat = choice.level, choice.far, obj.active_material
    if level == "surface":
        why = _surface_refusal(obj)
        if why:
            notes.append(why + ": drawing yarns")
            level = "yarns"
    ours = mat is not None and mat.node_tree is not None and any(
        n.bl_idname == nodes.NODE_IDNAME for n in mat.node_tree.nodes)
    if (level == "yarns" or far) and ours and _plain_preset(mat) is None:
        what = "drawing plies" if level == "yarns" else f"the {len(far)} far yarns stay plies"
        notes.append(f"material '{mat.name}' is not a plain preset material, whose yarn-level model the add-on "
                     f"knows: {what}")
        level = "plies" if level == "yarns" else level
        far = ()
    return lod.LevelChoice(level, choice.ply_pixels, "; ".join(notes) or None, far)


def applied_name(choice: lod.LevelChoice) -> str:
    """What apply_level records as applied for a decision: its level, or SPLIT_LEVEL for a split."""
    return SPLIT_LEVEL if choice.far else choice.level


def _split_parts(context, obj, near_obj, far_obj, far: tuple, material, geometry: str, made: list) -> tuple:
    """The split's two part objects (D67): `near_obj` and `far_obj` where they are obj's parts for its yarns as they
    are now, else new ones with `material` (None: the level's preset material follows), children of obj in its
    collections; what it makes is appended to `made` as it is made (apply_level removes it if anything fails)."""
    from . import operators  # noqa: PLC0415 (operators imports this module)

    s = obj.neural_yarn
    far_set = set(far)
    near = tuple(k for k in range(len(obj.data.curves)) if k not in far_set)
    wanted = ((near_obj, near, s.plies, lambda: operators.make_plies_object(
                   context, obj, s.plies, YARN_MODEL_PLY_TWIST, operators.PLY_SAMPLES_PER_TURN, material, yarns=near)),
              (far_obj, far, 1, lambda: operators.make_yarns_part(context, obj, far, material)))
    parts = []
    for old, yarns, plies, make in wanted:
        if _is_part(obj, old, yarns, plies, geometry):
            parts.append(old)
            continue
        made.append(make())
        parts.append(adopt(obj, made[-1], yarns, plies, geometry))
    return tuple(parts)


def apply_level(context, obj, requested: str | None = None) -> lod.LevelChoice:
    """Decides the level of a yarn object (decide_level) and builds it: at the ply level the object's plies object
    (made once, with the preset's ply material; the yarns hidden), at the yarn level the yarns themselves with the
    preset's yarn-level material, at the surface level the swatch's surface quad with the preset's surface material
    (what another level does not show is hidden, never deleted); split by Auto (D67), two part objects of the
    yarns, its near ones as plies and its far ones as yarns, each with its level's material (_split_parts). Only a
    material that is nothing but a preset's node is exchanged between levels. Records the level in obj.neural_yarn
    (applied, chosen: with why) and returns the decision."""
    from . import operators  # noqa: PLC0415 (operators imports this module)

    scene = context.scene
    s = obj.neural_yarn
    choice = decide_level(obj, scene, requested)
    level, mat = choice.level, obj.active_material
    preset = _plain_preset(mat)
    twisted = bool(choice.far) or (level == "plies" and s.plies > 1)
    if twisted and not abs(np.linalg.det(np.array(obj.matrix_world)[:3, :3])) > 0.0:
        raise GeometryError(f"'{obj.name}' has a zero scale: no plies can be made of its yarns")

    def mine(o):
        return _made_for(obj, o, scene)

    before = {name: mine(getattr(s, name)) for name in POINTERS}
    # Everything that can fail first, nothing shown, hidden or removed before it has succeeded: the materials, then
    # the level's objects (removed again if one of them cannot be made).
    needed = ("plies", "yarns") if choice.far else ("plies",) if twisted else (level,)
    mats = {lv: _surface_material(preset) if lv == "surface" else operators.preset_material(preset, lv)
            for lv in needed} if preset else {}
    geometry = _geometry_key(obj) if twisted else None
    now, made = dict(before), []
    try:
        if choice.far:
            now["near_plies_object"], now["far_yarns_object"] = _split_parts(
                context, obj, before["near_plies_object"], before["far_yarns_object"], choice.far,
                None if preset else mat, geometry, made)
            shown = [(now["near_plies_object"], "plies"), (now["far_yarns_object"], "yarns")]
        elif level == "surface":
            if now["surface_object"] is None:
                made.append(_make_surface_object(obj))
                now["surface_object"] = made[-1]
            shown = [(now["surface_object"], "surface")]
        elif twisted:
            every = tuple(range(len(obj.data.curves)))
            if not _is_part(obj, now["plies_object"], every, s.plies, geometry):
                made.append(operators.make_plies_object(context, obj, s.plies, YARN_MODEL_PLY_TWIST,
                                                        operators.PLY_SAMPLES_PER_TURN, None if preset else mat))
                now["plies_object"] = adopt(obj, made[-1], every, s.plies, geometry)
            shown = [(now["plies_object"], "plies")]
        else:
            shown = [(obj, level)]
    except Exception:
        for o in made:
            _remove(o)
        raise
    # A copy of another yarn object keeps none of that object's pointers; a part of a split the camera no longer
    # asks for is removed: it is the yarns' geometry cut where one camera put the threshold, not an object of its
    # own, and keeping every past cut would fill the file. Plies and surfaces are hidden, never deleted.
    for name in POINTERS:
        setattr(s, name, now[name])
    removed = []  # (a removed object's wrapper raises on any access: they are told apart by identity)
    for name in ("near_plies_object", "far_yarns_object"):
        old = before[name]
        if old is not None and old != now[name] and _owns(obj, old):
            removed.append(old)
            curves_bpy.remove_curves_object(old)
    for o, lv in shown:
        if mats:
            _set_material(o, mats[lv])
    candidates = [obj] + [o for o in (*before.values(), *now.values())
                          if o is not None and not any(o is r for r in removed)]
    for o in dict.fromkeys(candidates):
        _show(o, any(o == shown_obj for shown_obj, _ in shown))
    px = f" (ply {choice.ply_pixels:.3g} px wide)" if choice.ply_pixels is not None else ""
    if choice.far:
        px = (f" (ply {choice.ply_pixels:.3g} px wide at the nearest; {len(choice.far)} of {len(obj.data.curves)} "
              f"yarns as yarns, their ply under {lod.YARNS_BELOW_PLY_PIXELS:g} px)")
    s.applied = applied_name(choice)
    s.chosen = s.applied + px + (f"; warning: {choice.warning}" if choice.warning else "")
    return choice


def stale_levels(scene) -> list[str]:
    """"<object>: <applied> applied, the camera now asks for <level>" for each yarn object whose applied level is
    no longer what its setting gives for the scene's camera and render size."""
    out = []
    for obj in scene.objects:
        s = obj.neural_yarn if obj.type == "CURVES" else None
        if s is not None and s.applied:
            choice = decide_level(obj, scene)
            now = applied_name(choice)
            if now != s.applied:
                out.append(f"{obj.name}: {s.applied} applied, the camera now asks for {now}")
            elif choice.far and not _is_part(obj, s.far_yarns_object, choice.far, 1, _geometry_key(obj)):
                out.append(f"{obj.name}: {s.applied} applied, the camera now asks for another split (or the yarns "
                           "changed)")
            elif now == "plies" and s.plies > 1 and not _is_part(obj, s.plies_object, tuple(range(len(
                    obj.data.curves))), s.plies, _geometry_key(obj)):
                out.append(f"{obj.name}: its plies were made of other curves (or another number of plies)")
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
