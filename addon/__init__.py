# SPDX-License-Identifier: GPL-3.0-or-later
"""Neural Yarn: cloth from yarn curves with the neural yarn appearance model (Soh & Montazeri, EGSR 2024).

A Blender extension (blender_manifest.toml, 4.2+) that also loads as a legacy add-on (bl_info, 3.4+).
Modules: geometry/ (importers and generators, no bpy), model_io (model files, no bpy), fallback/ (the
fallback's tables, lobes and OSL shader, no bpy), resources (shipped files), curves_bpy (Curves objects),
viewport_display (how the viewport draws them), fallback_nodes + nodes (the Neural Yarn BSDF node),
scene_setup (camera, lights, render settings), operators, ui, batch (command-line renders), scene_description
(scene description files, no bpy) + scene_bpy (their Blender builder: the evaluation's scenes in Blender).
"""

bl_info = {
    "name": "Neural Yarn",
    "author": "neuralyarn developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar > Neural Yarn; Add > Knitted/Woven Swatch; File > Import",
    "description": "Cloth from yarn curves with the neural yarn appearance model (Soh & Montazeri 2024)",
    "category": "Material",
}

if "bpy" in locals():  # script reload (F8 / Reload Scripts)
    import importlib

    for _m in (fallback.lobes, fallback.schema, fallback.osl, model_io, resources, viewport_display,  # noqa: F821
               curves_bpy, fallback_nodes, nodes, level_of_detail, scene_setup, scene_description, scene_bpy,  # noqa: F821
               operators, ui):  # noqa: F821
        importlib.reload(_m)

import bpy  # noqa: E402

from . import (curves_bpy, fallback_nodes, level_of_detail, model_io, nodes, operators, resources,  # noqa: E402,F401
               scene_bpy, scene_description, scene_setup, ui, viewport_display)

_MODULES = (viewport_display, nodes, level_of_detail, operators, ui)


def register():
    for m in _MODULES:
        m.register()


def unregister():
    for m in reversed(_MODULES):
        m.unregister()
