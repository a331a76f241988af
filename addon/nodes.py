# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Neural Yarn BSDF" shader node: a ShaderNodeCustomGroup with a preset menu, a packed model and
the twist, whose inside is the fallback that this Blender can render (fallback_nodes.py).

The model always lives in the .blend as a Text data block (the model file's JSON, verbatim): a file
renders on another machine or a render farm without the model file. A patched Cycles (cycles_patch/)
compiles the node (bl_idname ShaderNodeNeuralYarnBsdf) to the native closure and ignores the group's
inside; stock Cycles renders the inside:

* OSL when this Blender has OSL, the scene uses it and renders on the CPU (fallback "Auto"), or when
  forced ("OSL");
* stock nodes otherwise ("Nodes"; also GPU and Blender without OSL, e.g. Debian's 3.4).

"Auto" is re-resolved before every render (a render_pre handler), so switching the scene's shading system
or device needs no action. A model that cannot be used renders in Cycles' missing-resource magenta and
the node shows the error.
"""

from __future__ import annotations

import hashlib
import json
import math

import bpy
from bpy.app.handlers import persistent

from . import fallback_nodes, model_io, resources

NODE_IDNAME = "ShaderNodeNeuralYarnBsdf"
#: Blender's own Neural Yarn BSDF node, in a Blender built with cycles_patch/ (0003); stock Blender has none.
#: It holds the model (a packed Text) and the tint; the add-on's node also has the presets and the fallback.
BUILTIN_IDNAME = "ShaderNodeBsdfNeuralYarn"
ERROR_COLOR = (1.0, 0.0, 1.0, 1.0)  # Cycles' missing-resource magenta
PRESET_ITEMS = [(p, p.title(), f"The shipped '{p}' model (the paper's {p} fibers)") for p in resources.PRESETS]
PRESET_ITEMS.append(("CUSTOM", "Custom", "A model file made with `neuralyarn bake` (Load Model File)"))
FALLBACK_ITEMS = [
    ("AUTO", "Auto", "OSL when the scene renders with Open Shading Language on the CPU, stock nodes otherwise"),
    ("OSL", "OSL", "Always the OSL script (needs Cycles with OSL: CPU, or OptiX)"),
    ("NODES", "Nodes", "Always the stock-node approximation (any device, any Blender)"),
]

_parsed: dict[str, model_io.YarnModel] = {}  # sha1 of a Text's content -> parsed model


def _digest(text: str) -> str:
    return hashlib.sha1(text.encode("utf-8")).hexdigest()


def parse_text(text) -> model_io.YarnModel:
    """The model packed in a Text data block (parsed once per content)."""
    s = text.as_string()
    d = _digest(s)
    if d not in _parsed:
        _parsed[d] = model_io.parse_model(s, f"text '{text.name}'")
    return _parsed[d]


#: Blender's Text data block takes seconds for a line of hundreds of KB (a model file written on one line:
#: 3.6 s for 0.5 MB); such a file is packed re-indented (the same JSON values, to the last bit).
MAX_PACKED_LINE = 4096


def _packed_json(model: model_io.YarnModel) -> str:
    if max(map(len, model.text.splitlines() or [""])) <= MAX_PACKED_LINE:
        return model.text
    return json.dumps(model.data, indent=1) + "\n"


def pack_model_text(model: model_io.YarnModel, name: str):
    """A Text data block holding the model's JSON: an existing one with the same content, else a new one."""
    content = _packed_json(model)
    for text in bpy.data.texts:
        if text.name.startswith(name) and text.as_string() == content:
            return text
    text = bpy.data.texts.new(name)
    text.from_string(content)
    text.use_fake_user = False
    return text


def pack_preset(preset: str, level: str = "plies"):
    """The Text of a shipped preset's model at a level ("plies" or "yarns"), loaded from the add-on's models/
    on first use."""
    model = model_io.load_model_file(resources.preset_model_path(preset, level))
    return pack_model_text(model, f"NY model {preset}{'_yarn' if level == 'yarns' else ''}.json")


def pack_model_file(path: str):
    """Validates a model file and packs it; raises ModelFileError naming the file and the problem."""
    model = model_io.load_model_file(bpy.path.abspath(path))
    return pack_model_text(model, "NY model " + bpy.path.basename(path))


def osl_active(scene) -> bool:
    return bool(
        scene is not None
        and bpy.app.build_options.cycles_osl
        and scene.render.engine == "CYCLES"
        and getattr(scene, "cycles", None) is not None
        and scene.cycles.shading_system
        and scene.cycles.device == "CPU"
    )


def _update(self, context):
    self.refresh(getattr(context, "scene", None))


def _material_of(node):
    """The material whose own node tree holds the node, or None (a node group's, a world's)."""
    tree = node.id_data
    return next((m for m in bpy.data.materials if m.node_tree is not None and m.node_tree == tree), None)


def _rename_material(node) -> None:
    """A material the add-on named after a preset ("Neural Yarn fleece", or ".001" of it) follows its node's
    new preset; a name the artist chose stays."""
    mat = _material_of(node)
    if mat is None:
        return
    stem = mat.name.split(".")[0]
    if stem.startswith("Neural Yarn ") and stem[len("Neural Yarn "):] in resources.PRESETS:
        new = f"Neural Yarn {node.preset}" if node.preset != "CUSTOM" else "Neural Yarn custom"
        if stem != new:
            mat.name = new


EEVEE_OUTPUT = "NY EEVEE output"
EEVEE_PREVIEW = "NY EEVEE preview"


def _eevee_output(node, needed: bool) -> None:
    """While the node holds OSL, its material gets a Material Output for EEVEE (Material Preview, EEVEE
    renders: they would draw the yarn black) fed by the stock-node fallback, and its own output serves
    Cycles; otherwise both go again. Only in a material's own tree."""
    tree = node.id_data
    if _material_of(node) is None:
        return
    ours = [n for n in tree.nodes if n.name.startswith((EEVEE_OUTPUT, EEVEE_PREVIEW))]
    main = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n not in ours]
    if not needed:
        for n in ours:
            tree.nodes.remove(n)
        for n in main:
            if n.target == "CYCLES":
                n.target = "ALL"
        return
    if ours or node.preview_tree is None:
        return
    for n in main:
        if n.target == "ALL":
            n.target = "CYCLES"
    group = tree.nodes.new("ShaderNodeGroup")
    group.name = EEVEE_PREVIEW
    group.node_tree = node.preview_tree
    group.location = (node.location.x, node.location.y - 300.0)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.name = EEVEE_OUTPUT
    out.target = "EEVEE"
    out.location = (group.location.x + 300.0, group.location.y)
    tree.links.new(group.outputs[fallback_nodes.GROUP_OUTPUT], out.inputs["Surface"])


def _apply_preset(self, context):
    if self.preset != "CUSTOM":
        try:
            self["model"] = pack_preset(self.preset, self.level.lower())  # item access: no nested update
        except (OSError, ValueError) as e:
            self.show_error(str(e))
            return
    self.refresh(getattr(context, "scene", None))


def _update_preset(self, context):
    _rename_material(self)
    _apply_preset(self, context)


class NeuralYarnBsdfNode(bpy.types.ShaderNodeCustomGroup):
    """Neural yarn appearance (Soh & Montazeri 2024) for a ply or yarn curve"""

    bl_idname = NODE_IDNAME
    bl_label = "Neural Yarn BSDF"
    bl_width_default = 220

    preset: bpy.props.EnumProperty(name="Preset", items=PRESET_ITEMS, default="fleece", update=_update_preset,
                                   description="The yarn material: a shipped preset, or a model file of your own")
    level: bpy.props.EnumProperty(
        name="Level", default="PLIES", update=_update_preset,
        items=(("PLIES", "Plies", "The curves are plies: the preset's ply model"),
               ("YARNS", "Yarns", "The curves are whole 3-ply yarns (ply twist 0.5): the preset's yarn-level model")),
        description="What the material's curves are (level of detail, docs/decisions.md D27)")
    model: bpy.props.PointerProperty(
        name="Model", type=bpy.types.Text, update=_update,
        description="The model file's JSON, packed into the .blend")
    twist_override: bpy.props.BoolProperty(
        name="Override Twist", default=False, update=_update,
        description="Use another fiber twist alpha than the model's (moves the surface fibers' highlight; the "
                    "lobe energies stay the model's)")
    twist: bpy.props.FloatProperty(
        name="Twist alpha", default=0.24, min=-4.0, max=4.0, update=_update,
        description="Fiber twist factor alpha: the surface fibers are tilted by atan(pi alpha) from the ply axis")
    fallback: bpy.props.EnumProperty(name="Fallback", items=FALLBACK_ITEMS, default="AUTO", update=_update,
                                     description="What renders the yarn in stock Blender (a patched Cycles uses the native closure)")
    built: bpy.props.StringProperty(name="Built", description="What the group holds now: OSL, NODES or ERROR")
    preview_tree: bpy.props.PointerProperty(
        name="EEVEE Preview", type=bpy.types.ShaderNodeTree,
        description="The stock-node fallback that EEVEE and Material Preview show while the group holds OSL")
    error: bpy.props.StringProperty(name="Error", description="Why the node renders the error colour")

    # -- node life cycle --------------------------------------------------------------------------------

    def init(self, context):
        self.node_tree = bpy.data.node_groups.new(".NeuralYarnBSDF", "ShaderNodeTree")
        fallback_nodes.ensure_interface(self.node_tree)
        # The node's socket does not take the interface's default.
        self.inputs[fallback_nodes.GROUP_INPUT_TINT].default_value = (1.0, 1.0, 1.0, 1.0)
        _apply_preset(self, context)

    def copy(self, node):
        if node.node_tree is not None:
            self.node_tree = node.node_tree.copy()

    def free(self):
        for tree in (self.node_tree, self.preview_tree):
            if tree is not None and tree.users <= 1:
                bpy.data.node_groups.remove(tree)

    # -- state ------------------------------------------------------------------------------------------

    def resolved_mode(self, scene) -> str:
        if self.fallback != "AUTO":
            return self.fallback
        return "OSL" if osl_active(scene) else "NODES"

    def tilt(self, model: model_io.YarnModel) -> float:
        alpha = self.twist if self.twist_override else model.alpha
        return math.atan(math.pi * alpha)

    def refresh(self, scene=None) -> None:
        """Rebuilds the inside for the current model, twist and fallback; an unusable model gives the error
        colour and the message (never an exception into Blender's UI)."""
        scene = scene if scene is not None else bpy.context.scene
        if self.node_tree is None:
            self.node_tree = bpy.data.node_groups.new(".NeuralYarnBSDF", "ShaderNodeTree")
        if self.model is None:
            self.show_error("no model: choose a preset or load a model file")
            return
        try:
            model = parse_text(self.model)
            if not self.twist_override:
                self["twist"] = model.alpha  # shown greyed: the model's own twist (item access: no update)
            mode = self.resolved_mode(scene)
            fallback_nodes.build(self.node_tree, model, mode, self.tilt(model))
            if mode == "OSL":  # EEVEE cannot run OSL: it gets the stock nodes through an output of its own
                if self.preview_tree is None:
                    self.preview_tree = bpy.data.node_groups.new(".NeuralYarnBSDF preview", "ShaderNodeTree")
                fallback_nodes.build(self.preview_tree, model, "NODES", self.tilt(model))
        except (model_io.ModelFileError, ValueError, KeyError, RuntimeError) as e:
            self.show_error(str(e))
            return
        self.built = mode
        self.error = ""
        _eevee_output(self, mode == "OSL")

    def show_error(self, message: str) -> None:
        tree = self.node_tree
        fallback_nodes.ensure_interface(tree)
        for n in list(tree.nodes):
            tree.nodes.remove(n)
        out = tree.nodes.new("NodeGroupOutput")
        emit = tree.nodes.new("ShaderNodeEmission")
        emit.inputs["Color"].default_value = ERROR_COLOR
        emit.location = (-200.0, 0.0)
        tree.links.new(emit.outputs[0], out.inputs[fallback_nodes.GROUP_OUTPUT])
        self.built = "ERROR"
        self.error = message
        print(f"Neural Yarn BSDF '{self.name}': {message}")

    # -- UI ---------------------------------------------------------------------------------------------

    def draw_buttons(self, context, layout):
        layout.prop(self, "preset", text="")
        if self.preset != "CUSTOM":
            layout.prop(self, "level", expand=True)
        if self.preset == "CUSTOM":
            row = layout.row(align=True)
            row.prop(self, "model", text="")
            row.operator("neural_yarn.load_model", text="", icon="FILEBROWSER")
        row = layout.row(align=True)
        row.prop(self, "twist_override", text="Own Twist")
        sub = row.row()
        sub.active = self.twist_override
        sub.prop(self, "twist", text="alpha")
        split = layout.split(factor=0.4)
        split.label(text="Fallback")
        split.prop(self, "fallback", text="")
        if self.error:
            layout.label(text=self.error, icon="ERROR")

    def draw_label(self):
        return "Neural Yarn BSDF"


def builtin_available() -> bool:
    """Whether this Blender has the built-in Neural Yarn BSDF node (a patched Blender)."""
    return hasattr(bpy.types, BUILTIN_IDNAME)


def _preset_of(text) -> tuple[str, str] | None:
    """(preset, level) when a Text holds a shipped preset's model exactly as `pack_preset` packs it."""
    stem = text.name.split(".json")[0]
    if not stem.startswith("NY model "):
        return None
    name = stem[len("NY model "):]
    preset, level = (name[:-len("_yarn")], "yarns") if name.endswith("_yarn") else (name, "plies")
    if preset not in resources.PRESETS:
        return None
    try:
        shipped = _packed_json(model_io.load_model_file(resources.preset_model_path(preset, level)))
    except (OSError, ValueError):
        return None
    return (preset, level) if text.as_string() == shipped else None


def convert_node(node, to: str):
    """Replaces a Neural Yarn BSDF node by the other kind and returns (new node, warnings): "BUILTIN",
    Blender's own node (a patched Blender only; a file with it renders the yarn only there), or "ADDON",
    this add-on's node (renders everywhere: natively in a patched Blender, its fallback elsewhere). Both
    render with the same closure in a patched Cycles: the model Text, tint, links, place and name carry
    over. Raises ValueError, changing nothing, when the conversion cannot be made."""
    if to not in ("BUILTIN", "ADDON"):
        raise ValueError(f"unknown node kind '{to}' (BUILTIN or ADDON)")
    kinds = {NODE_IDNAME: "ADDON", BUILTIN_IDNAME: "BUILTIN"}
    if node.bl_idname not in kinds:
        raise ValueError(f"'{node.name}' is not a Neural Yarn BSDF node")
    if kinds[node.bl_idname] == to:
        return node, []
    if to == "BUILTIN" and not builtin_available():
        raise ValueError("this Blender has no built-in Neural Yarn BSDF node (a Blender built with "
                         "cycles_patch/ has it)")
    if node.model is None:
        raise ValueError(f"'{node.name}' has no model to carry over")
    tree, text, warnings = node.id_data, node.model, []
    if to == "BUILTIN" and node.twist_override:
        warnings.append("the built-in node renders the model's own twist (the override was fallback-only)")
    if to == "ADDON" and node.inputs["Normal"].is_linked:
        warnings.append("the Normal input's link is dropped (the add-on's node has no Normal input)")
    tint = node.inputs[fallback_nodes.GROUP_INPUT_TINT]
    links_in = [l.from_socket for l in tint.links]
    links_out = [l.to_socket for l in node.outputs[fallback_nodes.GROUP_OUTPUT].links]
    state = (node.name, node.label, node.location.copy(), node.width, node.parent, tuple(tint.default_value))
    if to == "BUILTIN":
        _eevee_output(node, False)  # the OSL-era EEVEE output goes with the node that made it
    texts_before = set(bpy.data.texts)
    new = tree.nodes.new(BUILTIN_IDNAME if to == "BUILTIN" else NODE_IDNAME)
    if to == "BUILTIN":
        new.model = text
    else:
        shipped = _preset_of(text)
        if shipped is not None:  # the preset menu again, with the same packed Text
            new["level"] = 1 if shipped[1] == "yarns" else 0
            new["preset"] = [i[0] for i in PRESET_ITEMS].index(shipped[0])
        else:
            new["preset"] = len(resources.PRESETS)  # CUSTOM
        packed = new.model  # the default preset the node's init packed
        new.model = text  # the update builds the fallback for it
        _drop_unused_text(packed, texts_before)
    tree.nodes.remove(node)
    name, new.label, new.location, new.width, parent, default = state
    new.name, new.parent = name, parent
    new.inputs[fallback_nodes.GROUP_INPUT_TINT].default_value = default
    for socket in links_in:
        tree.links.new(socket, new.inputs[fallback_nodes.GROUP_INPUT_TINT])
    for socket in links_out:
        tree.links.new(new.outputs[fallback_nodes.GROUP_OUTPUT], socket)
    return new, warnings


def iter_nodes():
    """Every Neural Yarn BSDF node in materials, worlds' and lights' trees and node groups."""
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree is not None]
    trees += list(bpy.data.node_groups)
    for tree in trees:
        for node in tree.nodes:
            if node.bl_idname == NODE_IDNAME:
                yield node


