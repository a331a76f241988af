# SPDX-License-Identifier: Apache-2.0
"""Light that goes through a ply came in anywhere across its width (cycles_patch 0005, decisions D70). Two
parallel straight cotton plies under the back light, the back one 2.5 ply radii deeper and 1.4 higher, so that
it shadows the upper half of the front ply's width as the light sees it. Rendered by the patched standalone
Cycles with the shipped model: the front ply's shadowed half must glow about as brightly as its lit half, as
in explicit fibers (0.64 of it there; the line through the shading point alone left the shadowed half black,
0.02; docs/benchmarks.md "Across the ply's width"). No pixel may be non-finite or negative.

    .venv/bin/python tests/cycles/far_side_width.py OUT_DIR

Exits 1 with the reason otherwise."""
from __future__ import annotations

import json
import os
import sys
import types

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))

import numpy as np  # noqa: E402

import evaluate as ev  # noqa: E402
from garment import parallel_plies  # noqa: E402
from images import LUMINANCE  # noqa: E402

WIDTH, HEIGHT, SPP = 160, 80, 64
#: The front ply's upper (shadowed) and lower (lit) halves in the 160 x 80 frame at the camera's 12 ply radii
#: (its rows 34 .. 46; the middle row left out), away from its cut ends.
SHADOWED = (slice(34, 40), slice(20, 140))
LIT = (slice(41, 47), slice(20, 140))
#: Shadowed half over lit half: explicit fibers 0.64, the native closure 1.26 with D70 and 0.02 without (the
#: shadowed half lit only by its T lobe's and the back ply's scattered light). Between 0.4 and 2.5 separates
#: the two by more than an order of magnitude on either side.
BAND = (0.4, 2.5)


def main(out: str) -> int:
    os.makedirs(out, exist_ok=True)
    plies = os.path.join(out, "plies.json")
    with open(plies, "w") as f:
        json.dump(parallel_plies([(0.0, 0.0), (1.4, 2.5)], 48.7), f)
    a = types.SimpleNamespace(width=WIDTH, height=HEIGHT, threads=2, timeout=600.0)
    img = ev.render_image(a, ["--preset", "cotton", "--model", os.path.join(ev.MODELS, "cotton.json"), "--plies", plies,
                              "--lights", "back", "--width", str(WIDTH), "--height", str(HEIGHT), "--seed", "1"],
                          os.path.join(out, "half"), SPP, finite=False)
    if not np.isfinite(img).all() or (img < 0).any():
        print("far_side_width: non-finite or negative pixels", file=sys.stderr)
        return 1
    shadowed, lit = (float((img[r] @ LUMINANCE).mean()) for r in (SHADOWED, LIT))
    ratio = shadowed / max(lit, 1e-12)
    print(f"far_side_width: front ply's shadowed half {shadowed:.5f}, lit half {lit:.5f} (ratio {ratio:.2f})")
    if not BAND[0] <= ratio <= BAND[1]:
        print(f"far_side_width: ratio {ratio:.2f} outside {BAND}: light through the ply does not come from across "
              "its width", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
