# SPDX-License-Identifier: GPL-3.0-or-later
"""How yarn curves look in Solid and Material Preview: short pieces, so that the viewport draws every point.

Blender draws each curve of a Curves object in the viewport with 2^(3 + hair_subdiv) points, however long
the curve is (draw_cache_impl_curves.cc: `final.resolution = 1 << (steps + subdiv)`, steps = 3, in 3.4 as
in 4.5). That suits hair, a few points per strand; a knitted row is one curve of hundreds of points, and at
the default subdivision it is drawn through 8 of them: the knit shows as a zigzag. Renders take every
point, so only the viewport is wrong.

The add-on's Curves objects therefore get a Geometry Nodes modifier that is on in the viewport and off for
renders (F12, batch renders and animation renders use the curves as they are): it cuts every curve into pieces
of up to PIECE_POINTS points, linked by one-segment pieces between them, which the viewport then draws through
each point. Cycles would render the pieces' ends (a kink, slits on the outside of thick bends), so while a 3D
viewport shows Rendered shading with Cycles the modifiers are off (sync(): on a change of a viewport's
shading, an engine, a window's workspace or scene, after undo and redo, and every second for areas closed or
opened): that viewport then renders what F12 renders, and Solid views beside it draw zigzags until it leaves
Rendered shading. Objects of more than DISPLAY_POINTS points are drawn with 1/n of their points, each curve
resampled evenly (the modifier's "Point Step" n), a lighter display of heavy garments."""

from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

MODIFIER = "Neural Yarn display"
GROUP = ".NeuralYarn viewport pieces"
#: The node group's version, stamped on it: a file's group of another version (or a library's) is not
#: used for new objects, and load_post moves the file's own objects to the current one.
VERSION = 2
_STAMP = "neural_yarn_display_version"
#: Points per piece: the 2^3 points the viewport draws a curve with at the default subdivision (0), so that
#: each drawn point is near a control point.
PIECE_POINTS = 8
#: Points an object may have before its display is resampled to 1/n of them (the modifier's "Point Step" n,
#: chosen when the object is made; the artist can change it on the modifier).
DISPLAY_POINTS = 1_000_000
STEP = "Point Step"
_RADIUS = "ny_display_radius"
_SOURCE = "ny_display_source"
_MATERIAL = "ny_display_material"
#: Socket types of the attribute nodes' data types.
_KIND = {"FLOAT": "VALUE", "INT": "INT", "BOOLEAN": "BOOLEAN"}


def _socket(sockets, name: str, kind: str):
    """The socket called `name` of type `kind` (3.4's attribute and switch nodes carry one per data type)."""
    for s in sockets:
        if s.name == name and s.type == kind and getattr(s, "enabled", True):
            return s
    raise LookupError(f"no {kind} socket '{name}'")


