# SPDX-License-Identifier: Apache-2.0
"""Installs the packaged add-on zip the way a user does, enables it, makes a knitted swatch in fleece and
renders it (32 x 24, stock nodes), in a throw-away user directory (the caller sets BLENDER_USER_RESOURCES /
BLENDER_USER_SCRIPTS to a temporary directory).

    <python with bpy> tests/addon/install_smoke.py ZIP OUT.png                         (4.2+: extension)
    blender -b --factory-startup --python-exit-code 1 -P tests/addon/install_smoke.py -- ZIP OUT.png  (3.4)

Prints "install_smoke: ok ..." and exits 0, or prints the problem and exits 1.
"""
import os
import sys

import bpy


def main(zip_path: str, out: str) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if bpy.app.version >= (4, 2, 0):
        bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
        module = "bl_ext.user_default.neural_yarn"
    else:
        bpy.ops.preferences.addon_install(filepath=zip_path)
        bpy.ops.preferences.addon_enable(module="neural_yarn")
        module = "neural_yarn"
    ny = sys.modules.get(module)
    if ny is None:
        raise SystemExit(f"install_smoke: the add-on did not load as '{module}'")
    # The shipped models must come from inside the installed package, not from a checkout.
    models = ny.resources.resource_dir("models")
    if not models.startswith(os.path.dirname(ny.__file__)):
        raise SystemExit(f"install_smoke: models found outside the installed package: {models}")
    # So must the preset list (the core's presets.json, copied in by scripts/package_addon.sh).
    if not ny.resources.PRESETS_FILE.startswith(os.path.dirname(ny.__file__)) or "fleece" not in ny.resources.PRESETS:
        raise SystemExit(f"install_smoke: the preset list {ny.resources.PRESETS} came from "
                         f"{ny.resources.PRESETS_FILE}, not from the installed package")
    assert bpy.ops.neural_yarn.add_knit(rows=3, stitches=3, preset="fleece") == {"FINISHED"}
    obj = bpy.context.active_object
    scene = bpy.context.scene
    ny.scene_setup.frame(scene, [obj])
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 2
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 24, 100
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(out)
    peak = max(img.pixels[:])
    if not peak > 0.02:
        raise SystemExit(f"install_smoke: the render is black (peak {peak})")
    print(f"install_smoke: ok: {module} from {os.path.dirname(ny.__file__)}, Blender {bpy.app.version_string}, "
          f"peak {peak:.3f}")


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    try:
        main(*args)
    except SystemExit as e:
        print(e, file=sys.stderr)
        sys.stdout.flush()
        os._exit(1)
    except Exception as e:  # noqa: BLE001 - report anything as a failure, with the traceback
        import traceback
        traceback.print_exc()
        os._exit(1)
    sys.stdout.flush()
    # The bpy 4.5 wheel can hang at interpreter exit after a render (a static destructor waits on its audio
    # thread's condition variable); leave without running it.
    os._exit(0)
