# SPDX-License-Identifier: Apache-2.0
"""Writes the small sample files the add-on ships to try its importers (addon/samples/):

    knit_6x4.bccx          a 6 x 4 plain knit (Crane's loop curve), one polyline yarn per row, in centimetres
                           as Yuksel's yarn-level models, Z-up, with a BCCX trailer holding the yarn radius
                           (the importer's default Scale 0.01 gives metres)
    plain_weave_tile.txt   one 2 x 2 tile of a plain weave in Leaf et al.'s "Num Yarns" text layout (two warps,
    plain_weave_tile.txt.json  two wefts), with its sidecar: the tile period and yarn radius in centimetres

    .venv/bin/python scripts/make_samples.py [--out addon/samples]

Made from the add-on's own generators (addon/geometry), so the files are reproducible byte for byte
(tests/addon/test_geometry.py checks that the shipped ones are what this script writes).
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
sys.path.insert(0, os.path.join(ROOT, "addon"))
import geometry  # noqa: E402  (addon/geometry: pure numpy)

#: Knit units (a stitch is 2 pi wide, yarn radius 1/2) to centimetres: 1 mm yarn radius.
KNIT_CM = 0.2
#: The weave tile: yarn pitch and radius in centimetres.
WEAVE_SPACING_CM, WEAVE_RADIUS_CM = 0.25, 0.05


def knit_bcc(path: str) -> None:
    curves = geometry.plain_knit(4, 6, samples_per_loop=16, scale=KNIT_CM)
    points = [np.round(c.points, 5) for c in curves]  # 0.1 um: compact and stable across platforms
    geometry.write_bcc(path, points, curve_type="PL", up=2, file_info="neuralyarn sample: 6 x 4 plain knit, cm",
                       yarn_radius=0.5 * KNIT_CM)


def weave_tile(path: str) -> None:
    curves = geometry.woven_fabric(geometry.weave_pattern("plain"), 2, 2, spacing=WEAVE_SPACING_CM,
                                   yarn_radius=WEAVE_RADIUS_CM)
    lines = [f"Num Yarns: {len(curves)}", ""]
    for c in curves:
        lines.append(str(len(c.points)))
        lines += [" ".join(f"{v:.5f}" for v in p) for p in c.points]
        lines.append("")
    with open(path, "w", newline="\n") as f:
        f.write("\n".join(lines))
    with open(path + ".json", "w", newline="\n") as f:
        json.dump({"period": [2 * WEAVE_SPACING_CM, 2 * WEAVE_SPACING_CM], "yarn_radius": WEAVE_RADIUS_CM,
                   "units": "cm"}, f, indent=1)
        f.write("\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "addon", "samples"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    knit_bcc(os.path.join(a.out, "knit_6x4.bccx"))
    weave_tile(os.path.join(a.out, "plain_weave_tile.txt"))
    print(f"make_samples: wrote {', '.join(sorted(os.listdir(a.out)))} to {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
