# SPDX-License-Identifier: Apache-2.0
"""The main job's pictures: a knitted piece of 3-ply yarns in every preset, rendered with the native closure
(patched standalone Cycles) and with the stock-Blender fallback (the add-on's stock-node body in the bpy wheel),
and one contact sheet of all ten.

    .venv/bin/python scripts/showcase.py [--out out/showcase] [--samples 64] [--size 256]

Both rows render one scene per preset, examples/make_examples.py's knit: its Cycles XML in the patched Cycles,
its description (knit_<preset>.json) built in Blender by the add-on (scripts/fallback_render.py), with the same
camera, lights and curves. Prints each image's time and the paths; exits 1 with one line if a render fails.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

from evaluate import PRESETS

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
PYTHON = os.path.join(ROOT, ".venv", "bin", "python")


def run(cmd: list[str], what: str, tool: str = "showcase") -> None:
    t0 = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        tail = " ".join((r.stderr or r.stdout).strip().splitlines()[-2:])
        raise SystemExit(f"{tool}: {what} failed ({r.returncode}): {tail}")
    print(f"{tool}: {what}: {time.monotonic() - t0:.1f} s", flush=True)


def native_knits(out: str, presets: list[str], samples: int, size: int) -> list[str]:
    """The command rendering examples/make_examples.py's knit of 3-ply yarns with the native closure (patched
    Cycles) for the presets: out/knit_<preset>.exr and .png."""
    return [PYTHON, os.path.join(ROOT, "examples", "make_examples.py"), "--out", out, "--presets", *presets,
            "--scenes", "knit", "--render", "--check", "--samples", str(samples), "--width", str(size)]


def fallback_knit(out: str, preset: str, fallback: str, samples: int, exr: str) -> list[str]:
    """The command rendering the knit's description (native_knits wrote it) with a stock-Blender fallback
    ("nodes" or "osl") to the OpenEXR file `exr`."""
    return [PYTHON, os.path.join(ROOT, "scripts", "fallback_render.py"), os.path.join(out, f"knit_{preset}.json"), exr,
            "--body", fallback, "--samples", str(samples)]


def contact_sheet(rows: list[tuple[str, list[str]]], out: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(rows), len(PRESETS), figsize=(2.2 * len(PRESETS), 2.4 * len(rows)),
                             squeeze=False)
    for r, (label, paths) in enumerate(rows):
        for c, path in enumerate(paths):
            ax = axes[r][c]
            ax.imshow(mpimg.imread(path))
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(PRESETS[c])
            if c == 0:
                ax.set_ylabel(label)
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "showcase"))
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--size", type=int, default=256, help="image width and height in pixels")
    a = ap.parse_args()
    if a.samples < 1 or not 16 <= a.size <= 4096:
        raise SystemExit("showcase: --samples must be >= 1 and --size within [16, 4096]")
    os.makedirs(a.out, exist_ok=True)
    t0 = time.monotonic()
    run(native_knits(a.out, PRESETS, a.samples, a.size), "native closure (patched Cycles), knit, 5 presets")
    native = [os.path.join(a.out, f"knit_{p}.png") for p in PRESETS]
    nodes, blender = [], bpy_version()
    for p in PRESETS:
        path = os.path.join(a.out, f"knit_{p}_stock_nodes")
        run(fallback_knit(a.out, p, "nodes", a.samples, path + ".exr"), f"stock-node fallback (Blender {blender}), knit, {p}")
        # (as make_examples.py turns the native renders into PNG)
        run(["oiiotool", path + ".exr", "--colorconvert", "linear", "sRGB", "-d", "uint8", "-o", path + ".png"],
            f"{p} PNG")
        nodes.append(path + ".png")
    sheet = os.path.join(a.out, "contact_sheet.png")
    contact_sheet([("native closure\n(patched Cycles)", native), ("stock-node fallback\n(stock Blender)", nodes)],
                  sheet)
    print(f"showcase: {len(native) + len(nodes)} images in {a.out}; contact sheet {sheet} "
          f"({time.monotonic() - t0:.0f} s)")
    return 0


def bpy_version() -> str:
    r = subprocess.run([PYTHON, "-c", "import bpy, os, sys; sys.stdout.write(bpy.app.version_string); "
                        "sys.stdout.flush(); os._exit(0)"], capture_output=True, text=True)
    return r.stdout.strip().split(" ")[0] or "?"


if __name__ == "__main__":
    sys.exit(main())
