# SPDX-License-Identifier: Apache-2.0
"""Renders a scene description (`neuralyarn cycles-scene --out SCENE.json`, docs/file_formats.md) in Blender
(the bpy wheel) through the add-on's builder (addon/scene_bpy.py): the neural yarn material with the add-on's
fallback instead of the native closure, the baselines and the diffuse check with Blender's own nodes. The
camera, pixel filter, integrator, lights and curves are the description's, as in the scene's Cycles XML:

    .venv/bin/python scripts/fallback_render.py SCENE.json OUT.exr --body osl|nodes [--samples N]
                     [--threads T] [--save-blend B.blend] [--node addon|builtin]
    .venv/bin/python scripts/fallback_render.py B.blend OUT.exr --open-blend

OUT.exr is in the standalone Cycles' handedness (Blender's image mirrored back). Exits 1 with one line on a
description it cannot read or a scene stock Blender cannot render.
"""
from __future__ import annotations

import argparse
import os
import sys

import bpy

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))


def load_addon():
    """The add-on of this checkout (addon/), registered, through addon/batch.py's own loader."""
    sys.path.insert(0, os.path.join(ROOT, "addon"))
    import batch  # addon/batch.py: bpy and the standard library only, no relative imports
    return batch.addon_module()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", help="the scene description (.json), or with --open-blend a .blend saved by --save-blend")
    ap.add_argument("out")
    ap.add_argument("--body", choices=("osl", "nodes"), default="nodes",
                    help="the neural yarn node's fallback body (default nodes)")
    ap.add_argument("--node", choices=("addon", "builtin"), default="addon",
                    help="the neural yarn material's node: the add-on's (default) or Blender's built-in one "
                         "(a patched Blender only)")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    ap.add_argument("--save-blend", help="also save the scene as this .blend (models and images packed)")
    ap.add_argument("--open-blend", action="store_true",
                    help="SCENE is a .blend: open it (the add-on registered) and render it as saved")
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]  # (blender -P ... -- args)
    args = ap.parse_args(argv)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ny = load_addon()
    if args.open_blend:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.scene))
        scene = bpy.context.scene
    else:
        try:
            desc = ny.scene_description.load_scene(args.scene)
            scene = ny.scene_bpy.build(desc, fallback=args.body.upper(), samples=args.samples)
            if args.node == "builtin":
                for node in list(ny.nodes.iter_nodes()):
                    ny.nodes.convert_node(node, "BUILTIN")
        except (ny.scene_description.SceneDescriptionError, ValueError) as e:
            raise SystemExit(str(e))
        if args.save_blend:
            bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save_blend))
    if args.threads > 0:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = args.threads
    print(f"fallback_render: Blender {bpy.app.version_string}, Cycles OSL {bpy.app.build_options.cycles_osl}")
    ny.scene_bpy.render_mirrored(scene, args.out)
    print(f"fallback_render: wrote {args.out} ({scene.cycles.samples} spp)")


if __name__ == "__main__":
    try:
        main()
    except SystemExit as e:
        if e.code not in (None, 0):
            print(f"fallback_render: {e.code}", file=sys.stderr)
            sys.stdout.flush()
            os._exit(1)
    sys.stdout.flush()
    os._exit(0)  # the bpy 4.5 wheel can hang at exit after a render (see tests/addon/install_smoke.py)
