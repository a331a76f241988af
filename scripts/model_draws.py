# SPDX-License-Identifier: Apache-2.0
"""Training draws of one recipe: how far each model is from its maps in what a camera sees, and in renders
(docs/decisions.md D53, D54; docs/benchmarks.md "The M network's draws", "The ply level's M draws").

Trains models on one map file with several training seeds (`neuralyarn train --train-seed N`) and, for them and
any model files given, prints:
  * the 4D M lobe L1 against the training maps (`neuralyarn check --json`);
  * the fit: the scene predicted without noise with the model and with the maps as its scattering
    (`cycles-scene --predict-region --predict-maps`), model / maps - 1 per channel, under every distant light
    (--fit-lights), over the whole frame (and, for the close-up, its central region too); against the training
    maps and, with --maps-b, an independent gather of the same yarn or ply. The scene (--scene) is the yarn level's
    straight yarn of an evaluation run (method yarns: one straight curve) or the ply level's close-up (one ply);
  * with --eval, the render: the run's scenes with the model swapped in, mean colour error per channel (whole
    frame; the close-up's central region too) and HDR-FLIP against the run's reference A (and the mean error
    against the mean of references A and B);
and the maps' own prediction against references A and B (what no network changes: the far field's error and
the references' noise). With --noise-maps (two more independent gathers, as a bake's check gathers) and two
--maps-b files it also prints the noise-weighted scores of D56: each cell weighted by 1 / sqrt(s^2 + floor^2), s the
relative standard error of what the model is compared with.

  bash scripts/evaluate.sh --out build/eval_m --scenes yarn --methods yarns --presets fleece \\
      --lights back grazing axis --distances 120 --spp 64 --ref-spp 512
  .venv/bin/python scripts/model_draws.py --maps MAPS.nyrdm --maps-b MAPS_B.nyrdm --eval build/eval_m \\
      --preset fleece --lights back grazing axis --seeds 11 12 13 --models models/fleece_yarn.json \\
      --out build/draws -- --m-widths 6-21-21-3 --r-surface-spread 0.6
  # the ply level, predictions only (no --eval):
  .venv/bin/python scripts/model_draws.py --scene closeup --maps TRAIN.nyrdm --maps-b B.nyrdm --preset polyester \\
      --seeds 11 12 13 --models models/polyester.json --out build/draws_ply -- --m-widths 6-21-21-6

Everything is seeded (training, renders), so a rerun prints the same tables.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from images import read_exr  # noqa: E402
import evaluate  # noqa: E402


def run(cmd: list[str]) -> str:
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"model_draws: {' '.join(cmd)} failed:\n{r.stderr.strip()}")
    return r.stdout


SIZE = (160, 80)  # the evaluation run's image


def regions(centre: tuple[slice, slice] | None) -> dict:
    """The predicted regions as cycles-scene's --predict-region (x, y, w, h): the whole frame, and for the close-up
    its central region (evaluate.central_region: what issue 17's goals are measured over)."""
    out = {"frame": (0, 0, *SIZE)}
    if centre is not None:
        rows, cols = centre
        out["centre"] = (cols.start, rows.start, cols.stop - cols.start, rows.stop - rows.start)
    return out


def predict(a, scene_args: list[str], model: str, region: tuple, maps: list[str]) -> dict:
    """The region's mean colour under each fit light, predicted with `model` ("model") and with each map file in
    `maps` (its path): {(what, light): rgb}. The maps' predictions do not depend on the model (it only makes the
    scene one curve), so they are asked for once per region, not with every model."""
    out = run([evaluate.CLI, "cycles-scene", "--preset", a.preset, *scene_args, "--model", model,
               "--lights", a.fit_lights[0], "--predict-lights", *a.fit_lights, "--width", str(SIZE[0]),
               "--height", str(SIZE[1]), "--predict-region", *map(str, region),
               *(["--predict-maps", *maps] if maps else []), "--out", os.path.join(a.out, "predict.xml")])
    got = {}
    for line in out.splitlines():
        f = line.split()
        if f[:1] == ["predicted"]:
            got[(f[1] if f[1] == "model" else f[6], f[5])] = np.array([float(x) for x in f[2:5]])
    return got


def rgb(v) -> str:
    return " / ".join(f"{100 * x:+.1f}" for x in v)


def main(argv: list[str]) -> int:
    extra = []
    if "--" in argv:
        extra, argv = argv[argv.index("--") + 1:], argv[:argv.index("--")]
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog="after --: options of neuralyarn train")
    ap.add_argument("--maps", required=True, help="map file to train on and to check against")
    ap.add_argument("--maps-b", nargs="*", default=[],
                    help="independent map files of the same yarn (other path seeds): 'maps B' is their mean")
    ap.add_argument("--noise-maps", nargs="*", default=[],
                    help="two more independent map files of the same yarn (the bake's check gathers): each cell's "
                         "noise, for the noise-weighted scores (D56)")
    ap.add_argument("--noise-floor", type=float, default=0.05,
                    help="relative noise below which a cell's weight no longer grows (default 0.05: the goal's 5 %%)")
    ap.add_argument("--scene", choices=["yarn", "closeup"], default="yarn",
                    help="the yarn level's straight yarn (default) or the ply level's close-up")
    ap.add_argument("--eval", help="an evaluation run's directory (its scenes and references): render the models "
                                   "in its scenes; without it, predictions only")
    ap.add_argument("--preset", required=True)
    ap.add_argument("--lights", nargs="+", default=[], help="the run's lights to render (with --eval)")
    ap.add_argument("--fit-lights", nargs="+", default=["front", "grazing", "back", "axis"],
                    help="distant-light rigs to predict (default: all four)")
    ap.add_argument("--distance", default="120", help="the yarn scenes' camera distance (default 120)")
    ap.add_argument("--seeds", nargs="*", default=[], type=int, help="training seeds to train and measure")
    ap.add_argument("--models", nargs="*", default=[], help="model files to measure as they are")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--plies", help="the yarn scene's straight-yarn plies file (default: the --eval run's, or the "
                                    "harness's own)")
    ap.add_argument("--out", required=True, help="directory for the models, checks and renders")
    a = ap.parse_args(argv)

    def maps_b_mean(p: dict, light: str) -> np.ndarray:
        return np.mean([p[(m, light)] for m in a.maps_b], axis=0)
    if a.noise_maps and len(a.noise_maps) != 2:
        ap.error("--noise-maps takes two map files")
    if a.lights and not a.eval:
        ap.error("--lights renders in an evaluation run's scenes: give --eval")
    os.makedirs(os.path.join(a.out, "scenes"), exist_ok=True)
    size = argparse.Namespace(width=SIZE[0], height=SIZE[1])  # what evaluate.ply_length reads of a run
    if a.scene == "yarn":
        scenes = os.path.join(a.eval, "scenes") if a.eval else None
        plies = a.plies or (next(os.path.join(scenes, f) for f in sorted(os.listdir(scenes))
                                 if re.fullmatch(r"yarn_[0-9.]+\.json", f)) if scenes
                            else evaluate.straight_yarn_file(a.out, evaluate.ply_length(float(a.distance), size)))
        scene_args = ["--plies", plies, "--camera-distance", a.distance, "--level", "yarns"]
        stem, method = f"yarn_{a.preset}_{{light}}_d{a.distance}", "yarns"
    else:
        scene_args = ["--ply-length", f"{evaluate.ply_length(evaluate.CLOSEUP_DISTANCE, size):g}"]
        stem, method = f"closeup_{a.preset}_{{light}}", "native"
    closeup_centre = evaluate.central_region(evaluate.CLOSEUP_DISTANCE, evaluate.CLOSEUP_FOV, *SIZE) \
        if a.scene == "closeup" else None
    where = regions(closeup_centre)
    # Each light's references A and B, read once: A whole (the renders' metrics), both as region means.
    ref_a = {L: read_exr(os.path.join(a.eval, "refs", stem.format(light=L) + "_A.exr")) for L in a.lights}
    ref_b = {L: read_exr(os.path.join(a.eval, "refs", stem.format(light=L) + "_B.exr")) for L in a.lights}
    centre = closeup_centre or (slice(None), slice(None))  # the renders' region (the yarn scene: its frame)
    models = [(os.path.basename(m)[:-5], os.path.abspath(m)) for m in a.models]
    for seed in a.seeds:
        path = os.path.join(a.out, f"seed{seed}.json")
        if not os.path.exists(path):
            print(f"model_draws: training seed {seed}", file=sys.stderr, flush=True)
            run([evaluate.CLI, "train", "--maps", a.maps, "--out", path, "--train-seed", str(seed), *extra])
        models.append((f"seed {seed}", path))
    # Every map file (~200 MB each) read once per region, with the first model making the scene one curve.
    maps_pred = {region_name: predict(a, scene_args, models[0][1], region, [a.maps] + a.maps_b + a.noise_maps)
                 for region_name, region in where.items()} if models else {}
    rows = []
    for name, path in models:
        check = os.path.join(a.out, os.path.basename(path)[:-5] + "_check.json")
        run([evaluate.CLI, "check", path, "--maps", a.maps, "--json", check])
        with open(check) as f:
            row = {"model": name, "M_l1": float(np.mean(json.load(f)["lobes"]["M"]["l1"])), "fit": {}, "fit_b": {},
                   "render": {}}
        for region_name, region in where.items():
            p = {**maps_pred[region_name], **predict(a, scene_args, path, region, [])}
            row["fit"][region_name], row["fit_b"][region_name] = {}, {}
            for L in a.fit_lights:
                row["fit"][region_name][L] = list(p[("model", L)] / p[(a.maps, L)] - 1.0)
                if a.maps_b:
                    row["fit_b"][region_name][L] = list(p[("model", L)] / maps_b_mean(p, L) - 1.0)
        for light in a.lights:
            with open(os.path.join(a.eval, "scenes", stem.format(light=light) + f"_{method}_seed1.xml")) as f:
                xml = re.sub(r'model="[^"]*"', f'model="{path}"', f.read())
            tag = f"{os.path.basename(path)[:-5]}_{light}"
            with open(os.path.join(a.out, tag + ".xml"), "w") as f:
                f.write(xml)
            exr = os.path.join(a.out, tag + ".exr")
            run([evaluate.CYCLES, "--background", "--quiet", "--samples", str(a.spp), "--threads", str(os.cpu_count()),
                 "--width", str(SIZE[0]), "--height", str(SIZE[1]), "--output", exr, os.path.join(a.out, tag + ".xml")])
            img = read_exr(exr)
            m = evaluate.metrics(img, ref_a[light], centre)
            ab = 0.5 * (ref_a[light] + ref_b[light])
            row["render"][light] = {"error": m["mean_colour_error_frame"], "error_centre": m["mean_colour_error"],
                                    "flip": m["flip"],
                                    "error_ab": list(img.mean(axis=(0, 1)) / ab.mean(axis=(0, 1)) - 1),
                                    "error_ab_centre": list(img[centre].mean(axis=(0, 1)) / ab[centre].mean(axis=(0, 1)) - 1)}
        rows.append(row)
        print(f"model_draws: {name} done", file=sys.stderr, flush=True)
    with open(os.path.join(a.out, "draws.json"), "w") as f:
        json.dump(rows, f, indent=1)

    def mean_abs(d: dict) -> float:
        return 100 * float(np.mean([abs(x) for v in d.values() for x in v]))

    for region_name in where:
        print(f"Fit ({region_name}): the {a.scene} scene predicted with the model over the maps' prediction, R / G / B %")
        print("| model | M 4D L1 % | " + " | ".join(a.fit_lights) + " | mean \\|fit\\| % | against maps B |")
        print("|---|---|" + "---|" * len(a.fit_lights) + "---|---|")
        for r in rows:
            fit, fit_b = r["fit"][region_name], r["fit_b"][region_name]
            against_b = f"{mean_abs(fit_b):.1f}" if a.maps_b else "—"
            print(f"| {r['model']} | {100 * r['M_l1']:.1f} | " + " | ".join(rgb(fit[L]) for L in a.fit_lights) +
                  f" | {mean_abs(fit):.1f} | {against_b} |")
        print()
    def all_regions(by_region: dict) -> float:
        """mean_abs over every region's lights and channels (each region holds as many)."""
        return mean_abs({reg: sum(by_light.values(), []) for reg, by_light in by_region.items()})

    if len(where) > 1:
        print("All regions: mean |fit| % over " + ", ".join(where) + " (the --m-choice image-centre score x 100) "
              "against the training maps; against maps B")
        for r in rows:
            print(f"  {r['model']}: {all_regions(r['fit']):.2f}; " + (f"{all_regions(r['fit_b']):.2f}" if a.maps_b else "—"))
        print()
    if a.noise_maps or len(a.maps_b) == 2:
        def rel_noise(p: dict, pair: list[str], target: np.ndarray, scale: float, L: str) -> np.ndarray:
            """A cell's relative standard error: two independent gathers differ by sqrt(2) sigma of one; `scale`
            takes that sigma to the target's paths."""
            return np.abs(p[(pair[0], L)] - p[(pair[1], L)]) / np.sqrt(2.0) * scale / np.maximum(target, 1e-30)

        def weighted(r: dict, key: str, pair: list[str], scale: float, target) -> float:
            num = den = 0.0
            for reg, p in maps_pred.items():
                for L in a.fit_lights:
                    w = 1.0 / np.sqrt(rel_noise(p, pair, target(p, L), scale, L) ** 2 + a.noise_floor ** 2)
                    num += float(np.sum(w * np.abs(r[key][reg][L])))
                    den += float(np.sum(w))
            return 100 * num / den

        n_train = int(evaluate.map_gather(a.maps)["paths"])
        n_noise = int(evaluate.map_gather(a.noise_maps[0])["paths"]) if a.noise_maps else 0
        print(f"Noise-weighted (D56): each cell weighted 1 / sqrt(s^2 + {a.noise_floor:g}^2), s the relative noise of "
              "what it is compared with; against the training maps (s from --noise-maps); against maps B (s from "
              "its two files)")
        for r in rows:
            t = (f"{weighted(r, 'fit', a.noise_maps, np.sqrt(n_noise / n_train), lambda p, L: p[(a.maps, L)]):.2f}"
                 if a.noise_maps else "—")
            b = (f"{weighted(r, 'fit_b', a.maps_b, np.sqrt(0.5), maps_b_mean):.2f}" if len(a.maps_b) == 2 else "—")
            print(f"  {r['model']}: {t}; {b}")
        print()
    if a.maps_b:
        # The maps' own disagreement in the same mean: a model closer to B by less than this is not told apart (D54).
        gap = {reg: [x for L in a.fit_lights for x in maps_b_mean(p, L) / p[(a.maps, L)] - 1.0]
               for reg, p in maps_pred.items()}
        print("maps B against the maps, mean |B / maps - 1| %: " +
              ", ".join(f"{reg} {mean_abs({reg: v}):.2f}" for reg, v in gap.items()) +
              f", all {mean_abs(gap):.2f}")
        print()
    for key, label in (("error", "whole frame"), ("error_centre", "central region")) if a.lights else ():
        if key == "error_centre" and a.scene != "closeup":
            continue
        ab_key = "error_ab" if key == "error" else "error_ab_centre"
        print(f"Render: {label} against reference A, R / G / B %, FLIP")
        print("| model | " + " | ".join(a.lights) + " | mean \\|err\\| % (A; mean of A and B) |")
        print("|---|" + "---|" * len(a.lights) + "---|")
        for r in rows:
            cells = [f"{rgb(r['render'][L][key])}, {r['render'][L]['flip']:.3f}" for L in a.lights]
            err_a = mean_abs({L: r["render"][L][key] for L in a.lights})
            err_ab = mean_abs({L: r["render"][L][ab_key] for L in a.lights})
            print(f"| {r['model']} | " + " | ".join(cells) + f" | {err_a:.1f}; {err_ab:.1f} |")
        print()
    frame = maps_pred.get("frame", {})
    for L in a.lights:
        m, ra, rb = frame[(a.maps, L)], ref_a[L].mean(axis=(0, 1)), ref_b[L].mean(axis=(0, 1))
        print(f"maps' prediction (frame), {L}: against reference A {rgb(m / ra - 1)} %, against B {rgb(m / rb - 1)} %; "
              f"reference B against A {rgb(rb / ra - 1)} %")
    if a.maps_b:
        for region_name, p in maps_pred.items():
            for L in a.fit_lights:
                print(f"maps B's prediction against the maps' ({region_name}), {L}: "
                      f"{rgb(maps_b_mean(p, L) / p[(a.maps, L)] - 1)} %")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
