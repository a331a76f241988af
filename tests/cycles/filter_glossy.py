# SPDX-License-Identifier: Apache-2.0
"""The native closure under Cycles' Filter Glossy (bsdf_blur -> bsdf_neural_yarn_blur, D61): a cotton knit (narrow
R lobe, beta_R 1 degree) rendered by the patched standalone Cycles with the filter off and on, seeds 1-4 each. The
filter must engage (paths after a rough bounce see a wider R lobe: seed 1's pixels move) and keep the R lobe's energy
(the frame's mean over the seeds within TOLERANCE per channel), with no non-finite or negative pixel.

    .venv/bin/python tests/cycles/filter_glossy.py OUT_DIR

Exits 1 with the reason otherwise."""
from __future__ import annotations

import os
import re
import sys
import types

import cycles_check  # first: it puts scripts/ (evaluate, garment, images) on the path

import numpy as np

import evaluate as ev
from images import read_exr

SIZE = 64
SPP = 512
#: Frame mean per channel over SEEDS, filter on against off: the blurred R lobe keeps its energy, so the mean moves by
#: about the renders' own noise. One seed's sparkle decides it: at 64 spp one firefly moved it by 6 %; at 512 spp a
#: seed on one CPU +1.4 / +1.4 / -2.0 %, the same seed on another (whose paths differ) -1.1 / -3.0 / -5.0 %, and seeds
#: 1-4 there -1.1 ... +0.9 / -3.0 ... +1.1 / -5.0 ... +1.2 %, their means +0.0 / -0.4 / -1.1 % (docs/benchmarks.md,
#: "The native closure under Filter Glossy"). Hence the mean of four seeds at 512 spp.
TOLERANCE = 0.05
SEEDS = (1, 2, 3, 4)
#: A pixel moved by more than this (display-independent, linear) counts as moved; the filter must move some.
MOVED = 1e-3


def main(out: str) -> int:
    os.makedirs(out, exist_ok=True)
    a = types.SimpleNamespace(width=SIZE, height=SIZE, threads=2, timeout=600.0)
    images = {"off": [], "on": []}
    for seed in SEEDS:
        off = os.path.join(out, f"knit_cotton_filter_off_{seed}.xml")
        ev.cycles_scene(["--preset", "cotton", "--model", os.path.join(ev.MODELS, "cotton.json"),
                         *ev.patch_scene_args(out, "knit"), "--width", str(SIZE), "--height", str(SIZE), "--seed",
                         str(seed), "--out", off])
        text = open(off).read()
        if len(re.findall(r'filter_glossy="0"', text)) != 1:
            print("filter_glossy: the scene does not set filter_glossy=\"0\" once", file=sys.stderr)
            return 1
        on = os.path.join(out, f"knit_cotton_filter_on_{seed}.xml")
        open(on, "w").write(text.replace('filter_glossy="0"', 'filter_glossy="1"'))
        for name, scene in (("off", off), ("on", on)):
            exr = os.path.join(out, f"knit_cotton_filter_{name}_{seed}.exr")
            ev.render(a, scene, SPP, exr, f"filter {name}, seed {seed}", finite=False)
            img = read_exr(exr)[..., :3]
            if not np.isfinite(img).all() or (img < 0).any():
                print(f"filter_glossy: non-finite or negative pixels with the filter {name} (seed {seed})",
                      file=sys.stderr)
                return 1
            images[name].append(img)
    moved = int((np.abs(images["on"][0] - images["off"][0]).max(axis=2) > MOVED).sum())
    m_off, m_on = (np.mean([img.mean(axis=(0, 1)) for img in images[k]], axis=0) for k in ("off", "on"))
    rel = m_on / m_off - 1.0
    print(f"filter_glossy: {moved} of {SIZE * SIZE} pixels moved (seed 1); frame mean over seeds {SEEDS}, on/off - 1: "
          + " / ".join(f"{100 * r:+.2f} %" for r in rel))
    if moved == 0:
        print("filter_glossy: the filter changed no pixel: the closure ignores Cycles' bsdf_blur", file=sys.stderr)
        return 1
    if np.abs(rel).max() > TOLERANCE:
        print(f"filter_glossy: the frame mean moved by more than {100 * TOLERANCE:g} %", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    cycles_check.run(main, __doc__)