def _new_group():
    ng = bpy.data.node_groups.new(GROUP, "GeometryNodeTree")
    ng[_STAMP] = VERSION
    if hasattr(ng, "interface"):  # Blender 4.0+
        ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        step = ng.interface.new_socket(STEP, in_out="INPUT", socket_type="NodeSocketInt")
        ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        ng.inputs.new("NodeSocketGeometry", "Geometry")
        step = ng.inputs.new("NodeSocketInt", STEP)
        ng.outputs.new("NodeSocketGeometry", "Geometry")
    step.default_value, step.min_value, step.max_value = 1, 1, 1000
    step.description = ("Draw each curve with 1/n of its points, resampled evenly along it (1: every point): a "
                        "lighter viewport for heavy garments; renders take every point")
    nodes, link = ng.nodes, ng.links.new

    def node(kind, **props):
        n = nodes.new(kind)
        for k, v in props.items():
            setattr(n, k, v)
        return n

    def store(geometry, name, data_type, domain, value):
        """`value`: a socket, or a constant."""
        n = node("GeometryNodeStoreNamedAttribute", data_type=data_type, domain=domain)
        n.inputs["Name"].default_value = name
        link(geometry, n.inputs["Geometry"])
        target = _socket(n.inputs, "Value", _KIND[data_type])
        if isinstance(value, (bool, int, float)):
            target.default_value = value
        else:
            link(value, target)
        return n.outputs[0]

    def named(name, data_type):
        n = node("GeometryNodeInputNamedAttribute", data_type=data_type)
        n.inputs["Name"].default_value = name
        return _socket(n.outputs, "Attribute", _KIND[data_type])

    def math(operation, a, b=None, c=None):
        n = node("ShaderNodeMath", operation=operation)
        for k, v in enumerate((a, b, c)):
            if isinstance(v, (int, float)):
                n.inputs[k].default_value = v
            elif v is not None:
                link(v, n.inputs[k])
        return n.outputs[0]

    group_in, group_out = node("NodeGroupInput"), node("NodeGroupOutput")
    curves, step = group_in.outputs[0], group_in.outputs[1]
    # Poly curves keep their control points through Curve to Mesh (Catmull-Rom ones would be evaluated at
    # 12 points per segment); the radius and each curve's material index ride along as named attributes.
    poly = node("GeometryNodeCurveSplineType", spline_type="POLY")
    link(curves, poly.inputs["Curve"])
    carried = store(poly.outputs[0], _RADIUS, "FLOAT", "POINT", node("GeometryNodeInputRadius").outputs[0])
    carried = store(carried, _MATERIAL, "INT", "POINT", named("material_index", "INT"))
    # A point step n above 1 resamples each curve evenly to ceil((points - 1) / n) + 1 points.
    points = _socket(node("GeometryNodeSplineLength").outputs, "Point Count", "INT")
    resample = node("GeometryNodeResampleCurve", mode="COUNT")
    link(carried, resample.inputs["Curve"])
    link(math("ADD", math("CEIL", math("DIVIDE", math("SUBTRACT", points, 1.0), step)), 1.0), resample.inputs["Count"])
    switch = node("GeometryNodeSwitch", input_type="GEOMETRY")
    link(math("GREATER_THAN", step, 1.0), _socket(switch.inputs, "Switch", "BOOLEAN"))
    link(carried, _socket(switch.inputs, "False", "GEOMETRY"))
    link(resample.outputs[0], _socket(switch.inputs, "True", "GEOMETRY"))
    # Every PIECE_POINTS-th edge is split from its neighbours (a one-segment piece of its own): the curves
    # fall apart into pieces of at most PIECE_POINTS points, and the one-segment links between them.
    to_mesh = node("GeometryNodeCurveToMesh")
    link(_socket(switch.outputs, "Output", "GEOMETRY"), to_mesh.inputs["Curve"])
    split = node("GeometryNodeSplitEdges")
    link(to_mesh.outputs[0], split.inputs["Mesh"])
    index = node("GeometryNodeInputIndex").outputs[0]
    link(math("COMPARE", math("MODULO", index, PIECE_POINTS), PIECE_POINTS - 1, 0.25), split.inputs["Selection"])
    to_curve = node("GeometryNodeMeshToCurve")
    link(split.outputs[0], to_curve.inputs["Mesh"])
    set_radius = node("GeometryNodeSetCurveRadius")
    link(to_curve.outputs[0], set_radius.inputs["Curve"])
    link(named(_RADIUS, "FLOAT"), set_radius.inputs["Radius"])
    pieces = store(set_radius.outputs[0], "material_index", "INT", "CURVE", named(_MATERIAL, "INT"))
    # Geometry Nodes do not carry materials through a mesh: joined after the first original curve, the pieces
    # take its materials (realize_instances copies the first curves' parameters); that curve, marked, is then
    # deleted.
    first = node("GeometryNodeDeleteGeometry", domain="CURVE")
    link(curves, first.inputs["Geometry"])
    link(math("GREATER_THAN", index, 0.5), first.inputs["Selection"])
    marked = store(first.outputs[0], _SOURCE, "BOOLEAN", "CURVE", True)
    join = node("GeometryNodeJoinGeometry")
    link(pieces, join.inputs[0])
    link(marked, join.inputs[0])  # linked last, joined first (3.4 and 4.5): its materials are kept
    delete = node("GeometryNodeDeleteGeometry", domain="CURVE")
    link(join.outputs[0], delete.inputs["Geometry"])
    link(named(_SOURCE, "BOOLEAN"), delete.inputs["Selection"])
    out = delete.outputs[0]
    for name in (_RADIUS, _MATERIAL, _SOURCE):
        remove = node("GeometryNodeRemoveAttribute")
        remove.inputs["Name"].default_value = name
        link(out, remove.inputs["Geometry"])
        out = remove.outputs[0]
    link(out, group_out.inputs[0])
    return ng


def _is_current(ng) -> bool:
    return (ng is not None and ng.bl_idname == "GeometryNodeTree" and ng.library is None
            and ng.get(_STAMP) == VERSION)


def _current_group():
    """The file's display node group of this version, or None."""
    return next((ng for ng in bpy.data.node_groups if _is_current(ng)), None)


def node_group():
    """The add-on's display node group of this version, made once per file."""
    return _current_group() or _new_group()


def display_modifier(obj):
    """An object's display modifier (the add-on's node group of any version, whatever the modifier's name)."""
    for m in getattr(obj, "modifiers", ()):
        if m.type == "NODES" and m.node_group is not None and m.node_group.get(_STAMP) is not None:
            return m
    return None


