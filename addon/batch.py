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
import re
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
    p.add_argument("--preset", default="fleece", help="a shipped preset (fleece, silk, ...: the core's preset list)")
    p.add_argument("--model", help="a model file from `neuralyarn bake` instead of a preset")
    p.add_argument("--out", required=True, help="image to write (format from the extension: .png, .exr, .jpg)")
    p.add_argument("--scene", default="auto",
                   help="auto (the file's Curves objects, else a knit), knit, weave, bcc:FILE, leaf:FILE")
    p.add_argument("--plies", type=int, default=1,
                   help="demo scenes: twist each yarn into this many plies (Twist Plies), 1: one curve per yarn")
    p.add_argument("--lod", default=None, choices=("auto", "fibers", "plies", "yarns", "surface"),
                   help="the level of detail (auto: from the camera, docs/decisions.md D27) of demo scenes with --plies "
                        "(default auto) and of the file's yarn objects that had a level applied (default: their own); "
                        "one line 'level of detail: <object>: <level>' per object")
    p.add_argument("--keep-materials", action="store_true",
                   help="only give the material to Curves objects without a Neural Yarn material")
    p.add_argument("--fallback", default="auto", choices=("auto", "osl", "nodes"))
    p.add_argument("--osl", action="store_true", help="turn on Open Shading Language (CPU) if this Blender has it")
    p.add_argument("--resolution", type=int, nargs="+", default=None, metavar="PX", help="width [height]")
    p.add_argument("--samples", type=int, default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=0, help="0: all cores")
    p.add_argument("--blend", help="open this .blend first (the bpy wheel has no file argument)")
    p.add_argument("--frame", type=int, help="render this frame of the scene")
    p.add_argument("--frames", help="farm mode: render these frames (1-240, 1,5,9-12) as Dask tasks, one image "
                                    "each; '#' in --out is the zero-padded frame number")
    p.add_argument("--scheduler", help="farm mode: a Dask scheduler's address (default: a local cluster)")
    p.add_argument("--workers", type=int, default=2, help="farm mode: local cluster workers (default 2)")
    p.add_argument("--farm-python", help="farm mode inside Blender: a Python with Dask to drive the farm")
    return p.parse_args(argv)


def parse_frames(spec: str) -> list[int]:
    """'1-240', '1,5,9-12' -> the frame numbers, in order, without repeats."""
    frames: list[int] = []
    seen: set[int] = set()
    for part in spec.split(","):
        m = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*)?", part)
        if not m:
            raise BatchError(f"--frames: '{part}' is not a frame or a range (1-240, 1,5,9-12)")
        a, b = int(m.group(1)), int(m.group(2) or m.group(1))
        if b < a or b - a > 100000:
            raise BatchError(f"--frames: bad range '{part}'")
        frames += [f for f in range(a, b + 1) if f not in seen]
        seen.update(range(a, b + 1))
    return frames


def frame_path(out: str, frame: int) -> str:
    """--out for one frame: its run of '#' becomes the zero-padded frame number (as Blender's output path),
    else _NNNN goes before the extension."""
    m = re.search(r"#+", os.path.basename(out))
    if m:
        head = out[: len(out) - len(os.path.basename(out))]
        name = os.path.basename(out)
        return head + name[: m.start()] + f"{frame:0{len(m.group(0))}d}" + name[m.end():]
    stem, ext = os.path.splitext(out)
    return f"{stem}_{frame:04d}{ext}"


def _check(args) -> None:
    if args.resolution is not None and not (1 <= len(args.resolution) <= 2 and
                                            all(1 <= r <= 16384 for r in args.resolution)):
        raise BatchError("--resolution takes one or two sizes between 1 and 16384")
    if args.blend is not None and not os.path.isfile(args.blend):
        raise BatchError(f"--blend: '{args.blend}' does not exist")
    if args.frames is not None:
        parse_frames(args.frames)
        if args.frame is not None:
            raise BatchError("--frame renders one frame, --frames many: give one of them")
        if not 1 <= args.workers <= 1024:
            raise BatchError("--workers must be between 1 and 1024")
    elif args.scheduler is not None:
        raise BatchError("--scheduler needs --frames (farm mode)")
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


