# SPDX-License-Identifier: Apache-2.0
"""The close-up's fitting error lobe by lobe, for two sets of models side by side (issue 17, decisions D38):

    .venv/bin/python scripts/bench_lobe_split.py --before OLD_MODELS_DIR [--after models] [--maps build/bench_lobes]
        [--region centre|frame]

For each preset and distant light (front, grazing, back, axis), over the central region of the 160 x 80
close-up (evaluate.py's: columns 40-119, rows 34-45) or the whole frame, the model's image mean predicted without a renderer
(bench_split.predict with `--predict-lobes R|M|RM`) against the mean of two independent maps' predictions
(MAPS/<preset>_3001_L<K>.nyrdm and _3002_L<K>.nyrdm, the maps of scripts/bench_lobes.sh over the --after
model's K cross-sections): Rec. 709 luminance, relative;
the worst channel of the whole (R + M) after the change; the maps' own A/B difference. "—" where the maps hold
no light of that lobe. Which lobe a fitting error is in, and what a change of the models did to it; D36
showed Cycles renders the prediction within 0.1 %. A benchmark: prints a Markdown table; never a test.
"""
from __future__ import annotations

import argparse
import json
import os

from bench_split import predict, rel, worst
from evaluate import CLOSEUP_DISTANCE, CLOSEUP_FOV, PRESETS, central_region
from images import LUMINANCE

LIGHTS = ["front", "grazing", "back", "axis"]
SIZE = (160, 80)
REGIONS = {"centre": central_region(CLOSEUP_DISTANCE, CLOSEUP_FOV, *SIZE),  # rows, columns
           "frame": (slice(0, SIZE[1]), slice(0, SIZE[0]))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", required=True, help="directory of the models before (<preset>.json)")
    ap.add_argument("--after", default="models", help="directory of the models after (default: models)")
    ap.add_argument("--maps", default=os.path.join("build", "bench_lobes"), help="the two maps per preset")
    ap.add_argument("--presets", nargs="+", default=PRESETS, choices=PRESETS)
    ap.add_argument("--region", default="centre", choices=sorted(REGIONS),
                    help="the central region (default) or the whole frame, whose light under a back light is mostly "
                         "in the silhouettes")
    args = ap.parse_args()
    region = REGIONS[args.region]
    print("| preset | light | R before | R after | M before | M after | R + M before | R + M after (worst channel) "
          "| maps A/B |")
    print("|---|---|---|---|---|---|---|---|---|")
    for preset in args.presets:
        with open(os.path.join(args.after, f"{preset}.json")) as f:
            layouts = json.load(f)["provenance"]["maps"].get("layouts", 1)
        maps = [os.path.join(args.maps, f"{preset}_{seed}_L{layouts}.nyrdm") for seed in (3001, 3002)]
        res = {(tag, lobes): predict(preset, LIGHTS, SIZE, region, maps, {}, os.path.join(d, f"{preset}.json"), lobes)
               for tag, d in (("before", args.before), ("after", args.after)) for lobes in ("R", "M", "RM")}
        for light in LIGHTS:
            cells = []
            for lobes in ("R", "M", "RM"):
                for tag in ("before", "after"):
                    p = res[(tag, lobes)]
                    mean = 0.5 * (p[(light, "maps_A")] + p[(light, "maps_B")])
                    if mean @ LUMINANCE <= 1e-9:
                        cells.append("—")
                        continue
                    e = 100 * rel(p[(light, "model")], mean)
                    cells.append(f"**{e:+.1f}** ({100 * worst(p[(light, 'model')], mean):+.0f})"
                                 if lobes == "RM" and tag == "after" else f"{e:+.1f}")
            p = res[("after", "RM")]
            print(f"| {preset} | {light} | " + " | ".join(cells) +
                  f" | {100 * rel(p[(light, 'maps_B')], p[(light, 'maps_A')]):+.1f} |")


if __name__ == "__main__":
    main()
