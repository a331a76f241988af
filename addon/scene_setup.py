# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene setup for rendering yarns: a camera that frames them with a key and a rim light, and render
settings that work in every Blender the add-on supports. Used by the panel's "Frame for Render" and by
batch.py's demo scenes."""

from __future__ import annotations

import math

import bpy

#: Transparent bounces: the aggregated model's T lobe passes light through each ply as Cycles'
#: transparency, twice per ply (in and out) and per cloth layer; Cycles' default (8) darkens a 3-ply yarn
#: seen through another cloth layer.
MIN_TRANSPARENT_BOUNCES = 64


def has_denoiser() -> bool:
    """Whether this Blender's Cycles has OpenImageDenoise (bpy.app.build_options does not say)."""
    try:
        import _cycles
    except ImportError:
        return False
    return bool(getattr(_cycles, "with_openimagedenoise", False))


def render_settings(scene) -> list[str]:
    """Cycles, the denoiser off where this Blender has none (Debian's 3.4: F12 fails "Build without
    OpenImageDenoiser" otherwise) and enough transparent bounces for stacked cloth. Returns what it changed,
    for a report."""
    changed = []
    if scene.render.engine != "CYCLES":
        scene.render.engine = "CYCLES"
        changed.append("engine Cycles")
    cycles = scene.cycles
    if not has_denoiser():
        if cycles.use_denoising:
            cycles.use_denoising = False
            changed.append("denoising off (this Blender has no OpenImageDenoise)")
        if getattr(cycles, "use_preview_denoising", False):
            cycles.use_preview_denoising = False
    if cycles.transparent_max_bounces < MIN_TRANSPARENT_BOUNCES:
        cycles.transparent_max_bounces = MIN_TRANSPARENT_BOUNCES
        changed.append(f"{MIN_TRANSPARENT_BOUNCES} transparent bounces")
    return changed


def frame(scene, objects) -> None:
    """A camera looking down at 50 degrees at the objects' bounding box, a key and a rim light."""
    import mathutils

    lo = mathutils.Vector((math.inf,) * 3)
    hi = -lo
    for obj in objects:
        for corner in obj.bound_box:
            w = obj.matrix_world @ mathutils.Vector(corner)
            lo = mathutils.Vector(map(min, lo, w))
            hi = mathutils.Vector(map(max, hi, w))
    center, size = (lo + hi) / 2, max((hi - lo).length, 1e-6)
    cam = bpy.data.objects.new("NY camera", bpy.data.cameras.new("NY camera"))
    cam.data.lens = 50.0
    cam.data.clip_start = size * 1e-3
    cam.data.clip_end = size * 100.0
    direction = mathutils.Vector((0.0, -math.cos(math.radians(50)), math.sin(math.radians(50))))
    cam.location = center + direction * size * 1.6
    cam.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    for name, energy, d in (("NY key", 4.0, (0.4, -0.6, 0.7)), ("NY rim", 2.0, (-0.2, 0.7, -0.3))):
        light = bpy.data.objects.new(name, bpy.data.lights.new(name, "SUN"))
        light.data.energy = energy
        light.data.angle = math.radians(5.0)
        light.rotation_euler = (-mathutils.Vector(d)).to_track_quat("-Z", "Y").to_euler()
        scene.collection.objects.link(light)
    if scene.world is None:
        scene.world = bpy.data.worlds.new("NY world")
    scene.world.use_nodes = True
    bg = scene.world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
