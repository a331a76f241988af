# SPDX-License-Identifier: Apache-2.0
"""FLIP split into fitting and aggregation: how close any far-field model of a ply can come to explicit fibers in
HDR-FLIP, and how much of a model's FLIP its fit to the maps adds (issue 17; docs/benchmarks.md "FLIP's split").

The close-up's whole image is predicted without noise (`cycles-scene --predict-image`, decisions D20) with each
model and with the radiance distribution maps themselves — what a tabulated closure renders — and compared
with an evaluation run's explicit-fiber references A and B:

  * floor: FLIP(B, A), the harness's noise floor (two noisy images);
  * perfect: what a noise-free image without error scores against a reference as noisy as A — FLIP(m, max(m + n,
    0)) with m the first model's prediction standing in for the truth and n = (A - B) / sqrt 2, A's noise (FLIP
    weighs a smooth image against a grainy one otherwise than two grainy ones: this, not the floor, is the best a
    noise-free method can score);
  * maps: FLIP(maps' prediction, A), nearest bin and interpolated between the bins' centres — the aggregation
    error (far field, the maps' bins) plus A's noise and the maps' own: "maps A/B" is FLIP between the first two
    map files' predictions (their own noise), so the maps bound what a far-field model scores only where it is
    small;
  * each model: FLIP(its prediction, A), and FLIP(its prediction, the maps' prediction) — the fitting error alone,
    both noise-free; and, where given, FLIP of its render (the run's native render or --renders) against A;
  * with --ladder: FLIP of the path-weighted mean of the first k map files' predictions (k = 1 ... K, the files in
    the order given, so smallest first), and F(N) = F_inf + b / sqrt(N) fitted to them: the far field's FLIP at
    N paths and without the maps' noise, extrapolated (the aggregation error's own FLIP) — trustworthy only while the
    last step moves FLIP as the fit says: where the curve has flattened, its last value is the far field's FLIP;
  * profiles: the rms (%, luminance) of an image's row means over the ply's rows against A's (across the ply), and
    of its 10-pixel blocks along the ply over those rows (along it), for B, the maps (interpolated) and each model;
    and each model's FLIP with its row means replaced by the maps' (how much a right profile across the ply
    would give).

  .venv/bin/python scripts/bench_flip_split.py --eval build/eval_gabardine_axis --preset gabardine --lights axis \\
      --maps TRAIN.nyrdm build/bench_lobes/gabardine_3001_L32.nyrdm build/bench_lobes/gabardine_3002_L32.nyrdm \\
      --models SHIPPED.json models/gabardine.json --out build/flip_split
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from images import LUMINANCE, read_exr  # noqa: E402
import evaluate  # noqa: E402

SIZE = (160, 80)  # the close-up's image (evaluate.py DEFAULTS)


def ply_rows() -> slice:
    """The ply's rows: the central region's and the silhouette row it leaves out on each side."""
    rows, _ = evaluate.ply_band(evaluate.central_region(evaluate.CLOSEUP_DISTANCE, evaluate.CLOSEUP_FOV, *SIZE))
    return rows


def bands() -> dict:
    """The frame's rows in three parts: the silhouettes (two rows either side of the ply's first and last row,
    where the pixel filter mixes ply and background and camera rays graze it), the interior between them, and the
    background."""
    rows = ply_rows()
    top, bottom = rows.start, rows.stop - 1
    silhouette = [r for r in range(SIZE[1]) if abs(r - top) <= 2 or abs(r - bottom) <= 2]
    return {"silhouette": silhouette, "interior": list(range(top + 3, bottom - 2)),
            "background": [r for r in range(SIZE[1]) if r < top - 2 or r > bottom + 2]}


def flip(test: np.ndarray, ref: np.ndarray) -> dict:
    """Mean HDR-FLIP over the frame, and each band's share of it (the shares add up to the mean)."""
    import flip_evaluator
    error, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(ref, dtype=np.float32),
                                             np.ascontiguousarray(test, dtype=np.float32), "HDR", applyMagma=False,
                                             parameters={"ppd": evaluate.FLIP_PPD})
    error = np.asarray(error).reshape(ref.shape[:2])
    return {"mean": float(mean), **{b: float(error[rows].sum() / error.size) for b, rows in bands().items()}}


