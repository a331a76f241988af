# SPDX-License-Identifier: Apache-2.0
"""What building a knit's geometry costs in the add-on at each level of detail (issue 18: "geometry for a
40 x 40-stitch garment at yarn level builds in the add-on in <= 5 s; ply level: report it"): a knitted swatch of
ROWS x STITCHES stitches with a preset (Knitted Swatch), then Apply Level of Detail with the scene forced to one
level (surface, yarns, plies: 3 plies), each on a fresh swatch; the wall time of each step, the curves and points (or
vertices) it draws, and the level the add-on reports. Runs in the bpy wheel (no window: no progress bar is drawn).

    .venv/bin/python scripts/bench_lod_build.py [--rows 40] [--stitches 40] [--repeats 3]

A benchmark: prints, never a test. Ends with os._exit (the bpy wheel can hang at exit).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import bpy

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))


def build(addon, rows: int, stitches: int, level: str) -> dict:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    t0 = time.perf_counter()
    bpy.ops.neural_yarn.add_knit(rows=rows, stitches=stitches, preset="fleece")
    knit_s = time.perf_counter() - t0
    knit = bpy.context.active_object
    scene = bpy.context.scene
    addon.scene_setup.frame(scene, [knit])
    bpy.context.view_layer.update()
    scene.neural_yarn_lod = level
    t0 = time.perf_counter()
    assert bpy.ops.neural_yarn.apply_lod() == {"FINISHED"}
    lod_s = time.perf_counter() - t0
    shown = [o for o in scene.objects if o.type in ("CURVES", "MESH") and not o.hide_render]
    return {"knit_s": knit_s, "lod_s": lod_s, "chosen": knit.neural_yarn.chosen,
            "curves": sum(len(o.data.curves) for o in shown if o.type == "CURVES"),
            "points": sum(len(o.data.points if o.type == "CURVES" else o.data.vertices) for o in shown)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", type=int, default=40)
    ap.add_argument("--stitches", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(ROOT, "addon"))
    import batch  # the add-on's own loader

    addon = batch.addon_module()
    print(f"{args.rows} x {args.stitches} stitches, fleece, {args.repeats} repeats (seconds: best / median)")
    for level in ("SURFACE", "YARNS", "PLIES"):
        runs = [build(addon, args.rows, args.stitches, level) for _ in range(args.repeats)]
        knit = sorted(r["knit_s"] for r in runs)
        lod = sorted(r["lod_s"] for r in runs)
        total = sorted(r["knit_s"] + r["lod_s"] for r in runs)
        r = runs[0]
        print(f"{level.lower():6s}: swatch {knit[0]:.2f} / {knit[len(knit) // 2]:.2f} s, apply level "
              f"{lod[0]:.2f} / {lod[len(lod) // 2]:.2f} s, together {total[0]:.2f} / {total[len(total) // 2]:.2f} s; "
              f"rendered {r['curves']} curves, {r['points']} points or vertices; chosen: {r['chosen']}")
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
