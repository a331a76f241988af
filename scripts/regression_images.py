# SPDX-License-Identifier: Apache-2.0
"""Image regression (issue 19): a few small scenes per method, rendered and compared with committed references
(tests/data/regression/*.exr) by Blender's render-test rule, `idiff -fail 0.016 -failpercent 1` on the display
images (each pair at the reference's exposure, clamped, sRGB: scripts/images.py).

    .venv/bin/python scripts/regression_images.py [--out DIR] [--cases NAME ...]    # compare (CI)
    .venv/bin/python scripts/regression_images.py --update                          # regenerate the references

Every scene is written by `neuralyarn cycles-scene` (its XML for the patched standalone Cycles, its description
for Blender: the bpy wheel through scripts/fallback_render.py), seeded: a render repeats bit for bit on one
build, so any change of what a method renders — the closure, the model files, the fallback's tables and
shaders, the scene writers, the Blender builder — moves pixels. Regenerate the references (--update) only for
a change meant to alter images, and say so in the commit. Exits 1 naming each case that differs or fails.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import numpy as np

from evaluate import CLI, CYCLES, ROOT, patch_scene_args
from images import display, exposure_of, read_exr, write_exr

REFERENCES = os.path.join(ROOT, "tests", "data", "regression")
FALLBACK_RENDER = os.path.join(ROOT, "scripts", "fallback_render.py")
MODELS = os.path.join(ROOT, "models")
#: Blender's render tests' idiff rule: a display pixel fails beyond 0.016 (4/255), 1 % of them may.
IDIFF = ["-fail", "0.016", "-failpercent", "1"]
#: (name, renderer, cycles-scene arguments, samples): the close-up (the camera moved in: the ply a third of the
#: frame's height) of three presets under three rigs by every method (explicit fibers, the native closure, a
#: baseline, the OSL and stock-node fallbacks in Blender), and the harness's knit patch (make_examples.py's).
WIDTH, HEIGHT = 64, 32
CLOSEUP = ["--camera-distance", "5", "--ply-length", "30"]
KNIT = "knit"  # (the knit's plies file and camera: knit_args())
CASES = [
    ("closeup_fleece_keyrim_explicit", "cycles", ["--preset", "fleece", "--lights", "key-rim"], 16),
    ("closeup_fleece_keyrim_native", "cycles", ["--preset", "fleece", "--lights", "key-rim", "--model", "fleece"], 16),
    ("closeup_fleece_keyrim_chiang", "cycles",
     ["--preset", "fleece", "--lights", "key-rim", "--baseline", "chiang", "--baseline-colour", "0.05", "0.2", "0.5"], 16),
    ("closeup_fleece_keyrim_osl", "osl", ["--preset", "fleece", "--lights", "key-rim", "--model", "fleece"], 16),
    ("closeup_fleece_keyrim_nodes", "nodes", ["--preset", "fleece", "--lights", "key-rim", "--model", "fleece"], 16),
    ("closeup_cotton_grazing_explicit", "cycles", ["--preset", "cotton", "--lights", "grazing"], 16),
    ("closeup_cotton_grazing_native", "cycles", ["--preset", "cotton", "--lights", "grazing", "--model", "cotton"], 16),
    ("closeup_cotton_grazing_nodes", "nodes", ["--preset", "cotton", "--lights", "grazing", "--model", "cotton"], 16),
    ("closeup_silk_back_native", "cycles", ["--preset", "silk", "--lights", "back", "--model", "silk"], 16),
    ("closeup_silk_back_osl", "osl", ["--preset", "silk", "--lights", "back", "--model", "silk"], 16),
    ("knit_polyester_keyrim_explicit", "cycles", ["--preset", "polyester", KNIT], 4),
    ("knit_polyester_keyrim_native", "cycles", ["--preset", "polyester", KNIT, "--model", "polyester"], 16),
    ("knit_polyester_keyrim_nodes", "nodes", ["--preset", "polyester", KNIT, "--model", "polyester"], 16),
]


def knit_args(out: str) -> list[str]:
    """cycles-scene's arguments of the 4 x 4 knit of 3-ply yarns (its plies file, written into `out`, and the
    camera that frames it), in a square image."""
    return [*patch_scene_args(out, "knit"), "--width", str(WIDTH), "--height", str(WIDTH)]


def scene_args(args: list[str], out: str) -> list[str]:
    """The case's cycles-scene arguments: a preset's model name turned into its model file, the knit's plies and
    camera, or the close-up's."""
    full = [os.path.join(MODELS, f"{a}.json") if i and args[i - 1] == "--model" else a for i, a in enumerate(args)]
    if KNIT in full:
        full.remove(KNIT)
        return full + knit_args(out)
    return full + CLOSEUP + ["--width", str(WIDTH), "--height", str(HEIGHT)]