def _frame_argv(argv: list[str]) -> list[str]:
    """The arguments of one frame's render: the farm's own options dropped (their values too)."""
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        name = a.split("=", 1)[0]
        if name in ("--frames", "--scheduler", "--workers", "--farm-python", "--out"):
            skip = "=" not in a
            continue
        out.append(a)
    return out


def _farm_python(args) -> str:
    """The Python that drives the farm: --farm-python, else this one if it has Dask (the bpy wheel's)."""
    if args.farm_python:
        return args.farm_python
    if not bpy.app.binary_path:
        return sys.executable
    raise BatchError("--frames inside Blender needs a Python with Dask to drive the farm: --farm-python PATH "
                     "(e.g. the repository's .venv/bin/python; scripts/setup.sh installs Dask there)")


def run_farm(argv: list[str], args) -> list[str]:
    """Farm mode: one Dask task per frame (addon/farm.py, driven by a Python of its own), each a render of
    this script in a process of its own (this Blender, or this Python with the bpy wheel) writing one image
    atomically; frames already rendered are skipped."""
    import json
    import subprocess
    import tempfile
    blend = args.blend or bpy.data.filepath or None
    base = _frame_argv(argv) + (["--blend", os.path.abspath(blend)] if blend and not args.blend else [])
    if bpy.app.binary_path:  # a Blender executable: the frame runs in another Blender
        command = [bpy.app.binary_path, "-b", "--factory-startup", "--python-exit-code", "1", "-P",
                   os.path.abspath(__file__), "--"]
    else:  # the bpy wheel
        command = [sys.executable, os.path.abspath(__file__), "--"]
    frames = parse_frames(args.frames)
    jobs = [{"name": f"frame {f}", "argv": command + base + ["--frame", str(f), "--out", "{out}"],
             "out": os.path.abspath(frame_path(args.out, f))} for f in frames]
    farm = os.path.join(os.path.dirname(os.path.abspath(__file__)), "farm.py")
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(jobs, f)
    try:
        cmd = [_farm_python(args), farm, f.name, "--workers", str(args.workers)] + \
            (["--scheduler", args.scheduler] if args.scheduler else [])
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    except OSError as e:
        raise BatchError(f"cannot run the farm driver: {e}") from None
    finally:
        os.remove(f.name)
    for line in r.stdout.splitlines():
        print(f"neural_yarn batch: {line}", flush=True)
    if r.returncode != 0:
        errors = [ln[len("farm: error: "):] for ln in r.stderr.splitlines() if ln.startswith("farm: error: ")]
        raise BatchError(errors[0] if errors else " ".join(r.stderr.strip().splitlines()[-2:]) or "the farm failed")
    return [j["out"] for j in jobs]


def _check_preset(args, ny) -> None:
    """--preset against the add-on's preset list (the core's), known once the add-on is loaded."""
    if args.model is None and args.preset not in ny.resources.PRESETS:
        raise BatchError(f"unknown preset '{args.preset}' ({', '.join(ny.resources.PRESETS)})")


def _apply_level(ny, obj) -> list:
    """Applies a yarn object's level of detail (addon/level_of_detail.py), prints the batch log's line for it and
    returns [(an object that renders it: its plies, a part of its split, its surface or itself, that one's level)]."""
    try:
        ny.level_of_detail.apply_level(bpy.context, obj)
    except ny.geometry.GeometryError as e:
        raise BatchError(f"{obj.name}: the level of detail could not be built: {e}") from None
    print(f"level of detail: {obj.name}: {obj.neural_yarn.chosen}")
    return ny.level_of_detail.rendered_objects(obj)


