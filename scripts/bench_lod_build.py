# SPDX-License-Identifier: Apache-2.0
"""What building a knit's geometry costs in the add-on at each level of detail (issue 18: "geometry for a
40 x 40-stitch garment at yarn level builds in the add-on in <= 5 s; ply level: report it"): a knitted swatch of
ROWS x STITCHES stitches with a preset (Knitted Swatch), then Apply Level of Detail with the scene forced to one
level (surface, yarns, plies: 3 plies), each on a fresh swatch; the wall time of each step, the curves and points (or
vertices) it draws, and the level the add-on reports. Runs in the bpy wheel (no window: no progress bar is drawn).

With --receding, what splitting one object pays (D67): the swatch seen from a camera low over it (its courses
recede from ~ELEVATION degrees), Auto applied once as one object (the whole swatch at the level of its nearest
course: plies), once split by each course's footprint and once forced to yarns; build time, curves and points
drawn, and with --render-spp the render time of each in the bpy wheel's Cycles (the node fallback, 2 threads) and
the mean colour of the split's and the yarns' images against the plies' over the frame and its upper and lower
halves (where the far and the near courses are).

    .venv/bin/python scripts/bench_lod_build.py [--rows 40] [--stitches 40] [--repeats 3]
    .venv/bin/python scripts/bench_lod_build.py --receding [--elevation 12] [--size 640 360] [--render-spp 16]

A benchmark: prints, never a test. Ends with os._exit (the bpy wheel can hang at exit).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import bpy
import numpy as np

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


def receding(addon, rows: int, stitches: int, mode: str, a) -> dict:
    """The swatch under a camera low over it: Auto applied whole (mode "plies": as before D67, the level of its
    nearest course), split ("split") or the whole swatch at the yarn level ("yarns")."""
    import mathutils

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.neural_yarn.add_knit(rows=rows, stitches=stitches, preset="fleece")
    knit = bpy.context.active_object
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = a.size
    scene.render.resolution_percentage = 100
    addon.scene_setup.frame(scene, [knit])
    lo = mathutils.Vector([min((knit.matrix_world @ mathutils.Vector(c))[i] for c in knit.bound_box) for i in range(3)])
    hi = mathutils.Vector([max((knit.matrix_world @ mathutils.Vector(c))[i] for c in knit.bound_box) for i in range(3)])
    centre, size = (lo + hi) / 2, (hi - lo).length
    e = math.radians(a.elevation)
    direction = mathutils.Vector((0.0, -math.cos(e), math.sin(e)))
    cam = scene.camera
    cam.location = centre + direction * size * a.distance
    cam.rotation_euler = (-direction).to_track_quat("-Z", "Y").to_euler()
    bpy.context.view_layer.update()
    knit.neural_yarn.split = mode == "split"
    scene.neural_yarn_lod = "YARNS" if mode == "yarns" else "OBJECT"
    t0 = time.perf_counter()
    assert bpy.ops.neural_yarn.apply_lod() == {"FINISHED"}
    lod_s = time.perf_counter() - t0
    ld = addon.level_of_detail
    points, ply_radius = ld.ply_radii(knit, knit.neural_yarn.plies)
    px = addon.geometry.lod.curve_ply_pixels(points, np.diff(addon.curves_bpy.curve_offsets(knit)), ply_radius,
                                             ld.view_of(scene))
    shown = [o for o in scene.objects if o.type == "CURVES" and not o.hide_render]
    out = {"px": (float(np.nanmin(px)), float(np.nanmax(px))), "lod_s": lod_s, "chosen": knit.neural_yarn.chosen,
           "curves": sum(len(o.data.curves) for o in shown), "points": sum(len(o.data.points) for o in shown)}
    if a.render_spp:
        scene.render.engine = "CYCLES"
        scene.cycles.device, scene.cycles.shading_system = "CPU", False
        scene.cycles.samples = a.render_spp
        scene.cycles.use_adaptive_sampling = scene.cycles.use_denoising = False
        scene.cycles.seed = 1
        scene.render.threads_mode, scene.render.threads = "FIXED", 2
        scene.render.image_settings.file_format = "OPEN_EXR"
        path = os.path.join(a.out, f"receding_{mode}.exr")
        scene.render.filepath = path
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        out["render_s"] = time.perf_counter() - t0
        img = bpy.data.images.load(path)
        px = np.empty(len(img.pixels), dtype=np.float32)
        img.pixels.foreach_get(px)
        out["image"] = px.reshape(a.size[1], a.size[0], 4)
        bpy.data.images.remove(img)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", type=int, default=40)
    ap.add_argument("--stitches", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--receding", action="store_true", help="what splitting one object pays (D67)")
    ap.add_argument("--elevation", type=float, default=12.0, help="--receding: the camera's degrees over the swatch")
    ap.add_argument("--distance", type=float, default=0.6, help="--receding: camera distance in swatch diagonals")
    ap.add_argument("--size", type=int, nargs=2, default=(640, 360), help="--receding: render size")
    ap.add_argument("--render-spp", type=int, default=0, help="--receding: also render each (samples)")
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "bench_lod_split"), help="--receding: images")
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(ROOT, "addon"))
    import batch  # the add-on's own loader

    addon = batch.addon_module()
    if args.receding:
        os.makedirs(args.out, exist_ok=True)
        print(f"{args.rows} x {args.stitches} stitches, fleece, camera {args.elevation:g} deg over the swatch, "
              f"{args.size[0]} x {args.size[1]}, {args.repeats} repeats (seconds: best / median)")
        runs = {}
        for mode in ("plies", "split", "yarns"):
            rs = [receding(addon, args.rows, args.stitches, mode, args) for _ in range(args.repeats)]
            runs[mode] = rs[0]
            lod_t = sorted(r["lod_s"] for r in rs)
            line = (f"{mode}: apply level {lod_t[0]:.2f} / {lod_t[len(lod_t) // 2]:.2f} s; "
                    f"rendered {rs[0]['curves']} curves, {rs[0]['points']} points; courses' plies "
                    f"{rs[0]['px'][1]:.2f} to {rs[0]['px'][0]:.2f} px")
            if args.render_spp:
                ren = sorted(r["render_s"] for r in rs)
                line += f"; render {ren[0]:.2f} / {ren[len(ren) // 2]:.2f} s at {args.render_spp} spp"
            print(line + f"; chosen: {rs[0]['chosen']}")
        if args.render_spp:
            whole = runs["plies"]["image"]
            h = whole.shape[0]  # rows from the bottom (Blender's pixel order): the near courses first
            for mode in ("split", "yarns"):
                for name, rows in (("frame", slice(0, h)), ("upper half (far)", slice(h // 2, h)),
                                   ("lower half (near)", slice(0, h // 2))):
                    a_ = whole[rows, :, :3].reshape(-1, 3).mean(axis=0)
                    b_ = runs[mode]["image"][rows, :, :3].reshape(-1, 3).mean(axis=0)
                    print(f"{mode} against plies, {name}: mean colour " +
                          " / ".join(f"{(y / x - 1) * 100:+.1f}" for x, y in zip(a_, b_)) + " % (R / G / B)")
            # The step at the boundary: the split's luminance over the plies' in bands of rows, far to near (bands
            # where the whole frame is sky, the same in both, are left out).
            lum = np.array([0.2126, 0.7152, 0.0722])
            band = max(h // 24, 1)
            steps = []
            for r0 in range(h - band, -1, -band):
                a_, b_ = whole[r0:r0 + band, :, :3] @ lum, runs["split"]["image"][r0:r0 + band, :, :3] @ lum
                if abs(b_.mean() / a_.mean() - 1) > 1e-6:
                    steps.append(f"{(b_.mean() / a_.mean() - 1) * 100:+.1f}")
            print(f"split against plies, luminance in bands of {band} rows, far to near, where they differ: "
                  + " ".join(steps) + " %")
        sys.stdout.flush()
        os._exit(0)
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
