# SPDX-License-Identifier: Apache-2.0
"""Training draws of one recipe: how far each model is from its maps in what a camera sees, and in renders
(docs/decisions.md D53; docs/benchmarks.md "The M network's draws").

Trains models on one map file with several training seeds (`neuralyarn train --train-seed N`) and, for them and
any model files given, prints:
  * the 4D M lobe L1 against the training maps (`neuralyarn check --json`);
  * the fit: the yarn scene of an evaluation run (scripts/evaluate.sh, method yarns: one straight curve) predicted
    without noise with the model and with the maps as its scattering (`cycles-scene --predict-region
    --predict-maps`), model / maps - 1 per channel, under every distant light (--fit-lights); against the
    training maps and, with --maps-b, an independent gather of the same yarn;
  * the render: the run's scenes with the model swapped in, whole-frame mean colour error per channel and
    HDR-FLIP against the run's reference A (and the mean error against the mean of references A and B);
and the maps' own prediction against references A and B (what no network changes: the far field's error and
the references' noise).

  bash scripts/evaluate.sh --out build/eval_m --scenes yarn --methods yarns --presets fleece \\
      --lights back grazing axis --distances 120 --spp 64 --ref-spp 512
  .venv/bin/python scripts/model_draws.py --maps MAPS.nyrdm --maps-b MAPS_B.nyrdm --eval build/eval_m \\
      --preset fleece --lights back grazing axis --seeds 11 12 13 --models models/fleece_yarn.json \\
      --out build/draws -- --m-widths 6-21-21-3 --r-surface-spread 0.6

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


def predict(a, plies: str, model: str) -> dict:
    """The whole frame's mean colour of the yarn scene under each fit light, predicted with `model` ("model")
    and with each map file (its path): {(what, light): rgb}."""
    maps = [a.maps] + ([a.maps_b] if a.maps_b else [])
    out = run([evaluate.CLI, "cycles-scene", "--preset", a.preset, "--plies", plies, "--camera-distance", a.distance,
               "--level", "yarns", "--model", model, "--lights", a.fit_lights[0], "--predict-lights", *a.fit_lights,
               "--width", "160", "--height", "80", "--predict-region", "0", "0", "160", "80", "--predict-maps", *maps,
               "--out", os.path.join(a.out, "predict.xml")])
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
    ap.add_argument("--maps-b", help="an independent map file of the same yarn (another path seed)")
    ap.add_argument("--eval", required=True, help="an evaluation run's directory (its scenes and references)")
    ap.add_argument("--preset", required=True)
    ap.add_argument("--lights", nargs="+", required=True, help="the run's lights to render")
    ap.add_argument("--fit-lights", nargs="+", default=["front", "grazing", "back", "axis"],
                    help="distant-light rigs to predict (default: all four)")
    ap.add_argument("--distance", default="120", help="the scenes' camera distance (default 120)")
    ap.add_argument("--seeds", nargs="*", default=[], type=int, help="training seeds to train and measure")
    ap.add_argument("--models", nargs="*", default=[], help="model files to measure as they are")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--plies", help="the run's straight-yarn plies file (default: the one in its scenes/)")
    ap.add_argument("--out", required=True, help="directory for the models, checks and renders")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    scenes = os.path.join(a.eval, "scenes")
    plies = a.plies or next(os.path.join(scenes, f) for f in sorted(os.listdir(scenes))
                            if re.fullmatch(r"yarn_[0-9.]+\.json", f))
    # Each light's references A and B, read once: A whole (the renders' metrics), both as frame means.
    ref_a = {L: read_exr(os.path.join(a.eval, "refs", f"yarn_{a.preset}_{L}_d{a.distance}_A.exr")) for L in a.lights}
    refs = {L: [ref_a[L].mean(axis=(0, 1)),
                read_exr(os.path.join(a.eval, "refs", f"yarn_{a.preset}_{L}_d{a.distance}_B.exr")).mean(axis=(0, 1))]
            for L in a.lights}
    models = [(os.path.basename(m)[:-5], os.path.abspath(m)) for m in a.models]
    for seed in a.seeds:
        path = os.path.join(a.out, f"seed{seed}.json")
        if not os.path.exists(path):
            print(f"model_draws: training seed {seed}", file=sys.stderr, flush=True)
            run([evaluate.CLI, "train", "--maps", a.maps, "--out", path, "--train-seed", str(seed), *extra])
        models.append((f"seed {seed}", path))
    rows, maps_pred = [], {}
    for name, path in models:
        check = os.path.join(a.out, os.path.basename(path)[:-5] + "_check.json")
        run([evaluate.CLI, "check", path, "--maps", a.maps, "--json", check])
        with open(check) as f:
            row = {"model": name, "M_l1": float(np.mean(json.load(f)["lobes"]["M"]["l1"])), "fit": {}, "fit_b": {},
                   "render": {}}
        p = predict(a, plies, path)
        for L in a.fit_lights:
            row["fit"][L] = list(p[("model", L)] / p[(a.maps, L)] - 1.0)
            if a.maps_b:
                row["fit_b"][L] = list(p[("model", L)] / p[(a.maps_b, L)] - 1.0)
        maps_pred = p
        for light in a.lights:
            with open(os.path.join(scenes, f"yarn_{a.preset}_{light}_d{a.distance}_yarns_seed1.xml")) as f:
                xml = re.sub(r'model="[^"]*"', f'model="{path}"', f.read())
            tag = f"{os.path.basename(path)[:-5]}_{light}"
            with open(os.path.join(a.out, tag + ".xml"), "w") as f:
                f.write(xml)
            exr = os.path.join(a.out, tag + ".exr")
            run([evaluate.CYCLES, "--background", "--quiet", "--samples", str(a.spp), "--threads", str(os.cpu_count()),
                 "--width", "160", "--height", "80", "--output", exr, os.path.join(a.out, tag + ".xml")])
            img = read_exr(exr)
            m = evaluate.metrics(img, ref_a[light], (slice(None), slice(None)))
            row["render"][light] = {"error": m["mean_colour_error_frame"], "flip": m["flip"],
                                    "error_ab": list(img.mean(axis=(0, 1)) / (0.5 * (refs[light][0] + refs[light][1])) - 1)}
        rows.append(row)
        print(f"model_draws: {name} done", file=sys.stderr, flush=True)
    with open(os.path.join(a.out, "draws.json"), "w") as f:
        json.dump(rows, f, indent=1)

    def mean_abs(d: dict) -> float:
        return 100 * float(np.mean([abs(x) for v in d.values() for x in v]))

    print("Fit: the yarn scene predicted with the model over the maps' prediction, R / G / B %")
    print("| model | M 4D L1 % | " + " | ".join(a.fit_lights) + " | mean \\|fit\\| % | against maps B |")
    print("|---|---|" + "---|" * len(a.fit_lights) + "---|---|")
    for r in rows:
        against_b = f"{mean_abs(r['fit_b']):.1f}" if a.maps_b else "—"
        print(f"| {r['model']} | {100 * r['M_l1']:.1f} | " + " | ".join(rgb(r["fit"][L]) for L in a.fit_lights) +
              f" | {mean_abs(r['fit']):.1f} | {against_b} |")
    print("\nRender: whole frame against reference A, R / G / B %, FLIP")
    print("| model | " + " | ".join(a.lights) + " | mean \\|err\\| % (A; mean of A and B) |")
    print("|---|" + "---|" * len(a.lights) + "---|")
    for r in rows:
        cells = [f"{rgb(r['render'][L]['error'])}, {r['render'][L]['flip']:.3f}" for L in a.lights]
        err_a = mean_abs({L: r["render"][L]["error"] for L in a.lights})
        err_ab = mean_abs({L: r["render"][L]["error_ab"] for L in a.lights})
        print(f"| {r['model']} | " + " | ".join(cells) + f" | {err_a:.1f}; {err_ab:.1f} |")
    print()
    for L in a.lights:
        m, (ra, rb) = maps_pred[(a.maps, L)], refs[L]
        print(f"maps' prediction, {L}: against reference A {rgb(m / ra - 1)} %, against B {rgb(m / rb - 1)} %; "
              f"reference B against A {rgb(rb / ra - 1)} %")
    if a.maps_b:
        for L in a.fit_lights:
            print(f"maps B's prediction against the maps', {L}: {rgb(maps_pred[(a.maps_b, L)] / maps_pred[(a.maps, L)] - 1)} %")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
