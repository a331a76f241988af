# SPDX-License-Identifier: GPL-3.0-or-later
"""Batch renders from the command line (also what the tests run):

    blender -b [file.blend] --python-exit-code 1 -P <add-on dir>/batch.py -- --preset fleece --out fleece.png

With a .blend that has Curves objects, they get the preset's material (--keep-materials: only those without a
Neural Yarn material) and the file's camera, lights and settings are used. Without one (or --scene knit |
weave | bcc:FILE | leaf:FILE) a demo scene is built: the swatch, a camera that frames it, a key light in
front and a rim light behind (for the transmission), a dim grey world. The add-on is used if it is enabled,
else loaded from this file's directory. Every error is one line on stderr and exit code 1 (Blender needs
--python-exit-code 1 to pass it on).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys

import bpy

PACKAGE_NAMES = ("neural_yarn",)


class BatchError(RuntimeError):
    pass


def addon_module():
    """The Neural Yarn add-on package: enabled (legacy or extension), else loaded from this directory."""
    for name, module in list(sys.modules.items()):
        if (name in PACKAGE_NAMES or name.endswith(".neural_yarn")) and hasattr(module, "nodes") and \
                hasattr(module, "register"):
            if bpy.types.Node.bl_rna_get_subclass_py("ShaderNodeNeuralYarnBsdf") is not None:
                return module
    here = os.path.dirname(os.path.abspath(__file__))
    spec = importlib.util.spec_from_file_location("neural_yarn", os.path.join(here, "__init__.py"),
                                                  submodule_search_locations=[here])
    module = importlib.util.module_from_spec(spec)
    sys.modules["neural_yarn"] = module
    spec.loader.exec_module(module)
    module.register()
    return module


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors: one line and exit code 1, as every other error
        raise BatchError(message)


IMAGE_FORMATS = {".png": "PNG", ".exr": "OPEN_EXR", ".jpg": "JPEG", ".jpeg": "JPEG", ".tif": "TIFF", ".tiff": "TIFF"}
DEMO_SCENES = ("auto", "knit", "weave")


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = _Parser(prog="batch.py", description="Render yarns with the Neural Yarn add-on.")
    p.add_argument("--preset", default="fleece", help="fleece, silk, polyester, cotton or gabardine")
    p.add_argument("--model", help="a model file from `neuralyarn bake` instead of a preset")
    p.add_argument("--out", required=True, help="image to write (format from the extension: .png, .exr, .jpg)")
    p.add_argument("--scene", default="auto",
                   help="auto (the file's Curves objects, else a knit), knit, weave, bcc:FILE, leaf:FILE")
    p.add_argument("--plies", type=int, default=1,
                   help="demo scenes: twist each yarn into this many plies (Twist Plies), 1: one curve per yarn")
    p.add_argument("--keep-materials", action="store_true",
                   help="only give the material to Curves objects without a Neural Yarn material")
    p.add_argument("--fallback", default="auto", choices=("auto", "osl", "nodes"))
    p.add_argument("--osl", action="store_true", help="turn on Open Shading Language (CPU) if this Blender has it")
    p.add_argument("--resolution", type=int, nargs="+", default=None, metavar="PX", help="width [height]")
    p.add_argument("--samples", type=int, default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=0, help="0: all cores")
    return p.parse_args(argv)


def _check(args) -> None:
    if args.model is None and args.preset not in ("fleece", "silk", "polyester", "cotton", "gabardine"):
        raise BatchError(f"unknown preset '{args.preset}' (fleece, silk, polyester, cotton, gabardine)")
    if args.resolution is not None and not (1 <= len(args.resolution) <= 2 and
                                            all(1 <= r <= 16384 for r in args.resolution)):
        raise BatchError("--resolution takes one or two sizes between 1 and 16384")
    if not 1 <= args.plies <= 16:
        raise BatchError("--plies must be between 1 and 16")
    if args.samples is not None and not 1 <= args.samples <= 1 << 20:
        raise BatchError("--samples must be between 1 and 1048576")
    out_dir = os.path.dirname(os.path.abspath(args.out)) or "."
    if not os.path.isdir(out_dir):
        raise BatchError(f"--out: the directory '{out_dir}' does not exist")
    ext = os.path.splitext(args.out)[1].lower()
    if ext not in IMAGE_FORMATS:
        raise BatchError(f"--out: unknown image extension '{ext}' ({', '.join(IMAGE_FORMATS)})")
    if args.scene not in DEMO_SCENES and not args.scene.startswith(("bcc:", "leaf:")):
        raise BatchError(f"--scene: unknown scene '{args.scene}' (auto, knit, weave, bcc:FILE, leaf:FILE)")


def _demo_geometry(kind: str):
    try:
        return _make_demo_geometry(kind)
    except RuntimeError as e:  # an operator's error report (bpy.ops raises it in background mode)
        raise BatchError(f"--scene {kind}: the yarns could not be made: {str(e).strip()}") from None


def _make_demo_geometry(kind: str):
    ctx = bpy.context
    if kind == "knit":
        r = bpy.ops.neural_yarn.add_knit(rows=6, stitches=6, preset="NONE")
    elif kind == "weave":
        r = bpy.ops.neural_yarn.add_weave(weave="twill", warps=12, wefts=12, preset="NONE")
    elif kind.startswith("bcc:"):
        r = bpy.ops.neural_yarn.import_bcc(filepath=os.path.abspath(kind[4:]), preset="NONE")
    elif kind.startswith("leaf:"):
        r = bpy.ops.neural_yarn.import_leaf(filepath=os.path.abspath(kind[5:]), preset="NONE")
    else:  # (_check refused other names before anything was built)
        raise BatchError(f"--scene: unknown scene '{kind}'")
    if "FINISHED" not in r:
        raise BatchError(f"--scene {kind}: the yarns could not be made (see the error above)")
    return [ctx.active_object]


def run(argv: list[str]) -> str:
    args = parse_args(argv)
    _check(args)
    if not bpy.data.filepath:
        # No .blend given: a demo scene from an empty file, not the startup file's cube.
        bpy.ops.wm.read_factory_settings(use_empty=True)
    ny = addon_module()
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    if args.osl:
        scene.cycles.device = "CPU"
        scene.cycles.shading_system = True
    yarns = [o for o in scene.objects if o.type == "CURVES"]
    demo = args.scene != "auto" or not yarns
    if demo:
        yarns = _demo_geometry("knit" if args.scene == "auto" else args.scene)
        if args.plies > 1:
            r = bpy.ops.neural_yarn.make_plies(plies=args.plies, preset="KEEP")
            if "FINISHED" not in r:
                raise BatchError("--plies: the plies could not be made (see the error above)")
            yarns = [bpy.context.active_object]
    if args.model:
        try:
            text = ny.nodes.pack_model_file(args.model)
        except ny.model_io.ModelFileError as e:
            raise BatchError(str(e)) from None
        mat, node = ny.nodes.make_material("Neural Yarn " + os.path.basename(args.model), model_text=text)
    else:
        mat = ny.operators.preset_material(args.preset)
        node = next(n for n in mat.node_tree.nodes if n.bl_idname == ny.nodes.NODE_IDNAME)
    node.fallback = args.fallback.upper()
    if node.error:
        raise BatchError(node.error)
    for obj in yarns:
        has = obj.active_material is not None and obj.active_material.node_tree is not None and any(
            n.bl_idname == ny.nodes.NODE_IDNAME for n in obj.active_material.node_tree.nodes)
        if args.keep_materials and has:
            continue
        obj.data.materials.clear()
        obj.data.materials.append(mat)
    if demo or scene.camera is None:
        ny.scene_setup.frame(scene, yarns)
    if args.resolution:
        scene.render.resolution_x = args.resolution[0]
        scene.render.resolution_y = args.resolution[-1]
        scene.render.resolution_percentage = 100
    if args.samples:
        scene.cycles.samples = args.samples
        scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = args.seed
    ny.scene_setup.render_settings(scene)
    scene.cycles.use_denoising = False  # batch renders are measured, not denoised
    scene.render.threads_mode = "FIXED" if args.threads > 0 else "AUTO"
    if args.threads > 0:
        scene.render.threads = args.threads
    out = os.path.abspath(args.out)
    scene.render.image_settings.file_format = IMAGE_FORMATS[os.path.splitext(out)[1].lower()]
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    if not os.path.isfile(out):
        raise BatchError(f"the render did not write '{out}'")
    print(f"neural_yarn batch: wrote {out} ({len(yarns)} yarn object(s), material '{mat.name}', "
          f"fallback {node.built})")
    return out


def main() -> int:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    try:
        run(argv)
    except BatchError as e:
        print(f"neural_yarn batch: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    code = main()
    if not bpy.app.binary_path:
        # The bpy wheel (Blender as a Python module: `python batch.py -- ...`) can hang at interpreter exit.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    if code:
        sys.exit(code)
