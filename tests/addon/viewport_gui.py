# SPDX-License-Identifier: Apache-2.0
"""Blender's interface (not -b), under xvfb-run: a 3D viewport switched to Rendered shading with Cycles turns
the yarns' display modifiers off through the message bus, and back to Solid turns them on (issue 20, C9):

    xvfb-run -a blender --factory-startup --python-exit-code 1 -P tests/addon/viewport_gui.py

Prints "viewport_gui: ok" and exits 0, or names the failed step and exits 1.
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir, "addon"))
import batch  # noqa: E402  (the add-on's own loader)

addon = batch.addon_module()


def view3d():
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                return window, area.spaces.active
    raise RuntimeError("no 3D viewport")


def finish(message, code):
    print(f"viewport_gui: {message}", flush=True)
    os._exit(code)


STEPS = []  # (what to do, what show_viewport must then be)


def step():
    """Runs from a timer, so that the event loop handles the message bus between the steps."""
    try:
        knit = bpy.data.objects.get("knit")
        if knit is None:
            window, _ = view3d()
            with bpy.context.temp_override(window=window):
                bpy.ops.neural_yarn.add_knit(rows=2, stitches=2, preset="NONE")
            bpy.context.view_layer.objects.active.name = "knit"
            window.scene.render.engine = "CYCLES"
            STEPS.extend([("RENDERED", False), ("SOLID", True), ("MATERIAL", True), ("RENDERED", False)])
            return 0.2
        modifier = knit.modifiers[addon.viewport_display.MODIFIER]
        if getattr(step, "expect", None) is not None:
            shading, expected = step.expect
            if modifier.show_viewport != expected:
                finish(f"after {shading}: show_viewport {modifier.show_viewport}, expected {expected}", 1)
        if not STEPS:
            # Eevee as the engine: the viewport draws the curves again, so the pieces are back.
            window, space = view3d()
            if space.shading.type == "RENDERED" and window.scene.render.engine == "CYCLES":
                window.scene.render.engine = "BLENDER_EEVEE_NEXT" if bpy.app.version >= (4, 2) else "BLENDER_EEVEE"
                step.expect = ("RENDERED with Eevee", True)
                return 0.2
            finish("ok", 0)
        shading, expected = STEPS.pop(0)
        view3d()[1].shading.type = shading
        step.expect = (shading, expected)
        return 0.2
    except Exception as e:  # noqa: BLE001 - any failure ends the test with its message
        finish(f"{type(e).__name__}: {e}", 1)


bpy.app.timers.register(step, first_interval=0.5)
bpy.app.timers.register(lambda: finish("timed out", 1), first_interval=60.0)
