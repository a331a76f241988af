# SPDX-License-Identifier: Apache-2.0
"""What the add-on's viewport display costs on a heavy garment (issue 20, decisions D43): a knit of
ROWS x STITCHES stitches twisted into 3 plies (Twist Plies' defaults), its display modifier evaluated and
drawn by Workbench (Solid mode's engine; the modifier turned on for that render so that it draws what the
viewport draws) at every point (step 1) and at the step the add-on chose for it.

    xvfb-run -a .venv/bin/python scripts/bench_viewport_display.py [--rows 60] [--stitches 60]

Under xvfb Workbench draws with Mesa's software renderer on the CPU: the draw times are this machine's, not
a GPU's; the points drawn and the evaluation times are what the modifier itself costs. A benchmark: prints,
never a test. Ends with os._exit (the bpy wheel can hang at exit).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import bpy

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", type=int, default=60)
    ap.add_argument("--stitches", type=int, default=60)
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(ROOT, "addon"))
    import batch  # the add-on's own loader

    addon = batch.addon_module()
    vd = addon.viewport_display
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.neural_yarn.add_knit(rows=args.rows, stitches=args.stitches, preset="fleece")
    t = time.perf_counter()
    bpy.ops.neural_yarn.make_plies(preset="KEEP")
    plies_s = time.perf_counter() - t
    obj = bpy.context.active_object
    scene = bpy.context.scene
    addon.scene_setup.frame(scene, [obj])
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.hair_type = "STRIP"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1280, 720, 100
    modifier = vd.display_modifier(obj)
    auto = vd.display_step(obj)
    print(f"bench_viewport_display: {args.rows} x {args.stitches} stitches, 3 plies: {len(obj.data.points)} "
          f"points in {len(obj.data.curves)} curves (Twist Plies {plies_s:.1f} s); Blender {bpy.app.version_string}")
    print("| display | points in it | curves | points drawn | evaluation s | Workbench draw s (software) |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        scene.render.filepath = os.path.join(tmp, "w.png")
        for label, step, on in (("whole curves (no modifier)", 1, False), ("pieces, step 1", 1, True),
                                (f"pieces, step {auto} (the add-on's)", auto, True)):
            vd.set_display_step(obj, step)
            modifier.show_viewport = on
            obj.update_tag()
            t = time.perf_counter()
            data = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
            eval_s = time.perf_counter() - t
            points, pieces = len(data.points), len(data.curves)
            modifier.show_render = on
            t = time.perf_counter()
            bpy.ops.render.render(write_still=True)
            draw_s = time.perf_counter() - t
            modifier.show_render = False
            drawn = pieces * 2 ** (3 + scene.render.hair_subdiv)  # what the viewport draws per curve
            print(f"| {label} | {points} | {pieces} | {drawn} | {eval_s:.2f} | {draw_s:.2f} |")
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