#: A built-in node in a Blender without it (a file from a patched Blender): undefined, its sockets kept.
_BUILTIN_SOCKETS = (["Tint", "Normal", "Weight"], ["BSDF"])


def unrenderable_builtin_nodes(materials=None) -> list[str]:
    """"material 'M', node 'N'" for each built-in Neural Yarn BSDF node that this Blender cannot render: it has
    no such node, so a file saved in a patched Blender loads it as an undefined node, and the material renders
    without the yarn (black or transparent, with no message from Blender). Recognised by the sockets the
    undefined node keeps. `materials`: those to look in (default: all)."""
    if builtin_available():
        return []
    found = []

    def look(tree, where, seen):
        for node in tree.nodes:
            if node.bl_idname == "NodeUndefined" and \
                    ([s.name for s in node.inputs], [s.name for s in node.outputs]) == _BUILTIN_SOCKETS:
                found.append(f"{where}, node '{node.name}'")
            group = getattr(node, "node_tree", None)  # inside node groups too, each once
            if node.bl_idname == "ShaderNodeGroup" and group is not None and group not in seen:
                seen.add(group)
                look(group, f"{where}, group '{group.name}'", seen)

    for mat in bpy.data.materials if materials is None else materials:
        if mat is not None and mat.node_tree is not None:
            look(mat.node_tree, f"material '{mat.name}'", set())
    return found


