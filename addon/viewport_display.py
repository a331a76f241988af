# SPDX-License-Identifier: GPL-3.0-or-later
"""How yarn curves look in Solid and Material Preview: short pieces, so that the viewport draws every point.

Blender draws each curve of a Curves object in the viewport with 2^(3 + hair_subdiv) points, however long
the curve is (draw_cache_impl_curves.cc: `final.resolution = 1 << (steps + subdiv)`, steps = 3, in 3.4 as
in 4.5). That suits hair, a few points per strand; a knitted row is one curve of hundreds of points, and at
the default subdivision it is drawn through 8 of them: the knit shows as a zigzag. Renders take every
point, so only the viewport is wrong.

The add-on's Curves objects therefore get a Geometry Nodes modifier that is on in the viewport and off for
renders (F12, batch renders and animation renders use the curves as they are): it cuts every curve into
pieces of PIECE_POINTS points that share their end points, which the viewport then draws through each point.
Cycles would render the pieces' ends (a kink, slits on the outside of thick bends), so while a 3D viewport
shows Rendered shading with Cycles the modifiers are off (sync(), on every change of a viewport's shading or
a scene's engine): that viewport then renders what F12 renders, and Solid views beside it draw zigzags until
it leaves Rendered shading. Objects of more than DISPLAY_POINTS points are drawn through every n-th point
(the modifier's "Point Step"), a lighter display of heavy garments."""

from __future__ import annotations

import bpy

MODIFIER = "Neural Yarn display"
GROUP = ".NeuralYarn viewport pieces"
#: Points per piece: the 2^3 points the viewport draws a curve with at the default subdivision (0), so that
#: each drawn point is near a control point.
PIECE_POINTS = 8
#: Points an object may have before its display draws every n-th (the modifier's "Point Step", chosen when
#: the object is made; the artist can change it on the modifier).
DISPLAY_POINTS = 1_000_000
STEP = "Point Step"
_RADIUS = "ny_display_radius"
_SOURCE = "ny_display_source"


def _socket(sockets, name: str, kind: str):
    """The socket called `name` of type `kind` (3.4's attribute and switch nodes carry one per data type)."""
    for s in sockets:
        if s.name == name and s.type == kind and getattr(s, "enabled", True):
            return s
    raise LookupError(f"no {kind} socket '{name}'")


def _new_group():
    ng = bpy.data.node_groups.new(GROUP, "GeometryNodeTree")
    if hasattr(ng, "interface"):  # Blender 4.0+
        ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        step = ng.interface.new_socket(STEP, in_out="INPUT", socket_type="NodeSocketInt")
        ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        ng.inputs.new("NodeSocketGeometry", "Geometry")
        step = ng.inputs.new("NodeSocketInt", STEP)
        ng.outputs.new("NodeSocketGeometry", "Geometry")
    step.default_value, step.min_value, step.max_value = 1, 1, 1000
    step.description = ("Draw every n-th point of each curve (and its last) in the viewport: lighter display of "
                        "heavy garments; renders take every point")
    nodes, link = ng.nodes, ng.links.new

    def node(kind, **props):
        n = nodes.new(kind)
        for k, v in props.items():
            setattr(n, k, v)
        return n

    group_in, group_out = node("NodeGroupInput"), node("NodeGroupOutput")
    # Poly curves keep their control points through Curve to Mesh (Catmull-Rom ones would be evaluated at
    # 12 points per segment); the radius rides along as a named attribute.
    poly = node("GeometryNodeCurveSplineType", spline_type="POLY")
    store = node("GeometryNodeStoreNamedAttribute", data_type="FLOAT", domain="POINT")
    store.inputs["Name"].default_value = _RADIUS
    # A point step above 1 resamples each curve to every step-th point's count (evenly along it).
    count = node("GeometryNodeSplineLength")
    minus_one = node("ShaderNodeMath", operation="SUBTRACT")
    minus_one.inputs[1].default_value = 1.0
    per_step = node("ShaderNodeMath", operation="DIVIDE")
    ceil = node("ShaderNodeMath", operation="CEIL")
    plus_one = node("ShaderNodeMath", operation="ADD")
    plus_one.inputs[1].default_value = 1.0
    resample = node("GeometryNodeResampleCurve", mode="COUNT")
    stepped = node("ShaderNodeMath", operation="GREATER_THAN")
    stepped.inputs[1].default_value = 1.0
    switch = node("GeometryNodeSwitch", input_type="GEOMETRY")
    to_mesh = node("GeometryNodeCurveToMesh")
    # Every PIECE_POINTS-th edge is split from its neighbours (a two-point piece of its own): the curves
    # fall apart into pieces of at most PIECE_POINTS points.
    index = node("GeometryNodeInputIndex")
    modulo = node("ShaderNodeMath", operation="MODULO")
    modulo.inputs[1].default_value = PIECE_POINTS
    is_cut = node("ShaderNodeMath", operation="COMPARE")
    is_cut.inputs[1].default_value = PIECE_POINTS - 1
    is_cut.inputs[2].default_value = 0.25
    split = node("GeometryNodeSplitEdges")
    to_curve = node("GeometryNodeMeshToCurve")
    stored = node("GeometryNodeInputNamedAttribute", data_type="FLOAT")
    stored.inputs["Name"].default_value = _RADIUS
    set_radius = node("GeometryNodeSetCurveRadius")
    # Geometry Nodes do not carry materials through the mesh: joined after the original curves, the pieces
    # take the first input's materials (realize_instances copies the first curves' parameters), and the
    # original curves, marked, are then deleted.
    mark = node("GeometryNodeStoreNamedAttribute", data_type="BOOLEAN", domain="CURVE")
    mark.inputs["Name"].default_value = _SOURCE
    _socket(mark.inputs, "Value", "BOOLEAN").default_value = True
    join = node("GeometryNodeJoinGeometry")
    marked = node("GeometryNodeInputNamedAttribute", data_type="BOOLEAN")
    marked.inputs["Name"].default_value = _SOURCE
    delete = node("GeometryNodeDeleteGeometry", domain="CURVE")
    removes = [node("GeometryNodeRemoveAttribute") for _ in range(2)]
    removes[0].inputs["Name"].default_value = _RADIUS
    removes[1].inputs["Name"].default_value = _SOURCE

    link(group_in.outputs[0], poly.inputs["Curve"])
    link(poly.outputs[0], store.inputs["Geometry"])
    link(node("GeometryNodeInputRadius").outputs[0], _socket(store.inputs, "Value", "VALUE"))
    link(_socket(count.outputs, "Point Count", "INT"), minus_one.inputs[0])
    link(minus_one.outputs[0], per_step.inputs[0])
    link(group_in.outputs[1], per_step.inputs[1])
    link(per_step.outputs[0], ceil.inputs[0])
    link(ceil.outputs[0], plus_one.inputs[0])
    link(store.outputs[0], resample.inputs["Curve"])
    link(plus_one.outputs[0], resample.inputs["Count"])
    link(group_in.outputs[1], stepped.inputs[0])
    link(stepped.outputs[0], _socket(switch.inputs, "Switch", "BOOLEAN"))
    link(store.outputs[0], _socket(switch.inputs, "False", "GEOMETRY"))
    link(resample.outputs[0], _socket(switch.inputs, "True", "GEOMETRY"))
    link(_socket(switch.outputs, "Output", "GEOMETRY"), to_mesh.inputs["Curve"])
    link(index.outputs[0], modulo.inputs[0])
    link(modulo.outputs[0], is_cut.inputs[0])
    link(to_mesh.outputs[0], split.inputs["Mesh"])
    link(is_cut.outputs[0], split.inputs["Selection"])
    link(split.outputs[0], to_curve.inputs["Mesh"])
    link(to_curve.outputs[0], set_radius.inputs["Curve"])
    link(_socket(stored.outputs, "Attribute", "VALUE"), set_radius.inputs["Radius"])
    link(group_in.outputs[0], mark.inputs["Geometry"])
    link(set_radius.outputs[0], join.inputs[0])
    link(mark.outputs[0], join.inputs[0])  # linked last, joined first (3.4 and 4.5): its materials are kept
    link(join.outputs[0], delete.inputs["Geometry"])
    link(_socket(marked.outputs, "Attribute", "BOOLEAN"), delete.inputs["Selection"])
    link(delete.outputs[0], removes[0].inputs["Geometry"])
    link(removes[0].outputs[0], removes[1].inputs["Geometry"])
    link(removes[1].outputs[0], group_out.inputs[0])
    return ng