def point_step(points: int) -> int:
    """The display's point step for an object of `points` points: 1 (every point) up to DISPLAY_POINTS."""
    return max(1, -(-points // DISPLAY_POINTS))


def _input_identifier(ng, name: str) -> str:
    """How a modifier names the group input `name` (its identifier: "Input_2" in 3.x, "Socket_1" in 4.x)."""
    items = ng.interface.items_tree if hasattr(ng, "interface") else ng.inputs
    found = next((i.identifier for i in items if getattr(i, "in_out", "INPUT") == "INPUT" and i.name == name), None)
    if found is None:
        raise LookupError(f"the node group '{ng.name}' has no input '{name}'")
    return found


def display_step(obj) -> int:
    """The point step an object's display modifier draws with (1 for a group without one)."""
    modifier = display_modifier(obj)
    try:
        return int(modifier[_input_identifier(modifier.node_group, STEP)])
    except (LookupError, KeyError):
        return 1


def set_display_step(obj, step: int) -> None:
    """Draw the object's curves with 1/step of their points (its display modifier's "Point Step")."""
    modifier = display_modifier(obj)
    modifier[_input_identifier(modifier.node_group, STEP)] = step


def _use_current_group(obj, modifier) -> None:
    modifier.node_group = node_group()
    set_display_step(obj, point_step(len(obj.data.points)))


def add_to(obj) -> None:
    """Gives a Curves object the viewport-only display modifier (once)."""
    if display_modifier(obj) is not None:
        return
    had_group = _current_group() is not None
    modifier = None
    try:
        modifier = obj.modifiers.new(MODIFIER, "NODES")
        _use_current_group(obj, modifier)
        modifier.show_render = False
        modifier.show_viewport = True
    except Exception:
        if modifier is not None:
            obj.modifiers.remove(modifier)
        group = _current_group()
        if not had_group and group is not None and group.users == 0:
            bpy.data.node_groups.remove(group)
        raise


def upgrade() -> None:
    """Moves the file's own objects whose display modifier holds another version's group to this one (their
    point step chosen again); the old group is dropped when the file is saved, if nothing else uses it."""
    for obj in bpy.data.objects:
        modifier = display_modifier(obj) if obj.type == "CURVES" and obj.library is None else None
        if modifier is not None and not _is_current(modifier.node_group):
            _use_current_group(obj, modifier)


def cycles_renders_a_viewport(views) -> bool:
    """Whether any (shading type, render engine) of the open 3D viewports is Cycles' Rendered shading."""
    return any(shading == "RENDERED" and engine == "CYCLES" for shading, engine in views)


def _open_views():
    wm = bpy.context.window_manager
    for window in getattr(wm, "windows", ()):
        engine = window.scene.render.engine
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                yield area.spaces.active.shading.type, engine


def sync(views=None) -> None:
    """Turns the display modifiers off while Cycles renders a viewport, on otherwise (changed only where they
    differ, so that nothing is re-evaluated for nothing)."""
    show = not cycles_renders_a_viewport(_open_views() if views is None else views)
    for obj in bpy.data.objects:
        modifier = display_modifier(obj) if obj.type == "CURVES" else None
        if modifier is not None and modifier.show_viewport != show:
            modifier.show_viewport = show


_OWNER = object()
#: Seconds between checks of the open viewports for what the message bus does not announce (an area closed
#: or joined, a window opened).
_POLL_S = 1.0


def _subscribe() -> None:
    bpy.msgbus.clear_by_owner(_OWNER)
    for key in ((bpy.types.View3DShading, "type"), (bpy.types.RenderSettings, "engine"),
                (bpy.types.Window, "workspace"), (bpy.types.Window, "scene")):
        bpy.msgbus.subscribe_rna(key=key, owner=_OWNER, args=(), notify=sync)


@persistent
def _load_post(*_args) -> None:
    _subscribe()  # a file load clears the message bus
    upgrade()
    sync()


@persistent
def _undo_redo_post(*_args) -> None:
    sync()  # undo restores the modifiers' switches of its step


def _poll():
    sync()
    return _POLL_S


_HANDLERS = (("load_post", _load_post), ("undo_post", _undo_redo_post), ("redo_post", _undo_redo_post))


def register() -> None:
    _subscribe()
    for name, handler in _HANDLERS:
        if handler not in getattr(bpy.app.handlers, name):
            getattr(bpy.app.handlers, name).append(handler)
    if not bpy.app.timers.is_registered(_poll):
        bpy.app.timers.register(_poll, first_interval=_POLL_S, persistent=True)


def unregister() -> None:
    if bpy.app.timers.is_registered(_poll):
        bpy.app.timers.unregister(_poll)
    for name, handler in _HANDLERS:
        if handler in getattr(bpy.app.handlers, name):
            getattr(bpy.app.handlers, name).remove(handler)
    bpy.msgbus.clear_by_owner(_OWNER)
