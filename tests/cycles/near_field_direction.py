# SPDX-License-Identifier: Apache-2.0
"""A path that leaves a ply starts where the light it stands for came in: further along the ply toward the light
(cycles_patch 0005, decisions D72). Light that enters a ply keeps travelling the way it came along the ply's axis
(the gather's signed offsets, checked against a renderer's walk through explicit fibers by
`Gather.AxialExitOffsetMatchesARendererWalk`); so where a shadow falls across a ply under a light along its axis,
the ply glows into the shadow on the light's side of its edge, and the lit part beside the edge keeps its light.

A cotton ply, long and straight, under a sun 120 degrees from the view toward the ply's +x axis (behind the ply), a
black wall behind it shadowing it for x below about 3 ply radii. Rendered by the patched standalone Cycles with the
shipped model's offsets (its entry h left out, every path starting at the hit point's angle about the curve: where
around the ply paths start is near_field_entry.py's, D73), with the same model without its near field, and with the near field mirrored (every band's offsets
negated: light that travels against its direction), all with one seed, so that their differences are the near
field's. Against the model without a near field (over the ply's rows; the shadow: the columns under a quarter of
the brightest column's light): the shipped model must gain at least MIN_SHADOW_GAIN of the image's light in the
shadow and lose no more than MAX_LIT_LOSS in the lit part; the mirrored one must lose at least MIN_MIRROR_LOSS in
the lit part (its paths start in the shadow). Offsets drawn with either sign alike (the near field before D72)
give +0.035 and -0.092: they fail the first two. The same ply with its keys in the opposite order must give the
shipped model's shares within SAME_REVERSED (a kernel that followed the curve's parameter instead of the light, or
Cycles' sd->dPdu, which it flips on back-facing hits, would not). A model from before D72 (six unsigned quantiles,
D71's shipped cotton near field) must render, its offsets either way: its lit part between the shipped model's and
the mirrored one's. No pixel may be non-finite or negative.

The wall is this test's own fixture (a quad appended to `neuralyarn cycles-scene`'s XML). Explicit fibers are not
the reference here: cotton's back-lit fibers at a test's samples spread that shadow's light by +-40 % from one set
of seeds to another (docs/benchmarks.md, "The near field follows the light").

    .venv/bin/python tests/cycles/near_field_direction.py OUT_DIR

Exits 1 with the reason otherwise."""
from __future__ import annotations

import json
import os
import sys
import types

import cycles_check  # first: it puts scripts/ (evaluate, garment, images) on the path

import numpy as np

import evaluate as ev
from garment import parallel_plies
from images import LUMINANCE

WIDTH, HEIGHT, SPP = 160, 80, 16
#: A black wall 3 ply radii behind the ply (camera at 12 on -z) for x < 8.2: under the sun's direction toward
#: (0.87, 0, 0.5) it shadows the ply's front face for x < ~3.
WALL = ((0.0, 0.0, 0.0), ((-80, -30, 3), (8.196, -30, 3), (8.196, 30, 3), (-80, 30, 3)))
#: The ply's rows (its image is rows 26 .. 54; the middle, away from its silhouettes).
ROWS = slice(32, 48)
#: Shares of the image's light without a near field (measured: shipped +0.128 in the shadow, -0.003 in the lit
#: part; mirrored -0.249 in the lit part; the seed-to-seed spread of each at 16 spp is under 0.01. The reversed
#: ply against its own baseline: +0.141 / -0.003 — its samples are not the same ones, hence the wider margin, still
#: far from the +-0.2 a kernel that follows the curve's parameter would show).
MIN_SHADOW_GAIN, MAX_LIT_LOSS, MIN_MIRROR_LOSS, SAME_REVERSED = 0.06, 0.02, 0.1, 0.03
#: D71's shipped cotton near field (|offset| quantiles at 25 ... 99 %, ply radii): a model file from before D72.
LEGACY = {"axial_exit_through": [0.1924, 0.9947, 2.8774, 5.9009, 8.6583, 16.7305],
          "axial_exit_reflected": [0.0338, 0.1206, 0.3997, 1.1393, 2.0474, 5.4621]}


def mirrored(near_field: dict) -> dict:
    """The near field with every band's offsets negated (quantiles reversed to keep them non-decreasing)."""
    return {k: ([[-v for v in reversed(band)] for band in v] if k.endswith("_bands") else v)
            for k, v in near_field.items()}


