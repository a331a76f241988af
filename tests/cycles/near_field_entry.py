# SPDX-License-Identifier: Apache-2.0
"""A path that leaves a ply starts where the light it stands for came in around the ply: on the ply's face toward
the light, across the width at an h drawn from the gather's distribution given the hit point's (cycles_patch 0005,
decisions D73; the gather's statistic is checked against a renderer's walk through explicit fibers by
`Gather.EntryAcrossTheWidthMatchesARendererWalk`).

A fleece ply, long and straight, under a sun 85 degrees from the view in the plane normal to the ply (grazing the
face the camera sees, from +y), a black plate beside the ply on the light's side (the plane y = PLATE_Y, from a
little in front of the ply's axis to far behind it): the light reaches the ply's top face past the plate's edge,
its face toward the light not at all. Explicit fibers, which take their light in through that face, keep
EXPLICIT_KEEPS (measured 0.611; the four orientations' halves 0.609, 0.613) of the ply's light without the plate;
the shipped model must keep that within SAME_AS_FIBERS (measured 0.658). The model without its entry's h (every path
starts on the hit point's line, as before D73) keeps 0.957 and must be further than that from the fibers (else the
fixture no longer tells the two apart). The same plate on the ply's dark side must
take nothing from the model (a kernel that started paths anywhere around the ply would lose light there). All
renders with one seed; the explicit reference is rendered here, over four orientations of the cross-section.

    .venv/bin/python tests/cycles/near_field_entry.py OUT_DIR

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

WIDTH, HEIGHT, SPP, EXPLICIT_SPP = 160, 80, 32, 16
#: The plate: the plane y = PLATE_Y (ply radii; the ply's axis is the x axis, the camera at 12 on -z) from z = -0.5
#: (in front of the axis: the ply's top face, at z ~ -1, sees past it) to far behind.
PLATE_Y = 1.05
#: The ply's rows in the 160 x 80 frame.
ROWS = slice(26, 54)
#: What explicit fibers keep is the reference, rendered here; the model within SAME_AS_FIBERS of it (measured
#: |0.658 - 0.611| = 0.047, the reference's own halves 0.004 apart; without the entry's h: 0.35 off).
SAME_AS_FIBERS = 0.1
#: The plate on the dark side: the model keeps at least this (measured 1.000).
DARK_SIDE_KEEPS = 0.98


def plate(y: float):
    return (0.0, 0.0, 0.0), ((-80, y, -0.5), (80, y, -0.5), (80, y, 30), (-80, y, 30))


def main(out: str) -> int:
    os.makedirs(out, exist_ok=True)
    a = types.SimpleNamespace(width=WIDTH, height=HEIGHT, threads=2, timeout=600.0)
    plies = os.path.join(out, "ply.json")
    with open(plies, "w") as f:
        json.dump(parallel_plies([(0.0, 0.0)], 48.7), f)
    shipped = os.path.join(ev.MODELS, "fleece.json")
    model = json.load(open(shipped))
    near_field = model.get("near_field", {})
    if "through_entry" not in near_field or "reflected_entry" not in near_field:
        print("near_field_entry: the shipped fleece model has no entry's h ('through_entry', 'reflected_entry')",
              file=sys.stderr)
        return 1
    line = os.path.join(out, "fleece_line.json")  # the same model, every path on the hit point's line (D72)
    with open(line, "w") as f:
        json.dump({**model, "near_field": {k: v for k, v in near_field.items() if not k.endswith("_entry")}}, f)
    common = ["--preset", "fleece", "--lights", "sun-85-normal", "--width", str(WIDTH), "--height", str(HEIGHT),
              "--plies", plies]
    light = {}
    try:
        for name, y in (("open", None), ("plate", PLATE_Y), ("dark_side", -PLATE_Y)):
            edit = (lambda t, y=y: ev.with_diffuse_quad(t, "plate", *plate(y))) if y is not None else None
            for model_name, path in (("shipped", shipped), ("line", line)):
                rgb = ev.render_image(a, [*common, "--model", path, "--seed", "1"],
                                      os.path.join(out, f"{model_name}_{name}"), SPP, edit=edit)
                if not np.isfinite(rgb).all() or (rgb < 0).any():
                    raise ev.RenderFailed(f"{model_name}, {name}: non-finite or negative pixels")
                light[(model_name, name)] = float((rgb @ LUMINANCE)[ROWS].sum())
            if name == "dark_side":
                continue
            explicit = [ev.render_image(a, [*common, "--seed", str(1001 + r), "--ply-rotation", str(r)],
                                        os.path.join(out, f"explicit_{name}_{r}"), EXPLICIT_SPP, edit=edit)
                        for r in (0, 90, 180, 270)]
            light[("explicit", name)] = float((np.mean(explicit, axis=0) @ LUMINANCE)[ROWS].sum())
    except ev.RenderFailed as e:
        print(f"near_field_entry: {e}", file=sys.stderr)
        return 1
    keeps = {m: light[(m, "plate")] / light[(m, "open")] for m in ("explicit", "shipped", "line")}
    dark = light[("shipped", "dark_side")] / light[("shipped", "open")]
    print("near_field_entry: light kept with the plate on the light's side: " +
          ", ".join(f"{m} {k:.3f}" for m, k in keeps.items()) + f"; on the dark side: shipped {dark:.3f}")
    problems = []
    if not abs(keeps["shipped"] - keeps["explicit"]) <= SAME_AS_FIBERS:
        problems.append(f"the model keeps {keeps['shipped']:.3f} of its light, explicit fibers {keeps['explicit']:.3f}: "
                        "paths do not start where the light came in around the ply")
    if not abs(keeps["line"] - keeps["explicit"]) > SAME_AS_FIBERS:
        problems.append(f"the model without its entry's h keeps {keeps['line']:.3f}, as close to the fibers: the "
                        "plate no longer tells where the light comes in")
    if not dark >= DARK_SIDE_KEEPS:
        problems.append(f"a plate on the ply's dark side takes {1 - dark:.3f} of the model's light: paths start on "
                        "the side away from the light")
    return cycles_check.report("near_field_entry", problems)


if __name__ == "__main__":
    cycles_check.run(main, __doc__)
