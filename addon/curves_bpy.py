# SPDX-License-Identifier: GPL-3.0-or-later
"""YarnCurves (geometry/) into Blender: one Curves (hair) object per yarn set, which Cycles renders as
thick round curves with a radius per point, the shape the neural yarn model is made for.

Closed loops are closed by repeating their first point (Cycles' curves have no cyclic flag); everything is
computed before any data block is made, so a failure leaves the file unchanged.
"""

from __future__ import annotations

import numpy as np

import bpy

from . import viewport_display
from .geometry import GeometryError, YarnCurve, validate


def _arrays(curves: list[YarnCurve]) -> tuple[list[int], np.ndarray, np.ndarray]:
    sizes, pts, rad = [], [], []
    for c in curves:
        P, R = c.points, c.radius
        if c.cyclic:
            P = np.concatenate([P, P[:1]])
            R = np.concatenate([R, R[:1]])
        sizes.append(len(P))
        pts.append(P)
        rad.append(R)
    return sizes, np.concatenate(pts).astype(np.float32), np.concatenate(rad).astype(np.float32)


def _new_curves_data(name: str, sizes: list[int], positions: np.ndarray, radii: np.ndarray):
    """A Curves data block with the given curve sizes, positions and per-point radius."""
    data = bpy.data.hair_curves.new(name)
    try:
        if hasattr(data, "add_curves"):  # Blender 4.0+
            data.add_curves(sizes)
        else:
            bpy.data.hair_curves.remove(data)
            return _new_curves_data_by_conversion(name, sizes, positions, radii)
        data.position_data.foreach_set("vector", positions.ravel())
        attr = data.attributes.get("radius") or data.attributes.new("radius", "FLOAT", "POINT")
        attr.data.foreach_set("value", radii)
    except Exception:
        bpy.data.hair_curves.remove(data)
        raise
    return data


def _new_curves_data_by_conversion(name: str, sizes: list[int], positions: np.ndarray, radii: np.ndarray):
    """Blender 3.4-3.6 cannot resize a Curves data block from Python; there, the curves are made as a legacy
    poly Curve (per-point radius) on a temporary object in a temporary scene, converted with
    object.convert(target='CURVES') (which keeps positions and radius as the 'radius' attribute), and the
    temporary data removed, so that nothing but the new Curves data block is left in the file."""
    legacy = bpy.data.curves.new(name, "CURVE")
    legacy.dimensions = "3D"
    start = 0
    for n in sizes:
        spline = legacy.splines.new("POLY")
        spline.points.add(n - 1)
        co = np.ones((n, 4), dtype=np.float32)
        co[:, :3] = positions[start:start + n]
        spline.points.foreach_set("co", co.ravel())
        spline.points.foreach_set("radius", radii[start:start + n])
        start += n
    # The conversion runs on the selected objects of the current view layer: the temporary object is linked
    # to the scene's master collection and made the only selected one; the user's selection and active
    # object are restored afterwards.
    scene = bpy.context.scene
    view_layer = bpy.context.view_layer
    selected = [o for o in view_layer.objects if o.select_get(view_layer=view_layer)]
    active = view_layer.objects.active
    obj = bpy.data.objects.new(name, legacy)
    ok = False
    try:
        scene.collection.objects.link(obj)
        for o in selected:
            o.select_set(False, view_layer=view_layer)
        obj.select_set(True, view_layer=view_layer)
        view_layer.objects.active = obj
        result = bpy.ops.object.convert(target="CURVES")
        if "FINISHED" not in result or obj.type != "CURVES":
            raise GeometryError(f"{name}: this Blender could not convert the curves to a Curves object")
        data = obj.data
        n = len(data.points)
        got = np.empty(n, dtype=np.float32)
        data.attributes["radius"].data.foreach_get("value", got)
        if n != len(radii) or not np.allclose(got, radii, rtol=1e-5, atol=0.0):
            raise GeometryError(f"{name}: the conversion to a Curves object changed the points or radii")
        ok = True
        return data  # no user until the caller makes its object; orphans live until the file is saved
    finally:
        converted = obj.data if obj.type == "CURVES" else None
        bpy.data.objects.remove(obj)
        # Removed whatever its user count: Blender 3.4's conversion leaves a user on it, and it was saved
        # with every object made this way.
        bpy.data.curves.remove(legacy)
        if not ok and converted is not None and converted.users == 0:
            bpy.data.hair_curves.remove(converted)
        view_layer.update()  # re-sync the view layer's bases after the removal (3.x leaves stale ones)
        for o in selected:
            o.select_set(True, view_layer=view_layer)
        view_layer.objects.active = active