def node_group():
    """The add-on's display node group, made once per file."""
    ng = bpy.data.node_groups.get(GROUP)
    return ng if ng is not None and ng.bl_idname == "GeometryNodeTree" else _new_group()


def point_step(points: int) -> int:
    """The display's point step for an object of `points` points: 1 (every point) up to DISPLAY_POINTS."""
    return max(1, -(-points // DISPLAY_POINTS))


def _input_identifier(ng, name: str) -> str:
    """How a modifier names the group input `name` (its identifier: "Input_2" in 3.x, "Socket_1" in 4.x)."""
    items = ng.interface.items_tree if hasattr(ng, "interface") else ng.inputs
    return next(i.identifier for i in items if getattr(i, "in_out", "INPUT") == "INPUT" and i.name == name)


def display_step(obj) -> int:
    """The point step an object's display modifier draws with."""
    modifier = obj.modifiers[MODIFIER]
    return int(modifier[_input_identifier(modifier.node_group, STEP)])


def add_to(obj) -> None:
    """Gives a Curves object the viewport-only display modifier (once)."""
    if obj.modifiers.get(MODIFIER) is not None:
        return
    made_group = bpy.data.node_groups.get(GROUP) is None
    modifier = None
    try:
        modifier = obj.modifiers.new(MODIFIER, "NODES")
        modifier.node_group = node_group()
        modifier[_input_identifier(modifier.node_group, STEP)] = point_step(len(obj.data.points))
        modifier.show_render = False
        modifier.show_viewport = True
    except Exception:
        if modifier is not None:
            obj.modifiers.remove(modifier)
        group = bpy.data.node_groups.get(GROUP)
        if made_group and group is not None and group.users == 0:
            bpy.data.node_groups.remove(group)
        raise


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
        modifier = obj.modifiers.get(MODIFIER) if obj.type == "CURVES" else None
        if modifier is not None and modifier.show_viewport != show:
            modifier.show_viewport = show


_OWNER = object()


def _subscribe() -> None:
    bpy.msgbus.clear_by_owner(_OWNER)
    for key in ((bpy.types.View3DShading, "type"), (bpy.types.RenderSettings, "engine")):
        bpy.msgbus.subscribe_rna(key=key, owner=_OWNER, args=(), notify=sync)


@bpy.app.handlers.persistent
def _load_post(*_args) -> None:
    _subscribe()  # a file load clears the message bus
    sync()


def register() -> None:
    _subscribe()
    if _load_post not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(_load_post)


def unregister() -> None:
    if _load_post in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_load_post)
    bpy.msgbus.clear_by_owner(_OWNER)
