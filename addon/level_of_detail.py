# SPDX-License-Identifier: GPL-3.0-or-later
"""The level of detail of Curves objects from the scene camera (bpy side of geometry/lod.py, D27)."""

from __future__ import annotations

import numpy as np

from .geometry import lod, ply_center_distance
from .geometry.lod import YARN_MODEL_PLIES, YARN_MODEL_PLY_TWIST


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