def main(out: str) -> int:
    os.makedirs(out, exist_ok=True)
    a = types.SimpleNamespace(width=WIDTH, height=HEIGHT, threads=2, timeout=600.0)
    plies, reversed_plies = os.path.join(out, "ply.json"), os.path.join(out, "ply_reversed.json")
    ply = parallel_plies([(0.0, 0.0)], 48.7)
    with open(plies, "w") as f:
        json.dump(ply, f)
    keys = ply["plies"][0]
    with open(reversed_plies, "w") as f:
        json.dump({**ply, "plies": [[v for i in range(len(keys) // 3 - 1, -1, -1) for v in keys[3 * i:3 * i + 3]]]}, f)
    model = json.load(open(os.path.join(ev.MODELS, "cotton.json")))
    if "through_bands" not in model.get("near_field", {}):
        print("near_field_direction: the shipped cotton model has no signed near field ('through_bands')",
              file=sys.stderr)
        return 1
    offsets = {k: v for k, v in model["near_field"].items() if not k.endswith("_entry")}
    models = {}
    for name, nf in (("shipped", offsets), ("far", None), ("mirrored", mirrored(offsets)), ("legacy", LEGACY)):
        models[name] = os.path.join(out, f"cotton_{name}.json")
        with open(models[name], "w") as f:
            json.dump({**{k: v for k, v in model.items() if k != "near_field"}, **({"near_field": nf} if nf else {})}, f)
    common = ["--preset", "cotton", "--lights", "sun-120-axis", "--width", str(WIDTH), "--height", str(HEIGHT),
              "--seed", "1"]
    runs = {name: (path, plies) for name, path in models.items()}
    runs["reversed"] = (models["shipped"], reversed_plies)
    runs["far_reversed"] = (models["far"], reversed_plies)  # its own baseline: the order changes the samples
    img = {}
    try:
        for name, (path, ply_file) in runs.items():
            rgb = ev.render_image(a, [*common, "--plies", ply_file, "--model", path], os.path.join(out, name), SPP,
                                  edit=lambda t: ev.with_diffuse_quad(t, "wall", *WALL))
            if (rgb < 0).any():
                raise ev.RenderFailed(f"{name}: negative pixels")
            img[name] = rgb[ROWS] @ LUMINANCE
    except ev.RenderFailed as e:
        print(f"near_field_direction: {e}", file=sys.stderr)
        return 1
    far = img["far"]
    column = far.mean(axis=0)
    shadow = column < 0.25 * column.max()
    if shadow.sum() < 20 or (~shadow).sum() < 20:
        print(f"near_field_direction: {int(shadow.sum())} shadowed columns of {shadow.size}: the scene moved",
              file=sys.stderr)
        return 1
    def shares(name: str, base: np.ndarray) -> tuple[float, float]:
        d = img[name] - base
        return float(d[:, shadow].sum()) / float(base.sum()), float(d[:, ~shadow].sum()) / float(base.sum())

    share = {name: shares(name, far) for name in ("shipped", "mirrored", "legacy")}
    share["reversed"] = shares("reversed", img["far_reversed"])
    print("near_field_direction: light gained against no near field, shadow / lit part: " +
          ", ".join(f"{k} {s:+.3f} / {l:+.3f}" for k, (s, l) in share.items()))
    problems = []
    if not share["shipped"][0] >= MIN_SHADOW_GAIN:
        problems.append(f"the shadow gains {share['shipped'][0]:+.3f} < {MIN_SHADOW_GAIN}: paths do not start toward "
                        "the light")
    if not share["shipped"][1] >= -MAX_LIT_LOSS:
        problems.append(f"the lit part loses {-share['shipped'][1]:.3f} > {MAX_LIT_LOSS}: paths start away from the light")
    if not share["mirrored"][1] <= -MIN_MIRROR_LOSS:
        problems.append(f"the mirrored near field's lit part loses only {-share['mirrored'][1]:.3f} < {MIN_MIRROR_LOSS}: "
                        "the offsets' sign does not reach the kernel")
    if not all(abs(r - s) <= SAME_REVERSED for r, s in zip(share["reversed"], share["shipped"])):
        problems.append("the ply with its keys reversed gives other shares: the kernel follows the curve's parameter, "
                        "not the light")
    if not share["mirrored"][1] < share["legacy"][1] < share["shipped"][1]:
        problems.append(f"the pre-D72 model's lit part {share['legacy'][1]:+.3f} is not between the mirrored and the "
                        "shipped model's: its offsets are not taken either way")
    return cycles_check.report("near_field_direction", problems)


if __name__ == "__main__":
    cycles_check.run(main, __doc__)
