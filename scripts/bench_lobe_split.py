# SPDX-License-Identifier: Apache-2.0
"""The close-up's fitting error lobe by lobe, for two sets of models side by side (issue 17, decisions D38):

    .venv/bin/python scripts/bench_lobe_split.py --before OLD_MODELS_DIR [--after models] [--maps build/bench_lobes]

For each preset and distant light (front, grazing, back, axis), over the central region of the close-up
(evaluate.py's for the 160 x 80 close-up: columns 40-119, rows 34-45), the model's image mean predicted without a renderer (`neuralyarn cycles-scene
--predict-region --predict-lobes R|M|RM`) against the mean of two independent maps' predictions
(MAPS/<preset>_3001.nyrdm and _3002.nyrdm, the maps of scripts/bench_lobes.sh): Rec. 709 luminance, relative;
the worst channel of the whole (R + M) after the change; the maps' own A/B difference. "—" where the maps hold
no light of that lobe. Which lobe a fitting error is in, and what a change of the models did to it; D36
showed Cycles renders the prediction within 0.1 %. A benchmark: prints a Markdown table; never a test.
"""
from __future__ import annotations

import argparse
import collections
import os
import subprocess
import tempfile

from evaluate import CLI, CLOSEUP_PLY_LENGTH
from images import LUMINANCE

LIGHTS = ("front", "grazing", "back", "axis")
WIDTH, HEIGHT = 160, 80
REGION = (40, 34, 80, 12)  # evaluate.central_region of this close-up, as x, y, w, h


def lum(rgb) -> float:
    return sum(w * c for w, c in zip(LUMINANCE, rgb))


def predict(preset: str, model: str, lobes: str, maps: str) -> dict:
    """{light: {"model": rgb, "A": rgb, "B": rgb}} for one lobe selection."""
    x, y, w, h = REGION
    a, b = (os.path.join(maps, f"{preset}_{seed}.nyrdm") for seed in (3001, 3002))
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run([CLI, "cycles-scene", "--preset", preset, "--model", model, "--out",
                              os.path.join(tmp, "scene.xml"), "--width", str(WIDTH), "--height", str(HEIGHT),
                              "--ply-length", str(CLOSEUP_PLY_LENGTH), "--predict-region", str(x), str(y), str(w),
                              str(h), "--predict-lights", ",".join(LIGHTS), "--predict-lobes", lobes,
                              "--predict-maps", a, "--predict-maps", b],
                             capture_output=True, text=True, check=True).stdout
    result: dict = collections.defaultdict(dict)
    for line in out.splitlines():
        f = line.split()
        if f[0] != "predicted":
            continue
        key = "model" if f[1] == "model" else ("A" if f[6] == a else "B")
        result[f[5]][key] = [float(v) for v in f[2:5]]
    return result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", required=True, help="directory of the models before (<preset>.json)")
    ap.add_argument("--after", default="models", help="directory of the models after (default: models)")
    ap.add_argument("--maps", default=os.path.join("build", "bench_lobes"), help="the two maps per preset")
    ap.add_argument("--presets", nargs="+", default=["fleece", "silk", "polyester", "cotton", "gabardine"])
    args = ap.parse_args()
    print("| preset | light | R before | R after | M before | M after | R + M before | R + M after (worst channel) "
          "| maps A/B |")
    print("|---|---|---|---|---|---|---|---|---|")
    for preset in args.presets:
        res = {(tag, lobes): predict(preset, os.path.join(d, f"{preset}.json"), lobes, args.maps)
               for tag, d in (("before", args.before), ("after", args.after)) for lobes in ("R", "M", "RM")}
        for light in LIGHTS:
            cells = []
            for lobes in ("R", "M", "RM"):
                for tag in ("before", "after"):
                    v = res[(tag, lobes)][light]
                    maps = [(p + q) / 2 for p, q in zip(v["A"], v["B"])]
                    if lum(maps) <= 1e-9:
                        cells.append("—")
                        continue
                    e = 100 * (lum(v["model"]) / lum(maps) - 1)
                    if lobes == "RM" and tag == "after":
                        worst = max((100 * (m / p - 1) for m, p in zip(v["model"], maps) if p > 0), key=abs)
                        cells.append(f"**{e:+.1f}** ({worst:+.0f})")
                    else:
                        cells.append(f"{e:+.1f}")
            v = res[("after", "RM")][light]
            print(f"| {preset} | {light} | " + " | ".join(cells) + f" | {100 * (lum(v['B']) / lum(v['A']) - 1):+.1f} |")


if __name__ == "__main__":
    main()