def builtin_node_message(found: list[str]) -> str:
    return (f"{'; '.join(found)}: Blender's built-in Neural Yarn BSDF node, which only a patched Blender has; "
            "here the yarn would render black. Open the file in a patched Blender and convert the node to the "
            "add-on's (node editor, right click: Convert to Add-on Node), which renders everywhere")


def sync(scene) -> int:
    """Rebuilds the nodes whose inside does not match what the scene can render; returns how many."""
    count = 0
    for node in list(iter_nodes()):
        if node.built != "ERROR" and node.built != node.resolved_mode(scene):
            node.refresh(scene)
            count += 1
    return count


def purge_unused() -> int:
    """Removes the add-on's Texts (packed models "NY model ...", OSL fallbacks "NY ... .osl") and table
    images ("NY ...") that nothing uses any more: every preset an artist tried would otherwise stay packed
    in the .blend (Texts are saved whether used or not). Returns how many were removed."""
    used = {n.model for n in iter_nodes() if n.model is not None}
    trees = [m.node_tree for m in bpy.data.materials if m.node_tree is not None] + list(bpy.data.node_groups)
    for tree in trees:
        for n in tree.nodes:
            if n.bl_idname == "ShaderNodeScript" and n.script is not None:
                used.add(n.script)
            elif n.bl_idname == BUILTIN_IDNAME and n.model is not None:
                used.add(n.model)
    removed = 0
    for text in list(bpy.data.texts):
        if text.name.startswith("NY ") and text not in used:
            bpy.data.texts.remove(text)
            removed += 1
    for img in list(bpy.data.images):
        if img.name.startswith("NY ") and img.users == 0:
            bpy.data.images.remove(img)
            removed += 1
    return removed


