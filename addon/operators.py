# SPDX-License-Identifier: GPL-3.0-or-later
"""Operators: thin wrappers that read their properties, call the pure-Python geometry package, and make
Blender data only once everything has been computed and checked. Any bad input ends as an error report
naming the problem, CANCELLED, and an unchanged file (no half-made objects)."""

from __future__ import annotations

import json

import bpy
from bpy_extras.io_utils import ImportHelper

from . import curves_bpy, geometry, level_of_detail, model_io, nodes, resources, scene_setup

PRESET_OR_NONE = [("NONE", "None", "Do not assign a material")] + [
    (p, p.title(), f"Assign the '{p}' neural yarn material") for p in resources.PRESETS]
WEAVES = [("plain", "Plain", "1 up 1 down"), ("twill", "Twill", "u up d down, shifted by one per row"),
          ("satin", "Satin", "K-harness satin with move m"), ("basket", "Basket", "n x n plain")]
KEEP_OR_PRESET = [("KEEP", "Keep", "The yarn's own material")] + PRESET_OR_NONE[1:]
UP_AXES = [("auto", "From File", "The BCC header's up axis"), ("Y", "Y Up", "File is Y-up (converted to Z-up)"),
           ("Z", "Z Up", "File is Z-up")]

# Scene-unit defaults: Crane's knit units (a stitch is 2 pi wide, yarn radius 1/2) times 0.002 give a
# chunky knit with 1 mm yarn radius and 12.6 mm stitches.
KNIT_SCALE = 0.002
#: Curve points per turn of a ply's helix about its yarn (Twist Plies' default, and the level of detail's plies).
PLY_SAMPLES_PER_TURN = 24


def preset_material(preset: str, level: str = "plies"):
    """A material "Neural Yarn <preset>" ("... yarn" for the yarn level) whose Neural Yarn nodes all still hold
    that preset and level (reused), else a new one: the name alone says nothing once an artist has switched the
    node to another preset."""
    name = f"Neural Yarn {preset}" + (" yarn" if level == "yarns" else "")
    for mat in bpy.data.materials:
        if mat.name != name and not mat.name.startswith(name + "."):
            continue
        ours = [n for n in mat.node_tree.nodes if n.bl_idname == nodes.NODE_IDNAME] if mat.node_tree else []
        if ours and all(n.preset == preset and n.level.lower() == level for n in ours):
            return mat
    mat, _node = nodes.make_material(name, preset=preset, level=level)
    return mat


def _give_preset_material(obj, preset: str) -> None:
    """Gives a just-made object the preset's material; if that fails, the object goes too, so that a
    refused operation leaves nothing half-made in the file."""
    try:
        obj.data.materials.append(preset_material(preset))
    except BaseException:
        curves_bpy.remove_curves_object(obj)
        raise


class _Progress:
    """window_manager.progress_* around a long operation (a no-op without a window manager)."""

    def __init__(self, context, steps: int):
        self.wm = getattr(context, "window_manager", None)
        self.steps = steps

    def __enter__(self):
        if self.wm is not None:
            self.wm.progress_begin(0, self.steps)
        return self

    def update(self, k: int) -> None:
        if self.wm is not None:
            self.wm.progress_update(k)

    def fraction(self, f: float) -> None:
        self.update(round(f * self.steps))

    def __exit__(self, *exc):
        if self.wm is not None:
            self.wm.progress_end()
        return False