def profile_errors(img: np.ndarray, ref: np.ndarray) -> dict:
    """rms of the relative luminance error of the row means over the ply's rows (across) and of the 10-pixel
    blocks along the ply over them (along), %."""
    rows = ply_rows()

    def rms(a, b):
        return float(100.0 * np.sqrt(np.mean((a / b - 1.0) ** 2)))

    def blocks(x):
        return np.array([(x[rows, c:c + 10] @ LUMINANCE).mean() for c in range(0, x.shape[1], 10)])
    return {"across": rms(img[rows].mean(axis=1) @ LUMINANCE, ref[rows].mean(axis=1) @ LUMINANCE),
            "along": rms(blocks(img), blocks(ref))}


def with_row_means(img: np.ndarray, of: np.ndarray) -> np.ndarray:
    """img with each row's mean colour replaced by `of`'s (a black row stays black)."""
    mine, theirs = img.mean(axis=1, keepdims=True), of.mean(axis=1, keepdims=True)
    return img * np.where(mine > 0.0, theirs / np.where(mine > 0.0, mine, 1.0), 1.0)


def ladder_paths(files: list[str]) -> list[int]:
    """The map files' paths, read from their headers; two files of one path seed are refused before any work (path
    k's random stream is (seed, k): they share their first paths)."""
    gathers = [evaluate.map_gather(f) for f in files]
    seeds = [g["seed"] for g in gathers]
    if len(set(seeds)) != len(seeds):
        sys.exit(f"bench_flip_split: --ladder needs independent maps, but path seeds repeat: {seeds}")
    return [int(g["paths"]) for g in gathers]


def ladder(paths: list[int], nearest: list[np.ndarray], interpolated: list[np.ndarray], ref: np.ndarray) -> dict:
    """FLIP of the path-weighted mean of the first k maps' images against `ref`, k = 1 ... K, and the least-squares
    fit F(N) = F_inf + b / sqrt(N) over them: an image's noise falls as 1 / sqrt(N), and FLIP with it."""
    steps = []
    for k in range(1, len(paths) + 1):
        w = np.array(paths[:k], dtype=float) / sum(paths[:k])
        step = {"files": k, "paths": float(sum(paths[:k]))}
        for kind, images in (("nearest", nearest), ("interpolated", interpolated)):
            step[kind] = flip(sum(wi * im for wi, im in zip(w, images[:k])), ref)["mean"]
        steps.append(step)
    fit = {}
    x = np.array([1.0 / math.sqrt(s["paths"]) for s in steps])
    for kind in ("nearest", "interpolated"):
        y = np.array([s[kind] for s in steps])
        A = np.stack([np.ones_like(x), x], axis=1)
        (f_inf, b), *_ = np.linalg.lstsq(A, y, rcond=None)
        fit[kind] = {"F_inf": float(f_inf), "b": float(b), "rms": float(np.sqrt(np.mean((A @ [f_inf, b] - y) ** 2)))}
    return {"steps": steps, "fit": fit}


def cell(f: dict | None) -> str:
    return f"{f['mean']:.3f} ({f['silhouette']:.3f} / {f['interior']:.3f})" if f else ""