def create_curves_object(context, name: str, curves: list[YarnCurve], *, material=None, location=None):
    """A new Curves object holding `curves`, linked to the active collection and selected, drawn in the
    viewport through every point (viewport_display). Raises GeometryError (nothing is created) for invalid
    curves."""
    if not curves:
        raise GeometryError(f"{name}: no curves to create")
    validate(curves, source=name)
    sizes, positions, radii = _arrays(curves)
    if not (np.isfinite(positions).all() and np.isfinite(radii).all()):
        raise GeometryError(f"{name}: coordinates or radii overflow single precision")
    data = _new_curves_data(name, sizes, positions, radii)
    try:
        if material is not None:
            data.materials.append(material)
        obj = bpy.data.objects.new(name, data)
    except Exception:
        bpy.data.hair_curves.remove(data)
        raise
    try:
        viewport_display.add_to(obj)
    except Exception:
        remove_curves_object(obj)
        raise
    if location is not None:
        obj.location = location
    collection = context.collection if context is not None and context.collection is not None \
        else bpy.context.scene.collection
    collection.objects.link(obj)
    if context is not None and getattr(context, "view_layer", None) is not None:
        for other in context.view_layer.objects:  # (not .selected: it can hold stale entries in 3.x)
            if other is not None and other.select_get():
                other.select_set(False)
        obj.select_set(True)
        context.view_layer.objects.active = obj
    return obj


def remove_curves_object(obj) -> None:
    """Removes an object made by create_curves_object and its Curves data."""
    data = obj.data
    bpy.data.objects.remove(obj)
    if data is not None and data.users == 0:
        bpy.data.hair_curves.remove(data)


def curve_offsets(obj) -> np.ndarray:
    """Where each curve of a Curves object starts in its points, and their count last (len(curves) + 1 entries)."""
    offsets = np.empty(len(obj.data.curves) + 1, dtype=np.int32)
    obj.data.curve_offset_data.foreach_get("value", offsets)
    return offsets


def read_curves_object(obj) -> list[YarnCurve]:
    """The curves of a Curves object as YarnCurves (world space), e.g. to twist plies around them."""
    if obj is None or obj.type != "CURVES":
        raise GeometryError("select a Curves object (yarn curves made or imported by Neural Yarn)")
    data = obj.data
    n = len(data.points)
    if n == 0:
        raise GeometryError(f"'{obj.name}' has no curves")
    pos = np.empty(n * 3, dtype=np.float32)
    data.position_data.foreach_get("vector", pos)
    pos = pos.reshape(n, 3).astype(np.float64)
    rad = np.full(n, 0.01)
    attr = data.attributes.get("radius")
    if attr is not None:
        r = np.empty(n, dtype=np.float32)
        attr.data.foreach_get("value", r)
        rad = r.astype(np.float64)
    M = np.array(obj.matrix_world)
    pos = pos @ M[:3, :3].T + M[:3, 3]
    scale = float(np.cbrt(abs(np.linalg.det(M[:3, :3])))) or 1.0
    out = []
    offsets = curve_offsets(obj)
    for a, b in zip(offsets[:-1], offsets[1:]):
        P, R = pos[a:b], rad[a:b] * scale
        cyclic = len(P) > 3 and np.allclose(P[0], P[-1])
        if cyclic:
            P, R = P[:-1], R[:-1]
        out.append(YarnCurve(P, R, cyclic))
    return out