def run(argv: list[str]) -> str:
    args = parse_args(argv)
    _check(args)
    if args.frames is not None:
        _check_preset(args, addon_module())
        return ";".join(run_farm(argv, args))
    if args.blend:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
    if not bpy.data.filepath:
        # No .blend given: a demo scene from an empty file, not the startup file's cube.
        bpy.ops.wm.read_factory_settings(use_empty=True)
    ny = addon_module()
    _check_preset(args, ny)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    if args.osl:
        scene.cycles.device = "CPU"
        scene.cycles.shading_system = True
    yarns = [o for o in scene.objects if o.type == "CURVES"]
    demo = args.scene != "auto" or not yarns
    if args.resolution:  # before the level of detail, which depends on it
        scene.render.resolution_x = args.resolution[0]
        scene.render.resolution_y = args.resolution[-1]
        scene.render.resolution_percentage = 100
    levels, framed = {}, False  # each rendered yarn object's level: its material's level follows it
    if demo:
        yarns = _demo_geometry("knit" if args.scene == "auto" else args.scene)
        if args.plies > 1:
            ny.scene_setup.frame(scene, yarns)  # the camera the level is chosen for
            framed = True
            bpy.context.view_layer.update()  # its matrix_world
            scene.neural_yarn_lod = (args.lod or "auto").upper()
            for obj in yarns:  # geometry only at the level used: no ply curves for yarns
                obj.neural_yarn.plies = args.plies
                if not args.model:  # the preset's material first: the level's material follows from it
                    obj.data.materials.append(ny.operators.preset_material(args.preset, "plies"))
                levels.update(_apply_level(ny, obj))
            yarns = list(levels)
        else:
            print(f"level of detail: {', '.join(o.name for o in yarns)}: plies (--plies 1: the curves are plies)")
    else:
        # The yarn objects an artist applied a level of detail to, again for this render's camera and size (--lod,
        # when given, as the scene-wide override: what the render's stale-level check compares against too); what
        # they hide is not rendered.
        if args.lod is not None:
            scene.neural_yarn_lod = args.lod.upper()
        for obj in [o for o in yarns if o.neural_yarn.chosen]:
            levels.update(_apply_level(ny, obj))
        # What renders now, the plies or parts the levels just made included.
        yarns = [o for o in scene.objects if o.type == "CURVES" and not o.hide_render]
    levels = {obj: levels.get(obj, "plies") for obj in yarns}
    surfaces = [obj for obj in yarns if levels[obj] == "surface"]  # drawn with their own material
    yarns = [obj for obj in yarns if levels[obj] != "surface"]
    if args.model:
        try:
            text = ny.nodes.pack_model_file(args.model)
        except ny.model_io.ModelFileError as e:
            raise BatchError(str(e)) from None
        model_level = ny.nodes.parse_text(text).level
        other = sorted({lv for lv in levels.values() if lv != model_level})
        if other:
            raise BatchError(f"--model {args.model} is a {model_level}-level model; the level of detail is "
                             f"{' and '.join(other)}")
        mats = {model_level: ny.nodes.make_material("Neural Yarn " + os.path.basename(args.model), model_text=text)[0]}
    else:
        mats = {lv: ny.operators.preset_material(args.preset, lv) for lv in sorted(set(levels.values()) or {"plies"})}
    for mat in mats.values():
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
        obj.data.materials.append(mats[levels[obj]])
    used = {slot.material for obj in scene.objects for slot in obj.material_slots}
    found = ny.nodes.unrenderable_builtin_nodes(used)
    if found:
        raise BatchError(ny.nodes.builtin_node_message(found))
    if (demo and not framed) or scene.camera is None:
        ny.scene_setup.frame(scene, yarns + surfaces)
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
    if args.frame is not None:
        scene.frame_set(args.frame)
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    if not os.path.isfile(out):
        raise BatchError(f"the render did not write '{out}'")
    names = ([m.name for m in mats.values()] if yarns else []) + [o.active_material.name for o in surfaces]
    print(f"neural_yarn batch: wrote {out} ({len(yarns) + len(surfaces)} yarn object(s), material "
          + ", ".join(f"'{n}'" for n in dict.fromkeys(names)) + f", fallback {node.built})")
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