def run(cmd: list[str], what: str) -> str:
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        tail = " ".join((r.stderr or r.stdout).strip().splitlines()[-2:])
        raise RuntimeError(f"{what} failed ({r.returncode}): {tail}")
    return r.stdout


def render(name: str, renderer: str, args: list[str], spp: int, out: str) -> str:
    """Renders one case into out/NAME.exr and returns the path."""
    exr = os.path.join(out, name + ".exr")
    scene = os.path.join(out, name + (".xml" if renderer == "cycles" else ".json"))
    full = scene_args(args, out)
    run([CLI, "cycles-scene", *full, "--seed", "1", "--out", scene], f"{name}: cycles-scene")
    if renderer == "cycles":
        # (the standalone takes the image size from its command line)
        size = [full[full.index(k) + 1] for k in ("--width", "--height")]
        run([CYCLES, "--background", "--quiet", "--samples", str(spp), "--threads", "2", "--width", size[0], "--height",
             size[1], "--output", exr, scene], f"{name}: cycles")
    else:
        run([sys.executable, FALLBACK_RENDER, scene, exr, "--body", renderer, "--samples", str(spp), "--threads", "2"],
            f"{name}: Blender ({renderer})")
    return exr


def compare(name: str, exr: str, out: str) -> tuple[bool, str]:
    """idiff's verdict on the display images of the render and the reference (one exposure: the reference's)."""
    ref_path = os.path.join(REFERENCES, name + ".exr")
    if not os.path.isfile(ref_path):
        return False, f"no reference {os.path.relpath(ref_path, ROOT)} (make it with --update)"
    ref, img = read_exr(ref_path), read_exr(exr)
    if ref.shape != img.shape:
        return False, f"size {img.shape[1]} x {img.shape[0]}, the reference's {ref.shape[1]} x {ref.shape[0]}"
    if not np.isfinite(img).all():
        return False, f"{int((~np.isfinite(img)).sum())} non-finite pixel values"
    exposure = exposure_of(ref)
    a, b = os.path.join(out, name + "_ref_display.exr"), os.path.join(out, name + "_display.exr")
    write_exr(a, display(ref, exposure))
    write_exr(b, display(img, exposure))
    r = subprocess.run(["idiff", *IDIFF, a, b], capture_output=True, text=True)
    verdict = next((ln.strip() for ln in r.stdout.splitlines() if ln.strip() in ("PASS", "WARNING", "FAILURE")), "?")
    worst = next((ln.strip() for ln in r.stdout.splitlines() if "Max error" in ln), "")
    return r.returncode in (0, 1) and verdict != "FAILURE", "; ".join(x for x in (verdict, worst) if x)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "regression"))
    ap.add_argument("--update", action="store_true", help="render the references into tests/data/regression/")
    ap.add_argument("--cases", nargs="+", choices=[c[0] for c in CASES], help="only these cases")
    a = ap.parse_args()
    for tool in (CLI, CYCLES):
        if not os.access(tool, os.X_OK):
            print(f"regression_images: {tool} is not built (scripts/setup.sh)", file=sys.stderr)
            return 1
    cases = [c for c in CASES if not a.cases or c[0] in a.cases]
    os.makedirs(a.out, exist_ok=True)
    failed = []
    for k, (name, renderer, args, spp) in enumerate(cases):
        t0 = time.monotonic()
        try:
            exr = render(name, renderer, args, spp, a.out)
            if a.update:
                os.makedirs(REFERENCES, exist_ok=True)
                write_exr(os.path.join(REFERENCES, name + ".exr"), read_exr(exr), half=True)
                ok, what = True, "reference written"
            else:
                ok, what = compare(name, exr, a.out)
        except RuntimeError as e:
            ok, what = False, str(e)
        print(f"[{k + 1}/{len(cases)}] {name}: {'ok' if ok else 'DIFFERS'} ({what}, {time.monotonic() - t0:.1f} s)",
              flush=True)
        if not ok:
            failed.append(name)
    if failed:
        print(f"regression_images: {len(failed)} of {len(cases)} differ: {', '.join(failed)}", file=sys.stderr)
        return 1
    print(f"regression_images: {len(cases)} cases {'written' if a.update else 'match their references'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
