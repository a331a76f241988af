#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Where the native closure's error over stacked cloth layers comes from (issue 19): the stability suite's layered
scene (`cycles-scene --layers 2`, camera at 6 ply radii, a ply 16 radii long) with the plies' spacing within a
sheet and between sheets varied (`--layer-pitch Y Z`, ply radii; 2.05 is the suite's: touching but for a small
gap), the native closure against explicit fibers under one light:

    cd scripts && ../.venv/bin/python bench_layer_pitch.py --pitches 2.05,2.05 2.05,4 4,2.05 4,4 --out ../build/bench_layer_pitch
        [--preset fleece] [--light environment] [--spp 256] [--ref-spp 64] [--width 128] [--height 64]

The reference is explicit fibers over four orientations of the cross-section (90 degrees apart, --ref-spp each);
its floor is one half of them against the other. Prints per pitch the mean luminance error (and per channel)
over the middle half of the frame and over the whole frame; writes OUT/bench_layer_pitch.json. A benchmark:
prints, never a test.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

import evaluate as ev

ROTATIONS = (0, 90, 180, 270)


def render(a, args: list[str], name: str, spp: int) -> np.ndarray:
    """Writes the scene and renders it with the patched Cycles (the harness's render: its errors, its progress line
    on stderr; the table goes to stdout)."""
    try:
        return ev.render_image(a, args, os.path.join(a.out, name), spp)
    except ev.RenderFailed as e:
        raise SystemExit(f"bench_layer_pitch: {name}: {e}")


def errors(img: np.ndarray, ref: np.ndarray) -> dict:
    """Mean luminance and per-channel errors over the middle half of the frame and over the whole frame
    (evaluate.metrics)."""
    h, w = ref.shape[:2]
    m = ev.metrics(img, ref, (slice(h // 4, h - h // 4), slice(w // 4, w - w // 4)))
    return {"centre": {"luminance": m["mean_luminance_error"], "rgb": m["mean_colour_error"]},
            "frame": {"luminance": m["mean_luminance_error_frame"], "rgb": m["mean_colour_error_frame"]}}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pitches", nargs="+", default=["2.05,2.05", "2.05,4", "4,2.05", "4,4"],
                    help="Y,Z pairs: within a sheet, between sheets (ply radii, at least 2)")
    ap.add_argument("--preset", default="fleece")
    ap.add_argument("--light", default="environment")
    ap.add_argument("--layers", type=int, default=2)
    ap.add_argument("--spp", type=int, default=256, help="the native closure's samples")
    ap.add_argument("--ref-spp", type=int, default=64, help="explicit fibers' samples per orientation")
    ap.add_argument("--width", type=int, default=128)
    ap.add_argument("--height", type=int, default=64)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per render")
    ap.add_argument("--out", default=os.path.join(ev.ROOT, "build", "bench_layer_pitch"))
    a = ap.parse_args()
    try:
        pitches = [tuple(float(v) for v in p.split(",")) for p in a.pitches]
        if not all(len(p) == 2 for p in pitches):
            raise ValueError
    except ValueError:
        print("bench_layer_pitch: --pitches takes Y,Z pairs of numbers, e.g. 2.05,4", file=sys.stderr)
        return 1
    os.makedirs(a.out, exist_ok=True)
    rows = []
    print("| pitch within / between sheets | centre: luminance (R / G / B) % | frame: luminance % | reference floor, centre % |")
    print("|---|---|---|---|")
    for y, z in pitches:
        common = ["--preset", a.preset, "--lights", a.light, "--width", str(a.width), "--height", str(a.height),
                  "--ply-length", "16", "--camera-distance", "6", "--layers", str(a.layers),
                  "--layer-pitch", f"{y:g}", f"{z:g}"]
        tag = f"y{y:g}_z{z:g}"
        native = render(a, [*common, "--model", os.path.join(ev.MODELS, f"{a.preset}.json"), "--seed", "1"],
                        f"native_{tag}", a.spp)
        parts = [render(a, [*common, "--seed", str(1001 + r), "--ply-rotation", str(r)], f"explicit_{tag}_{r}",
                        a.ref_spp) for r in ROTATIONS]
        ref = sum(parts) / len(parts)
        e = errors(native, ref)
        floor = errors((parts[0] + parts[1]) / 2, (parts[2] + parts[3]) / 2)
        rows.append({"pitch_y": y, "pitch_z": z, "native": e, "floor": floor})
        c = e["centre"]
        print(f"| {y:g} / {z:g} | {100 * c['luminance']:+.1f} ({' / '.join(f'{100 * v:+.1f}' for v in c['rgb'])}) | "
              f"{100 * e['frame']['luminance']:+.1f} | {100 * floor['centre']['luminance']:+.1f} |", flush=True)
    with open(os.path.join(a.out, "bench_layer_pitch.json"), "w") as f:
        json.dump({"preset": a.preset, "light": a.light, "layers": a.layers, "spp": a.spp, "ref_spp": a.ref_spp,
                   "rotations": list(ROTATIONS), "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
