# SPDX-License-Identifier: Apache-2.0
"""Splits the native closure's error against explicit fibers into fitting and aggregation (issue 17), per
preset and light, for a finished `scripts/evaluate.sh` run:

    .venv/bin/python scripts/bench_split.py --eval build/eval_fidelity --maps DIR [--json OUT.json]

For each (preset, light) of the run whose light is the environment or a distant-light rig, over the run's
central region (evaluate.py's):
  model      the model's image mean predicted without a renderer (`neuralyarn cycles-scene --predict-region`),
  maps A, B  the same with two independent radiance distribution maps as the ply's scattering
             (DIR/<preset>_A.nyrdm and DIR/<preset>_B.nyrdm, e.g. links to two gathers of other seeds):
             the tabulated far field, the best any far-field model of this ply can do,
  reference  the explicit-fiber reference A of the run (and B, its noise floor),
  native     the run's native render at its first spp and seed.
Columns (Rec. 709 luminance, relative): fitting = model / maps - 1 (maps noise: A / B - 1), aggregation =
reference / maps - 1 (reference noise: B / A - 1), total = native / reference - 1, and integration = native /
model - 1 (Cycles against the prediction of what it renders: ~0 unless the closure's integration is wrong).
The worst channel of fitting and aggregation is printed next to each. With --rows, the same per image row of
the region too, with each row's share of the reference's light (where in the ply an error sits: the rows next
to the silhouette, where the camera ray grazes the ply, or the inner ones); one prediction call per row.
A benchmark: prints a table, writes JSON; never a test.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

from evaluate import CLI, CLOSEUP_PLY_LENGTH, LUMINANCE, central_region, model_path, yarn_args
from images import read_exr

#: The rigs the prediction covers (sphere lights are near-field: not predicted).
PREDICTED = ("environment", "front", "grazing", "back", "axis")


def predict(preset: str, lights: list[str], size: tuple[int, int], region, maps: list[str], yarns: dict,
            model: str | None = None, lobes: str = "RM") -> dict:
    """{(light, "model" | "maps_A" | "maps_B"): RGB} from one `cycles-scene --predict-region` call (each map
    file loaded once for all the lights): of the preset's model (or `model`), R + M (or `lobes`: "R", "M")."""
    rows, cols = region
    args = [CLI, "cycles-scene", *yarn_args(yarns, preset), "--lights", lights[0],
            "--model", model or model_path(yarns, preset), "--predict-lobes", lobes,
            "--width", str(size[0]), "--height", str(size[1]), "--ply-length", f"{CLOSEUP_PLY_LENGTH:g}",
            "--predict-region", str(cols.start), str(rows.start), str(cols.stop - cols.start),
            str(rows.stop - rows.start), "--predict-lights", ",".join(lights),
            "--out", os.path.join(tempfile.gettempdir(), f"ny_split_{os.getpid()}.xml")]
    for m in maps:
        args += ["--predict-maps", m]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"bench_split: {' '.join(args)} failed: {r.stderr.strip()}")
    out = {}
    for m in re.finditer(r"predicted (model|maps) (\S+) (\S+) (\S+) (\S+)(?: (\S+))?", r.stdout):
        key = "model" if m.group(1) == "model" else ("maps_A" if m.group(6) == maps[0] else "maps_B")
        out[(m.group(5), key)] = np.array([float(m.group(k)) for k in (2, 3, 4)])
    return out


def rel(a, b) -> float:
    return float(a @ LUMINANCE / (b @ LUMINANCE) - 1.0)


def worst(a, b) -> float:
    r = a / np.where(b > 0, b, np.nan) - 1.0
    if not np.isfinite(r).any():  # the maps hold nothing in any channel here (a dark ply's inner rows)
        return float("nan")
    return float(r[np.nanargmax(np.abs(r))])