class _MakesYarn:
    """Mix-in: create the object from computed curves, with the optional preset; errors -> report."""

    preset: bpy.props.EnumProperty(name="Material", items=PRESET_OR_NONE, default="fleece",
                                   description="The neural yarn material the new yarns get")

    #: Generated swatches are placed at the 3D cursor, as Blender's Add menu does; imports keep the file's
    #: coordinates.
    at_cursor = False

    def compute(self, context) -> tuple[str, list]:
        raise NotImplementedError

    def swatch(self) -> dict | None:
        """A generated swatch's pattern, size and face in its object's space, if the surface level may draw it."""
        return None

    def execute(self, context):
        try:
            name, curves = self.compute(context)
            # The object first: a refusal there must not leave a material (and its texts, images and node
            # group) behind in the artist's file.
            cursor = getattr(getattr(context, "scene", None), "cursor", None)
            location = tuple(cursor.location) if self.at_cursor and cursor is not None else None
            obj = curves_bpy.create_curves_object(context, name, curves, location=location)
            swatch = self.swatch()
            if swatch is not None:  # what the surface level needs to know of it (level_of_detail.py)
                obj[level_of_detail.SWATCH_KEY] = json.dumps(swatch)
            if self.preset != "NONE":
                _give_preset_material(obj, self.preset)
        except (geometry.GeometryError, model_io.ModelFileError, OSError, ValueError, MemoryError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        n = sum(len(c.points) for c in curves)
        self.report({"INFO"}, f"{obj.name}: {len(curves)} yarn curves, {n} points")
        return {"FINISHED"}


class NEURALYARN_OT_import_bcc(_MakesYarn, bpy.types.Operator, ImportHelper):
    """Import yarn curves from a BCC file (Cem Yuksel's yarn-level cloth models)"""

    bl_idname = "neural_yarn.import_bcc"
    bl_label = "Import BCC Yarns"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".bcc"
    filter_glob: bpy.props.StringProperty(default="*.bcc;*.bccx", options={"HIDDEN"})
    scale: bpy.props.FloatProperty(name="Scale", default=0.01, min=1e-9, max=1e6, soft_max=10.0, precision=6,
                                   description="File units to scene units. BCC stores no unit; Yuksel's yarn-level "
                                               "models are in centimetres (his sweater is 52 units wide): 0.01 "
                                               "gives metres")
    yarn_radius: bpy.props.FloatProperty(
        name="Yarn Radius", default=0.0, min=0.0, description="In file units; 0: the BCCX radius, else where "
        "neighbouring yarn passes touch (estimated from the curves)")
    up_axis: bpy.props.EnumProperty(name="Up Axis", items=UP_AXES, default="auto",
                                    description="Which file axis points up (converted to Blender's Z-up)")
    samples_per_segment: bpy.props.IntProperty(name="Samples per Segment", default=8, min=1, max=64,
                                               description="Curve points per control-point segment of the spline")

    def compute(self, context):
        with _Progress(context, 100) as progress:
            curves = geometry.read_bcc(self.filepath, scale=self.scale, yarn_radius=self.yarn_radius or None,
                                       samples_per_segment=self.samples_per_segment, up_axis=self.up_axis,
                                       progress=progress.fraction)
        return bpy.path.display_name_from_filepath(self.filepath) or "yarns", curves


class NEURALYARN_OT_import_leaf(_MakesYarn, bpy.types.Operator, ImportHelper):
    """Import a periodic yarn pattern of Leaf et al. (text "Num Yarns" layout or BCC tile), tiled n x m"""

    bl_idname = "neural_yarn.import_leaf"
    bl_label = "Import Periodic Pattern"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filter_glob: bpy.props.StringProperty(default="*.txt;*.bcc;*.bccx", options={"HIDDEN"})
    tiles_x: bpy.props.IntProperty(name="Tiles X", default=4, min=1, max=1000,
                                   description="Repetitions of the pattern along its first axis")
    tiles_y: bpy.props.IntProperty(name="Tiles Y", default=4, min=1, max=1000,
                                   description="Repetitions of the pattern along its second axis")
    period_x: bpy.props.FloatProperty(name="Period X", default=0.0, min=0.0,
                                      description="Tile period in pattern units; 0: from the sidecar, else estimated")
    period_y: bpy.props.FloatProperty(name="Period Y", default=0.0, min=0.0,
                                      description="Tile period along the second axis in pattern units; 0: from the sidecar, else estimated")
    yarn_radius: bpy.props.FloatProperty(name="Yarn Radius", default=0.0, min=0.0,
                                         description="In pattern units; 0: sidecar, BCCX, else estimated")
    scale: bpy.props.FloatProperty(name="Scale", default=0.01, min=1e-9, max=1e6, soft_max=10.0, precision=6,
                                   description="Pattern units to scene units (0.01: centimetres to metres)")
    up_axis: bpy.props.EnumProperty(name="Up Axis", items=UP_AXES, default="auto",
                                    description="Which file axis points up (converted to Blender's Z-up)")

    def compute(self, context):
        period = None
        if self.period_x > 0.0 or self.period_y > 0.0:
            if not (self.period_x > 0.0 and self.period_y > 0.0):
                raise geometry.GeometryError("give both tile periods, or neither (0 = estimate)")
            period = (self.period_x, self.period_y)
        curves = geometry.read_leaf(self.filepath, nx=self.tiles_x, ny=self.tiles_y, period=period,
                                    yarn_radius=self.yarn_radius or None, scale=self.scale, up_axis=self.up_axis)
        return bpy.path.display_name_from_filepath(self.filepath) or "pattern", curves


class NEURALYARN_OT_add_knit(_MakesYarn, bpy.types.Operator):
    """Add a plain-knit swatch (Crane's closed-form stitch curve), one yarn per row"""

    bl_idname = "neural_yarn.add_knit"
    bl_label = "Knitted Swatch"
    bl_options = {"REGISTER", "UNDO"}
    at_cursor = True

    rows: bpy.props.IntProperty(name="Rows", default=8, min=1, max=2000, description="Courses of stitches (one yarn each)")
    stitches: bpy.props.IntProperty(name="Stitches", default=8, min=1, max=2000, description="Stitches per row (wales)")
    yarn_radius: bpy.props.FloatProperty(name="Yarn Radius", default=0.5, min=0.01, max=2.0,
                                         description="In knit units, where a stitch is 2 pi wide (Crane's loop curve)")
    scale: bpy.props.FloatProperty(name="Scale", default=KNIT_SCALE, min=1e-6, max=100.0, precision=4,
                                   description="Knit units to scene units (default: 1 mm yarn radius, 12.6 mm stitches)")
    purl: bpy.props.BoolProperty(name="Purl Side", default=False, description="Show the back (purl) face of the knit")
    samples_per_loop: bpy.props.IntProperty(name="Samples per Loop", default=64, min=8, max=512,
                                            description="Curve points per stitch loop")

    def compute(self, context):
        return "knit", geometry.plain_knit(self.rows, self.stitches, yarn_radius=self.yarn_radius, scale=self.scale,
                                           purl=self.purl, samples_per_loop=self.samples_per_loop)

    def swatch(self):
        return {"pattern": geometry.knit_pattern(yarn_radius=self.yarn_radius), "rows": self.rows,
                "stitches": self.stitches, "scale": self.scale, "purl": self.purl}


class NEURALYARN_OT_add_weave(_MakesYarn, bpy.types.Operator):
    """Add a woven swatch: warp and weft yarns from a weave pattern, crimped at the crossings"""

    bl_idname = "neural_yarn.add_weave"
    bl_label = "Woven Swatch"
    bl_options = {"REGISTER", "UNDO"}
    at_cursor = True

    weave: bpy.props.EnumProperty(name="Weave", items=WEAVES, default="plain", description="The interlacing pattern")
    warps: bpy.props.IntProperty(name="Warps", default=16, min=1, max=5000, description="Lengthwise yarns")
    wefts: bpy.props.IntProperty(name="Wefts", default=16, min=1, max=5000, description="Crosswise yarns")
    spacing: bpy.props.FloatProperty(name="Spacing", default=2.5, min=0.01, description="Yarn pitch (pattern units)")
    yarn_radius: bpy.props.FloatProperty(name="Yarn Radius", default=0.5, min=0.001, description="In pattern units")
    scale: bpy.props.FloatProperty(name="Scale", default=KNIT_SCALE, min=1e-6, max=100.0, precision=4,
                                   description="Pattern units to scene units")
    twill_up: bpy.props.IntProperty(name="Twill Up", default=2, min=1, max=64, description="Twill: wefts a warp floats over")
    twill_down: bpy.props.IntProperty(name="Twill Down", default=2, min=1, max=64, description="Twill: wefts a warp passes under")
    satin_harness: bpy.props.IntProperty(name="Satin Harnesses", default=5, min=5, max=128,
                                         description="Satin: the repeat K (a warp floats over K - 1 wefts)")
    satin_move: bpy.props.IntProperty(name="Satin Move", default=2, min=2, max=126,
                                      description="Satin: the shift m between neighbouring warps (coprime with K)")
    basket_n: bpy.props.IntProperty(name="Basket Size", default=2, min=1, max=64,
                                    description="Basket: yarns woven together as one (n x n)")

    #: The settings of each weave beyond the common ones (the redo panel shows only these).
    WEAVE_SETTINGS = {"plain": (), "twill": ("twill_up", "twill_down"), "satin": ("satin_harness", "satin_move"),
                      "basket": ("basket_n",)}

    def draw(self, context):
        layout = self.layout
        for name in ("weave", *self.WEAVE_SETTINGS[self.weave], "warps", "wefts", "spacing", "yarn_radius", "scale",
                     "preset"):
            layout.prop(self, name)

    def compute(self, context):
        params = {"plain": {}, "twill": {"u": self.twill_up, "d": self.twill_down},
                  "satin": {"K": self.satin_harness, "m": self.satin_move}, "basket": {"n": self.basket_n}}
        pattern = geometry.weave_pattern(self.weave, **params[self.weave])
        curves = geometry.woven_fabric(pattern, self.warps, self.wefts, spacing=self.spacing,
                                       yarn_radius=self.yarn_radius)
        for c in curves:
            c.points *= self.scale
            c.radius *= self.scale
        return f"weave {self.weave}", curves


class NEURALYARN_OT_make_plies(bpy.types.Operator):
    """Replace each yarn of the active Curves object by K plies S-twisted around it (a new object; the
    original is hidden, not deleted)"""

    bl_idname = "neural_yarn.make_plies"
    bl_label = "Twist Plies"
    bl_options = {"REGISTER", "UNDO"}

    plies: bpy.props.IntProperty(name="Plies", default=3, min=1, max=16, description="Plies twisted into each yarn")
    ply_twist: bpy.props.FloatProperty(name="Ply Twist alpha", default=0.5, min=0.0, max=8.0,
                                       description="2 R_yarn x plies turns per unit length")
    samples_per_turn: bpy.props.IntProperty(name="Samples per Turn", default=PLY_SAMPLES_PER_TURN, min=4, max=256,
                                            description="Curve points per turn of each ply's helix")
    preset: bpy.props.EnumProperty(name="Material", items=KEEP_OR_PRESET, default="KEEP",
                                   description="The plies' material: the yarn's own, or a preset")

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is not None and obj.type == "CURVES":
            return True
        if hasattr(cls, "poll_message_set"):
            cls.poll_message_set("Select a Curves object: yarns added or imported with Neural Yarn")
        return False

    def execute(self, context):
        src = context.active_object
        try:
            obj = make_plies_object(context, src, self.plies, self.ply_twist, self.samples_per_turn,
                                    src.active_material if self.preset == "KEEP" else None)
        except (geometry.GeometryError, MemoryError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        try:
            if self.preset != "KEEP":
                _give_preset_material(obj, self.preset)
        except (model_io.ModelFileError, OSError, ValueError) as e:
            curves_bpy.remove_curves_object(obj)
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        # Its yarns' plies: a level of detail applied to the yarns reuses them while the yarns are as they were (a
        # copy of the yarns does not); an object of their own, not the yarns' child.
        level_of_detail.adopt(src, obj, tuple(range(len(src.data.curves))), self.plies, parent=False)
        src.neural_yarn.plies_object, src.neural_yarn.plies = obj, self.plies
        src.hide_set(True)
        src.hide_render = True
        self.report({"INFO"}, f"{obj.name}: {len(obj.data.curves)} plies from {len(src.data.curves)} yarns")
        return {"FINISHED"}


def make_plies_object(context, src, plies: int, ply_twist: float, samples_per_turn: int, material, yarns=None):
    """A new Curves object "<src> plies": each yarn of `src` (or those of the indices `yarns`) replaced by `plies`
    plies S-twisted around it, with `material` (or none); `src` itself is left as it is. Raises GeometryError
    (nothing is created)."""
    curves = curves_bpy.read_curves_object(src)
    if yarns is not None:
        curves = [curves[k] for k in yarns]
    out = []
    with _Progress(context, len(curves)) as progress:
        for k, yarn in enumerate(curves):
            out += geometry.twist_plies(yarn, plies, alpha_yarn=ply_twist, samples_per_turn=samples_per_turn)
            progress.update(k + 1)
    name = f"{src.name} plies" if yarns is None else f"{src.name} near plies"
    obj = curves_bpy.create_curves_object(context, name, out, material=material)
    obj.neural_yarn.plies = 1  # its curves are plies: a level of detail applied to it never twists them again
    return obj


def make_yarns_part(context, src, yarns, material):
    """A new Curves object "<src> far yarns": the yarns of `src` of the indices `yarns`, as they are, with `material`
    (or none). Raises GeometryError (nothing is created)."""
    curves = curves_bpy.read_curves_object(src)
    obj = curves_bpy.create_curves_object(context, f"{src.name} far yarns", [curves[k] for k in yarns],
                                          material=material)
    obj.neural_yarn.plies = 1  # drawn as yarns; a level of detail is applied through `src`, never to it alone
    return obj


class NEURALYARN_OT_apply_lod(bpy.types.Operator):
    """Build each selected yarn object at its level of detail from the scene camera: ply curves where a ply is
    wide on screen, the yarns themselves with the yarn-level model where it is not (geometry only at the level
    used)"""

    bl_idname = "neural_yarn.apply_lod"
    bl_label = "Apply Level of Detail"
    bl_options = {"REGISTER", "UNDO"}

    @staticmethod
    def targets(context) -> list:
        """The selected yarn objects; a selected plies or surface object stands for its yarns; each once."""
        found = (level_of_detail.yarn_object_of(o, context.scene) for o in context.selected_objects)
        return list(dict.fromkeys(o for o in found if o.type == "CURVES"))

    @classmethod
    def poll(cls, context):
        if cls.targets(context):
            return True
        if hasattr(cls, "poll_message_set"):
            cls.poll_message_set("Select the yarn Curves objects (the yarns, their plies or their surface)")
        return False

    def execute(self, context):
        targets = self.targets(context)
        lines, failed = [], []
        for obj in targets:
            try:  # each object whole or not at all: apply_level changes nothing before its plies exist
                choice = level_of_detail.apply_level(context, obj)
            except (geometry.GeometryError, model_io.ModelFileError, OSError, ValueError, MemoryError) as e:
                failed.append(f"{obj.name}: {e}")
                continue
            lines.append(f"{obj.name}: {obj.neural_yarn.chosen}")
            if choice.warning:
                self.report({"WARNING"}, f"{obj.name}: {choice.warning}")
        if failed:
            self.report({"ERROR"}, "level of detail not applied to " + "; ".join(failed))
        if not lines:
            return {"CANCELLED"}
        self.report({"INFO"}, "level of detail: " + "; ".join(lines))
        return {"FINISHED"}


class NEURALYARN_OT_assign_preset(bpy.types.Operator):
    """Give the selected Curves objects the neural yarn material of a preset"""

    bl_idname = "neural_yarn.assign_preset"
    bl_label = "Assign Yarn Material"
    bl_options = {"REGISTER", "UNDO"}

    preset: bpy.props.EnumProperty(name="Preset", items=[i for i in PRESET_OR_NONE if i[0] != "NONE"],
                                   description="The neural yarn material to give the selected Curves objects")

    def execute(self, context):
        targets = [o for o in context.selected_objects if o.type == "CURVES"]
        if not targets:
            self.report({"ERROR"}, "select one or more Curves objects (yarn curves)")
            return {"CANCELLED"}
        try:
            mat = preset_material(self.preset)
        except (model_io.ModelFileError, OSError, ValueError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        for obj in targets:
            obj.data.materials.clear()
            obj.data.materials.append(mat)
        self.report({"INFO"}, f"'{mat.name}' on {len(targets)} object(s)")
        return {"FINISHED"}


NEURAL_YARN_NODES = (nodes.NODE_IDNAME, nodes.BUILTIN_IDNAME)


def _context_node(context, idnames):
    """The node an operator acts on: the UI's `node` (a panel's context pointer), else the edited tree's
    active node; None unless its bl_idname is one of `idnames`."""
    node = getattr(context, "node", None)
    if node is None:
        space = getattr(context, "space_data", None)
        tree = getattr(space, "edit_tree", None)
        node = tree.nodes.active if tree is not None else None
    return node if node is not None and node.bl_idname in idnames else None


class NEURALYARN_OT_load_model(bpy.types.Operator, ImportHelper):
    """Load a model file made with `neuralyarn bake` into a Neural Yarn BSDF node (packed into the .blend)"""

    bl_idname = "neural_yarn.load_model"
    bl_label = "Load Model File"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".json"
    filter_glob: bpy.props.StringProperty(default="*.json", options={"HIDDEN"})

    def execute(self, context):
        node = _context_node(context, (nodes.NODE_IDNAME,))
        if node is None:
            self.report({"ERROR"}, "no active Neural Yarn BSDF node")
            return {"CANCELLED"}
        try:
            text = nodes.pack_model_file(self.filepath)
        except model_io.ModelFileError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        node["preset"] = len(resources.PRESETS)  # CUSTOM, without reloading a shipped model
        node.model = text
        if node.error:
            self.report({"ERROR"}, node.error)
            return {"CANCELLED"}
        self.report({"INFO"}, f"model '{text.name}' packed into the file")
        return {"FINISHED"}


class NEURALYARN_OT_frame_render(bpy.types.Operator):
    """Add a camera that frames the selected yarns (all Curves objects if none is selected), a key and a rim
    light, and render settings that work in this Blender (no denoiser where it has none; transparent
    bounces for stacked cloth)"""

    bl_idname = "neural_yarn.frame_render"
    bl_label = "Frame for Render"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        yarns = [o for o in context.selected_objects if o.type == "CURVES"] or \
            [o for o in context.scene.objects if o.type == "CURVES"]
        if not yarns:
            self.report({"ERROR"}, "no yarn curves to frame: add a swatch or import yarns first")
            return {"CANCELLED"}
        scene_setup.frame(context.scene, yarns)
        changed = scene_setup.render_settings(context.scene)
        self.report({"INFO"}, f"camera and lights around {len(yarns)} object(s)" +
                    (f"; {', '.join(changed)}" if changed else ""))
        return {"FINISHED"}


class NEURALYARN_OT_convert_node(bpy.types.Operator):
    """Swap the active Neural Yarn BSDF node for the other kind: Blender's built-in node (a patched Blender
    only: files with it render the yarn only there) or the add-on's node (renders everywhere, natively in a
    patched Blender); the model, tint, links and name carry over"""

    bl_idname = "neural_yarn.convert_node"
    bl_label = "Convert Neural Yarn Node"
    bl_options = {"REGISTER", "UNDO"}

    to: bpy.props.EnumProperty(
        name="To", default="BUILTIN",
        items=(("BUILTIN", "Built-in Node", "Blender's own Neural Yarn BSDF (a Blender built with cycles_patch/)"),
               ("ADDON", "Add-on Node", "The add-on's Neural Yarn BSDF: presets, and a fallback for stock Blender")),
        description="The kind of node the active Neural Yarn BSDF node becomes")

    @classmethod
    def poll(cls, context):
        return nodes.builtin_available() and _context_node(context, NEURAL_YARN_NODES) is not None

    def execute(self, context):
        node = _context_node(context, NEURAL_YARN_NODES)
        if node is None:
            self.report({"ERROR"}, "no active Neural Yarn BSDF node")
            return {"CANCELLED"}
        try:
            new, warnings = nodes.convert_node(node, self.to)
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        new.id_data.nodes.active = new
        for w in warnings:
            self.report({"WARNING"}, f"{new.name}: {w}")
        return {"FINISHED"}


CLASSES = (
    NEURALYARN_OT_import_bcc,
    NEURALYARN_OT_import_leaf,
    NEURALYARN_OT_add_knit,
    NEURALYARN_OT_add_weave,
    NEURALYARN_OT_make_plies,
    NEURALYARN_OT_apply_lod,
    NEURALYARN_OT_assign_preset,
    NEURALYARN_OT_load_model,
    NEURALYARN_OT_frame_render,
    NEURALYARN_OT_convert_node,
)


def _import_menu(self, context):
    self.layout.operator(NEURALYARN_OT_import_bcc.bl_idname, text="BCC Yarns (.bcc)")
    self.layout.operator(NEURALYARN_OT_import_leaf.bl_idname, text="Periodic Yarn Pattern (Leaf et al.)")


def _add_menu(self, context):
    self.layout.separator()
    self.layout.operator(NEURALYARN_OT_add_knit.bl_idname, icon="OUTLINER_OB_CURVES")
    self.layout.operator(NEURALYARN_OT_add_weave.bl_idname, icon="OUTLINER_OB_CURVES")


def _node_context_menu(self, context):
    node = _context_node(context, NEURAL_YARN_NODES)
    if node is None or not nodes.builtin_available():
        return
    self.layout.separator()
    to = "ADDON" if node.bl_idname == nodes.BUILTIN_IDNAME else "BUILTIN"
    op = self.layout.operator(NEURALYARN_OT_convert_node.bl_idname,
                              text="Convert to Add-on Node" if to == "ADDON" else "Convert to Built-in Node")
    op.to = to


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_file_import.append(_import_menu)
    bpy.types.VIEW3D_MT_add.append(_add_menu)
    bpy.types.NODE_MT_context_menu.append(_node_context_menu)


def unregister():
    bpy.types.NODE_MT_context_menu.remove(_node_context_menu)
    bpy.types.VIEW3D_MT_add.remove(_add_menu)
    bpy.types.TOPBAR_MT_file_import.remove(_import_menu)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)