def predicted(a, prefix: str, model: str, maps: list[str], interpolate: bool = False) -> dict:
    """{(what, light): image}: what is "model" or the index of a map file (1, 2, ...). The model also makes the
    scene one curve (without it cycles-scene writes explicit fibers)."""
    size = argparse.Namespace(width=SIZE[0], height=SIZE[1])
    cmd = [evaluate.CLI, "cycles-scene", "--preset", a.preset,
           "--ply-length", f"{evaluate.ply_length(evaluate.CLOSEUP_DISTANCE, size):g}", "--lights", a.lights[0],
           "--predict-lights", *a.lights, "--width", str(SIZE[0]), "--height", str(SIZE[1]),
           "--predict-image", prefix, "--model", model, "--out", prefix + ".xml"]
    if maps:
        cmd += ["--predict-maps", *maps] + (["--predict-interpolate"] if interpolate else [])
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"bench_flip_split: {' '.join(cmd)} failed:\n{r.stderr}")
    out = {}
    for line in r.stdout.splitlines():
        f = line.split()
        if f[:2] == ["predicted", "image"]:
            what = "model" if f[2] == "model" else int(f[2][4:])
            out[(what, f[3])] = read_exr(line.split(" ", 4)[4])
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--eval", required=True, help="an evaluation run of the close-up (its refs/ and renders/)")
    ap.add_argument("--preset", required=True)
    ap.add_argument("--lights", nargs="+", required=True, help="distant lights or environment of that run")
    ap.add_argument("--maps", nargs="+", required=True,
                    help="map files of the ply: their predictions' mean is 'the maps' (the first two also give the "
                         "maps' own noise)")
    ap.add_argument("--models", nargs="+", required=True, help="model files")
    ap.add_argument("--renders", nargs="*", default=[],
                    help="with one light: per model, its render (an EXR, e.g. model_draws.py --eval's) or '-' for "
                         "none; without it the run's own native render goes with the first model")
    ap.add_argument("--ladder", action="store_true",
                    help="also FLIP of the path-weighted mean of the first k map files, k = 1 ... K, and its "
                         "extrapolation to infinitely many paths (give the files smallest first)")
    ap.add_argument("--out", required=True, help="directory for the predicted images and results.json")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    stem = f"closeup_{a.preset}_{{light}}"
    if a.renders and (len(a.lights) != 1 or len(a.renders) != len(a.models)):
        ap.error("--renders: one light, and one render or '-' per model")
    files = [os.path.abspath(m) for m in a.maps]
    paths = ladder_paths(files) if a.ladder else []
    maps = predicted(a, os.path.join(a.out, "maps"), os.path.abspath(a.models[0]), files)
    interp = predicted(a, os.path.join(a.out, "maps_interpolated"), os.path.abspath(a.models[0]), files, True)
    results, shared = {}, {}
    for light in a.lights:
        ref_a, ref_b = (read_exr(os.path.join(a.eval, "refs", stem.format(light=light) + f"_{r}.exr")) for r in "AB")
        nearest = [maps[(k + 1, light)] for k in range(len(files))]
        interpolated = [interp[(k + 1, light)] for k in range(len(files))]
        mean_maps, mean_interp = np.mean(nearest, axis=0), np.mean(interpolated, axis=0)
        # Read and averaged once; every model is compared with them.
        shared[light] = (ref_a, ref_b, mean_maps, mean_interp)
        two = len(a.maps) > 1
        row = {"floor": flip(ref_b, ref_a),
               "maps": flip(mean_maps, ref_a), "maps_interpolated": flip(mean_interp, ref_a),
               "maps_ab": flip(maps[(2, light)], maps[(1, light)]) if two else None,
               "maps_interpolated_ab": flip(interp[(2, light)], interp[(1, light)]) if two else None, "models": {},
               "profiles": {"B": profile_errors(ref_b, ref_a), "maps": profile_errors(mean_interp, ref_a)}}
        if a.ladder:
            row["ladder"] = ladder(paths, nearest, interpolated, ref_a)
        results[light] = row
    for k, model in enumerate(a.models):
        name = os.path.splitext(os.path.basename(model))[0]
        p = predicted(a, os.path.join(a.out, f"model{k + 1}"), os.path.abspath(model), [])
        for light in a.lights:
            ref_a, ref_b, mean_maps, mean_interp = shared[light]
            m = {"path": model, "prediction": flip(p[("model", light)], ref_a),
                 "fitting": flip(p[("model", light)], mean_maps),
                 "profiles": profile_errors(p[("model", light)], ref_a),
                 "with_maps_row_means": flip(with_row_means(p[("model", light)], mean_interp), ref_a)}
            if k == 0:
                noisy = np.maximum(p[("model", light)] + (ref_a - ref_b) / math.sqrt(2.0), 0.0)
                results[light]["perfect"] = flip(p[("model", light)], noisy)
            render = None
            if a.renders:
                render = a.renders[k] if a.renders[k] != "-" else None
            elif not a.renders and k == 0:
                render = os.path.join(a.eval, "renders", stem.format(light=light) + "_native_1024spp_seed1.exr")
            if render and os.path.exists(render):
                m["render"], m["render_file"] = flip(read_exr(render), ref_a), render
            results[light]["models"][f"{k + 1}: {name}"] = m
    out = os.path.join(a.out, "results.json")
    with open(out + ".tmp", "w") as f:
        json.dump({"command": ["scripts/bench_flip_split.py", *argv], "lights": results}, f, indent=1)
    os.replace(out + ".tmp", out)
    print("HDR-FLIP over the frame (its silhouettes' / interior's share)")
    print("| light | floor | perfect | maps: nearest, interpolated | maps A/B: nearest, interpolated | model | "
          "prediction | fitting | render |")
    print("|---|---|---|---|---|---|---|---|---|")
    for light, row in results.items():
        head = f"| {light} | {cell(row['floor'])} | {cell(row['perfect'])} | {cell(row['maps'])}, " \
               f"{cell(row['maps_interpolated'])} | {cell(row['maps_ab'])}, {cell(row['maps_interpolated_ab'])} |"
        for name, m in row["models"].items():
            print(f"{head} {name} | {cell(m['prediction'])} | {cell(m['fitting'])} | {cell(m.get('render'))} |")
            head = "| | | | | |"
    print("\nProfiles against A, rms % (across the ply's rows / along it in 10-pixel blocks), and each model's FLIP"
          " with the maps' row means")
    print("| light | B | maps (interpolated) | model | its profiles | its FLIP with the maps' row means |")
    print("|---|---|---|---|---|---|")

    def pr(x):
        return f"{x['across']:.1f} / {x['along']:.1f}"
    for light, row in results.items():
        head = f"| {light} | {pr(row['profiles']['B'])} | {pr(row['profiles']['maps'])} |"
        for name, m in row["models"].items():
            print(f"{head} {name} | {pr(m['profiles'])} | {m['with_maps_row_means']['mean']:.3f} |")
            head = "| | | |"
    for light, row in results.items() if a.ladder else ():
        lad = row["ladder"]
        print(f"\nThe maps' FLIP against A by paths ({light}): the path-weighted mean of the first k files, nearest / "
              "interpolated")
        print("| files | paths | FLIP nearest | FLIP interpolated |")
        print("|---|---|---|---|")
        for r in lad["steps"]:
            print(f"| {r['files']} | {r['paths']:.3g} | {r['nearest']:.4f} | {r['interpolated']:.4f} |")
        last, before = lad["steps"][-1], lad["steps"][-2] if len(lad["steps"]) > 1 else None
        for kind in ("nearest", "interpolated"):
            fit = lad["fit"][kind]
            step = (f"; the last step ({last['paths'] / before['paths']:.2g}x the paths) moved it by "
                    f"{last[kind] - before[kind]:+.4f}, where the fit says {fit['b'] * (last['paths'] ** -0.5 - before['paths'] ** -0.5):+.4f}"
                    if before else "")
            print(f"  {kind}: F(N) = {fit['F_inf']:.4f} + {fit['b']:.1f} / sqrt(N), rms residual {fit['rms']:.4f}{step}")

    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