@persistent
def _render_pre(scene, *_args):
    sync(scene)
    found = unrenderable_builtin_nodes()
    if found:  # a render_pre handler cannot stop the render; batch.py refuses before it
        print(f"Neural Yarn: warning: {builtin_node_message(found)}")


@persistent
def _save_pre(*_args):
    purge_unused()


def _drop_unused_text(text, texts_before) -> None:
    """Removes `text` when a new node packed it (it is not among `texts_before`) and it has ended up unused: the
    default preset a node's init packs before it is given its model, which would otherwise sit among the file's
    Texts until a save purges it."""
    if text is not None and text not in texts_before and text.users == 0:
        bpy.data.texts.remove(text)


def make_material(name: str, *, preset: str | None = None, model_text=None, level: str = "plies"):
    """A material whose surface is one Neural Yarn BSDF node (a preset's model at `level`, plies or yarns)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    texts_before = set(bpy.data.texts)
    node = tree.nodes.new(NODE_IDNAME)
    packed = node.model  # the default preset, packed by the node's init
    if model_text is not None:
        node.preset = "CUSTOM"
        node.model = model_text
    elif preset is not None:
        node["level"] = 1 if level == "yarns" else 0  # item access: the preset's update below packs it once
        if preset != node.preset:
            node.preset = preset
        elif level == "yarns":
            _apply_preset(node, bpy.context)
    _drop_unused_text(packed, texts_before)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    out.location = (300.0, 0.0)
    tree.links.new(node.outputs[fallback_nodes.GROUP_OUTPUT], out.inputs["Surface"])
    return mat, node


def _menu(self, context):
    if getattr(context.space_data, "tree_type", "") == "ShaderNodeTree":
        op = self.layout.operator("node.add_node", text="Neural Yarn BSDF", icon="OUTLINER_OB_CURVES")
        op.type = NODE_IDNAME
        op.use_transform = True


def register():
    bpy.utils.register_class(NeuralYarnBsdfNode)
    bpy.types.NODE_MT_add.append(_menu)
    if _render_pre not in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.append(_render_pre)
    if _save_pre not in bpy.app.handlers.save_pre:
        bpy.app.handlers.save_pre.append(_save_pre)


def unregister():
    if _save_pre in bpy.app.handlers.save_pre:
        bpy.app.handlers.save_pre.remove(_save_pre)
    if _render_pre in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.remove(_render_pre)
    bpy.types.NODE_MT_add.remove(_menu)
    bpy.utils.unregister_class(NeuralYarnBsdfNode)