def split_rows(a, res: dict, size, region, preset: str, light: str, refs: dict) -> list[dict]:
    """Fitting and aggregation per image row of the region, with the row's share of reference A's light."""
    rows, cols = region
    maps = [os.path.join(a.maps, f"{preset}_{w}.nyrdm") for w in "AB"]
    ref = refs[(preset, light)]
    ref_a = read_exr(os.path.join(a.eval, ref["image_A"]))[..., :3]
    ref_b = read_exr(os.path.join(a.eval, ref["image_B"]))[..., :3]
    total = float(ref_a[rows, cols].mean(axis=(0, 1)) @ LUMINANCE) * (rows.stop - rows.start)
    print(f"\n{preset}, {light}: per row\n\n| row | share of the light % | fitting % | maps A/B % | aggregation % "
          "| ref B/A % |\n|---|---|---|---|---|---|")
    out = []
    for y in range(rows.start, rows.stop):
        p = predict(preset, [light], size, (slice(y, y + 1), cols), maps, res.get("yarns", {}))
        maps_mean = 0.5 * (p[(light, "maps_A")] + p[(light, "maps_B")])
        ra, rb = ref_a[y, cols].mean(axis=0), ref_b[y, cols].mean(axis=0)
        r = {"row": y, "share": float(ra @ LUMINANCE) / total, "fitting": rel(p[(light, "model")], maps_mean),
             "maps_noise": rel(p[(light, "maps_A")], p[(light, "maps_B")]), "aggregation": rel(ra, maps_mean),
             "reference_noise": rel(rb, ra)}
        out.append(r)
        print(f"| {y} | {100 * r['share']:.1f} | {100 * r['fitting']:+.1f} | {100 * r['maps_noise']:+.1f} | "
              f"{100 * r['aggregation']:+.1f} | {100 * r['reference_noise']:+.1f} |", flush=True)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--eval", required=True, help="output directory of scripts/evaluate.sh (results.json)")
    ap.add_argument("--maps", required=True, help="directory with <preset>_A.nyrdm and <preset>_B.nyrdm")
    ap.add_argument("--json", help="write the rows here too")
    ap.add_argument("--rows", action="store_true", help="also split every image row of the region")
    ap.add_argument("--presets", nargs="+", help="only these presets of the run")
    ap.add_argument("--lights", nargs="+", help="only these lights of the run")
    a = ap.parse_args()
    with open(os.path.join(a.eval, "results.json")) as f:
        res = json.load(f)
    s = res["settings"]
    size = (s["width"], s["height"])
    cam = res["scenes"]["closeup"]
    region = central_region(cam["distance"], cam["fov"], *size)
    refs = {(r["preset"], r["light"]): r for r in res["references"] if not r["failed"]}
    natives = {(r["preset"], r["light"]): r for r in res["runs"]
               if r["method"] == "native" and not r["failed"] and r["seed"] == 1 and r["spp"] == s["spp"][0]}
    rows = []
    print("| preset | light | fitting % (worst ch.) | maps A/B % | aggregation % (worst ch.) | ref B/A % | "
          "total % | integration % |")
    print("|---|---|---|---|---|---|---|---|")
    cells = [(preset, light) for preset, light in refs if light in PREDICTED and (preset, light) in natives
             and (not a.presets or preset in a.presets) and (not a.lights or light in a.lights)]
    predicted = {}
    for preset in dict.fromkeys(p for p, _ in cells):
        maps = [os.path.join(a.maps, f"{preset}_{w}.nyrdm") for w in "AB"]
        lights = [light for p, light in cells if p == preset]
        for (light, key), v in predict(preset, lights, size, region, maps, res.get("yarns", {})).items():
            predicted.setdefault((preset, light), {})[key] = v
    for preset, light in cells:
        ref, p = refs[(preset, light)], predicted[(preset, light)]
        mean = lambda path: read_exr(os.path.join(a.eval, path))[region].mean(axis=(0, 1))  # noqa: E731
        ref_a, ref_b, nat = mean(ref["image_A"]), mean(ref["image_B"]), mean(natives[(preset, light)]["image"])
        maps_mean = 0.5 * (p["maps_A"] + p["maps_B"])
        row = {"preset": preset, "light": light, "model": p["model"].tolist(), "maps_A": p["maps_A"].tolist(),
               "maps_B": p["maps_B"].tolist(), "reference_A": ref_a.tolist(), "reference_B": ref_b.tolist(),
               "native": nat.tolist(),
               "fitting": rel(p["model"], maps_mean), "fitting_worst_channel": worst(p["model"], maps_mean),
               "maps_noise": rel(p["maps_A"], p["maps_B"]),
               "aggregation": rel(ref_a, maps_mean), "aggregation_worst_channel": worst(ref_a, maps_mean),
               "reference_noise": rel(ref_b, ref_a), "total": rel(nat, ref_a), "integration": rel(nat, p["model"])}
        rows.append(row)
        print(f"| {preset} | {light} | {100 * row['fitting']:+.1f} ({100 * row['fitting_worst_channel']:+.0f}) | "
              f"{100 * row['maps_noise']:+.1f} | {100 * row['aggregation']:+.1f} "
              f"({100 * row['aggregation_worst_channel']:+.0f}) | {100 * row['reference_noise']:+.1f} | "
              f"{100 * row['total']:+.1f} | {100 * row['integration']:+.1f} |", flush=True)
    if a.rows:
        for row in rows:
            row["per_row"] = split_rows(a, res, size, region, row["preset"], row["light"], refs)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"command": ["scripts/bench_split.py", *sys.argv[1:]], "eval": res["command"],
                       "settings": s, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
