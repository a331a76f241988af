#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Plies in each other's shadow (decisions D68): the native closure with and without its model's near field
against explicit fibers, under one light, in scenes of several plies:

    cd scripts && ../.venv/bin/python bench_near_field.py --out ../build/bench_near_field \\
        [--preset cotton] [--light back] [--scenes crossed yarn yarn-1.3 yarn-2] [--spp 64] [--ref-spp 32]

`crossed`: two straight plies crossed at 84 degrees, the back one touching the front one; `half`: two parallel
straight plies, the back one 2.5 radii deeper and 1.4 higher, shadowing the upper half of the front one's width
under the back light (decisions D70; also prints the front ply's shadowed half over its lit half); `yarn`: the harness's
yarn close-up (three plies twisted, touching); `lone`: one ply of the yarn alone (`ply1`, `ply2`: the others);
`yarn-S`, `lone-S`, `ply1-S`, `ply2-S`: the same with the plies' offsets from the yarn's axis times S (the sum of
the three lone plies against the yarn: what the plies do to each other); `helix-S`: the lone ply with its whole helix
(offset and pitch) times S, so bent 1/S as much (decisions D74); `tilt-A`, `roll-A`: one straight ply turned A degrees
toward the camera or in the image plane (what a straight ply shows of the angles a helix shows); `ring-S`, `ringy-A`: one ply bent on a circle (ring_of). The reference is explicit fibers over four
orientations of the cross-section (--ref-spp each); its floor is one half of them against the other. Prints per
scene the luminance error (R / G / B) over the whole frame and, for `crossed` and `half`, over the front ply where
the back one shadows it; writes OUT/bench_near_field.json and, with --image PNG, per scene explicit fibers, the native
closure with its near field and their difference (luminance) side by side; with --maps, for the scenes of one ply
also the model's and the maps' far field predicted on it (aggregation against fit, decisions D74) and with
--sector-maps the bent ply's own (D75), with --bent-m M from networks conditioned on the bend and pooled over bends
(cpp_core/bench/bench_bent_m, D76). A benchmark: prints, never a test.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

import evaluate as ev
from garment import crossed_plies, parallel_plies, straight_yarn_plies
from images import LUMINANCE, read_exr

ROTATIONS = (0, 90, 180, 270)
WIDTH, HEIGHT = 160, 80
#: The front ply where the back one shadows it in `crossed` (rows, columns of the 160 x 80 frame, camera at 12).
OVERLAP = (slice(35, 45), slice(74, 86))
#: `half`: the front ply's upper (shadowed) and lower (lit) halves (rows 34 .. 46 at the camera's 12 ply radii).
SHADOWED_HALF, LIT_HALF = (slice(34, 40), slice(20, 140)), (slice(41, 47), slice(20, 140))
#: The scenes of one ply, which --maps predicts without a renderer (no shadows, no light between plies).
ONE_PLY = ("helix", "tilt", "roll", "ring", "ringy", "lone", "ply1", "ply2")
YARN_LENGTH = 48.7  # ply radii: the harness's yarn close-up at its default camera


def plies(scene: str) -> dict:
    """The scene's plies file content."""
    if scene == "crossed":
        return crossed_plies([0.0, 84.0], YARN_LENGTH)
    if scene == "half":
        return parallel_plies([(0.0, 0.0), (1.4, 2.5)], YARN_LENGTH)
    name, _, spread = scene.partition("-")
    if name in ("tilt", "roll"):
        d = crossed_plies([float(spread)], YARN_LENGTH)  # one straight ply turned in the image plane (roll)
        if name == "tilt":  # ... or toward the camera: its y and z swapped
            d["plies"] = [np.reshape(p, (-1, 3))[:, [0, 2, 1]].ravel().tolist() for p in d["plies"]]
        return d
    if name in ("ring", "ringy"):
        radius, turn_deg = ring_of(scene)
        a = np.linspace(0.0, 2.0 * math.pi, max(64, int(8 * radius)) + 1)
        x, y, turn = radius * np.cos(a), radius * np.sin(a), math.radians(turn_deg)
        p = np.stack([x * math.cos(turn), y, x * math.sin(turn)], axis=1)
        return {"format": "neuralyarn-plies 1", "ply_radius": 1.0, "length": float(2.0 * math.pi * radius),
                "plies": [[round(float(v), 5) for v in p.ravel()]]}
    if name == "helix":
        # The yarn S times as long, scaled down to the frame's length; its first ply cut to the frame.
        scale = float(spread)
        d = straight_yarn_plies(YARN_LENGTH * scale)
        p = np.array(d["plies"][0]).reshape(-1, 3) * scale
        p = p[np.abs(p[:, 0]) <= 0.5 * YARN_LENGTH + 2.0]
        d["plies"], d["length"] = [[round(float(v), 5) for v in p.ravel()]], YARN_LENGTH
        d["yarns"] = [[round(float(v), 5) for v in (-0.5 * YARN_LENGTH, 0, 0, 0.5 * YARN_LENGTH, 0, 0)]]
        d["yarn_radius"] *= scale
        return d
    d = straight_yarn_plies(YARN_LENGTH)
    if spread:
        d["plies"] = [[round(v * (float(spread) if i % 3 else 1.0), 5) for i, v in enumerate(p)] for p in d["plies"]]
    if name == "lone":
        d["plies"] = d["plies"][:1]
    elif name.startswith("ply"):
        d["plies"] = [d["plies"][int(name[3:])]]
    return d


def ring_of(scene: str) -> tuple[float, float]:
    """(radius, degrees turned about the image's vertical) of a ply bent on a circle: `ring-S` of radius S in the image
    plane (bending alone); `ringy-A` of radius 3 (the yarn's helix bends its ply about as much) turned A degrees, so
    that at its top and bottom the ply turns toward the camera while it bends, as a helix's crests do."""
    name, _, value = scene.partition("-")
    return (float(value), 0.0) if name == "ring" else (3.0, float(value))


def render(a, args: list[str], name: str, spp: int) -> np.ndarray:
    try:
        return ev.render_image(a, args, os.path.join(a.out, name), spp)
    except ev.RenderFailed as e:
        raise SystemExit(f"bench_near_field: {name}: {e}")


def error(img: np.ndarray, ref: np.ndarray, region=(slice(None), slice(None))) -> dict:
    m, r = img[region].mean(axis=(0, 1)), ref[region].mean(axis=(0, 1))
    return {"luminance": float(m @ LUMINANCE / (r @ LUMINANCE) - 1.0), "rgb": [float(v) for v in m / r - 1.0]}


def fmt(e: dict) -> str:
    return f"{100 * e['luminance']:+.1f} ({' / '.join(f'{100 * v:+.1f}' for v in e['rgb'])})"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="cotton")
    ap.add_argument("--light", default="back")
    ap.add_argument("--scenes", nargs="+", default=["crossed", "yarn", "yarn-1.3", "yarn-2"])
    ap.add_argument("--spp", type=int, default=64, help="the native closure's samples")
    ap.add_argument("--ref-spp", type=int, default=32, help="explicit fibers' samples per orientation")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per render")
    ap.add_argument("--out", default=os.path.join(ev.ROOT, "build", "bench_near_field"))
    ap.add_argument("--image", help="a PNG of each scene: fibers, native (near field), native - fibers")
    ap.add_argument("--maps", help="the preset's maps (.nyrdm): for the scenes of one ply (helix, tilt, roll, ring, ringy, "
                    "lone, ply1, ply2), also the model's and the maps' far field predicted on it without a renderer "
                    "(cpp_core/bench/bench_bent_ply; decisions D74)")
    ap.add_argument("--sector-maps", nargs="+", metavar="M", help="with --maps: maps of the bent ply gathered per sector "
                    "about the tube (cpp_core/bench/bench_bent_gather --sector k --sectors K, in order of k), predicted "
                    "each where its sector is (decisions D75)")
    ap.add_argument("--bent-m", metavar="NETS", help="with --sector-maps: bench_bent_m's networks of M, conditioned on "
                    "the bend and pooled over bends, each with the sector's R (decisions D76)")
    a = ap.parse_args()
    a.width, a.height = WIDTH, HEIGHT
    for s in a.scenes:
        name, _, spread = s.partition("-")
        number = spread.replace(".", "", 1).isdigit()
        if not (s in ("crossed", "half") or (name in ("yarn", "lone", "ply1", "ply2") and (not spread or number)) or
                (name in ("helix", "tilt", "roll", "ring", "ringy") and number)):
            print(f"bench_near_field: unknown scene '{s}' (crossed, half, yarn, lone, ply1, ply2, each with -S but crossed "
                  "and half; helix-S, tilt-A, roll-A, ring-S, ringy-A)", file=sys.stderr)
            return 1
    if a.sector_maps and not a.maps:
        print("bench_near_field: --sector-maps needs --maps (the straight ply's, predicted beside them)", file=sys.stderr)
        return 1
    if a.bent_m and not a.sector_maps:
        print("bench_near_field: --bent-m needs --sector-maps (the R beside its M)", file=sys.stderr)
        return 1
    os.makedirs(a.out, exist_ok=True)
    shipped = os.path.join(ev.MODELS, f"{a.preset}.json")
    model = json.load(open(shipped))
    if "near_field" not in model:
        print(f"bench_near_field: {shipped} has no near field", file=sys.stderr)
        return 1
    far = os.path.join(a.out, f"{a.preset}_far_field.json")
    with open(far, "w") as f:
        json.dump({k: v for k, v in model.items() if k != "near_field"}, f)
    rows, panels = [], []
    print("| scene | frame: far field | frame: near field | shadowed ply: far | shadowed ply: near | floor, frame |")
    print("|---|---|---|---|---|---|")
    for scene in a.scenes:
        path = os.path.join(a.out, f"plies_{scene}.json")
        with open(path, "w") as f:
            json.dump(plies(scene), f)
        common = ["--preset", a.preset, "--lights", a.light, "--width", str(WIDTH), "--height", str(HEIGHT),
                  "--plies", path]
        parts = [render(a, [*common, "--seed", str(1001 + r), "--ply-rotation", str(r)], f"explicit_{scene}_{r}",
                        a.ref_spp) for r in ROTATIONS]
        ref = sum(parts) / len(parts)
        floor = error((parts[0] + parts[1]) / 2, (parts[2] + parts[3]) / 2)
        row = {"scene": scene, "floor": floor}
        halves = {"explicit": ref}
        for name, m in (("far", far), ("near", shipped)):
            img = render(a, [*common, "--model", m, "--seed", "1"], f"native_{scene}_{name}", a.spp)
            row[name] = error(img, ref)
            if scene in ("crossed", "half"):
                row[name + "_shadowed"] = error(img, ref, OVERLAP if scene == "crossed" else SHADOWED_HALF)
            halves[name] = img
        if scene == "half":
            row["shadowed_over_lit"] = {k: float((v[SHADOWED_HALF] @ LUMINANCE).mean() / (v[LIT_HALF] @ LUMINANCE).mean())
                                        for k, v in halves.items()}
            print("half: the front ply's shadowed half over its lit half: " +
                  ", ".join(f"{k} {v:.2f}" for k, v in row["shadowed_over_lit"].items()), flush=True)
        if a.maps and scene.partition("-")[0] in ONE_PLY:
            row["predicted"] = predicted(a, scene, path, parts, halves["far"])
        rows.append(row)
        panels.append((scene, halves["explicit"], halves["near"]))
        shadowed = [fmt(row[k]) if k in row else "" for k in ("far_shadowed", "near_shadowed")]
        print(f"| {scene} | {fmt(row['far'])} | {fmt(row['near'])} | {shadowed[0]} | {shadowed[1]} | "
              f"{100 * floor['luminance']:+.1f} |", flush=True)
    with open(os.path.join(a.out, "bench_near_field.json"), "w") as f:
        json.dump({"preset": a.preset, "light": a.light, "spp": a.spp, "ref_spp": a.ref_spp,
                   "rotations": list(ROTATIONS), "rows": rows}, f, indent=1)
    if a.image:
        write_panels(a.image, panels, a.preset, a.light)
    return 0


def predicted(a, scene: str, plies_path: str, explicit_parts: list, native: np.ndarray) -> dict:
    """The model's and the maps' far field on the plies of `scene` (bench_bent_ply --plies, direct light only, no
    shadows: for one ply; with --sector-maps also the bent ply's own maps, each hit read from its sector about the
    bend; with --bent-m also M from bench_bent_m's networks beside the sector's R, calibrated too where they carry
    their tables, D77) against explicit fibers and the native render (far field): luminance over the frame and over
    the glint (frame_and_glint). Prints one line; the numbers for the JSON."""
    prefix = os.path.join(a.out, f"predicted_{scene}")
    tool = os.path.join(ev.BUILD, "cpp_core", "bench_bent_ply")
    sectors = ["--sector-maps", *a.sector_maps] if a.sector_maps else []
    sectors += ["--bent-m", a.bent_m] if a.bent_m else []
    r = subprocess.run([tool, "--model", os.path.join(ev.MODELS, f"{a.preset}.json"), "--maps", a.maps, "--rig", a.light,
                        "--width", str(WIDTH), "--height", str(HEIGHT), "--plies", plies_path, *sectors, "--out", prefix],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"bench_near_field: {tool} failed: {r.stderr.strip()}")
    # Every image the tool wrote, as it names them ("NAME: frame mean R G B").
    names = [line.split(":")[0] for line in r.stdout.splitlines() if ": frame mean " in line]
    out = frame_and_glint(explicit_parts, native, {k: read_exr(f"{prefix}_{k}.exr")[..., :3] for k in names})
    print(f"{scene}: frame / the 3 % of pixels where native exceeds fibers most: " +
          ", ".join(f"{k} {v['frame']:.5f} / {v['glint']:.4f}" for k, v in out.items()), flush=True)
    return out


def frame_and_glint(explicit_parts: list, native: np.ndarray, others: dict) -> dict:
    """Mean luminance over the frame and over the glint — the 3 % of pixels where the native render exceeds the fibers
    most — of the fibers (the mean of `explicit_parts`), the native render and `others`. The glint's pixels are chosen
    with the first half of the fibers' renders and the fibers measured there with the other half: chosen and measured
    in the same noisy image, they would be the pixels where its noise happens to be low."""
    n = len(explicit_parts) // 2
    chooser = sum(explicit_parts[:n]) / n @ LUMINANCE
    measured = sum(explicit_parts[n:]) / (len(explicit_parts) - n) @ LUMINANCE
    lum = {"fibers": sum(explicit_parts) / len(explicit_parts) @ LUMINANCE, "native": native @ LUMINANCE,
           **{k: v @ LUMINANCE for k, v in others.items()}}
    excess = lum["native"] - chooser
    glint = excess > np.percentile(excess, 97)
    return {k: {"frame": float(v.mean()), "glint": float((measured if k == "fibers" else v)[glint].mean())}
            for k, v in lum.items()}


def write_panels(path: str, panels: list, preset: str, light: str) -> None:
    """Per scene (a row): explicit fibers, the native closure, native - fibers, in luminance on one scale."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(panels), 3, figsize=(12, 2.2 * len(panels)), squeeze=False)
    for ax, (scene, ref, img) in zip(axes, panels):
        r, n = ref @ LUMINANCE, img @ LUMINANCE
        top = float(np.percentile(r, 99.5)) or 1.0
        ax[0].imshow(r, vmin=0.0, vmax=top, cmap="gray")
        ax[1].imshow(n, vmin=0.0, vmax=top, cmap="gray")
        ax[2].imshow(n - r, vmin=-0.5 * top, vmax=0.5 * top, cmap="RdBu_r")
        for a_, title in zip(ax, (f"{scene}: explicit fibers", "native (near field)", "native - fibers (red: brighter)")):
            a_.set_title(title, fontsize=9)
            a_.axis("off")
    fig.suptitle(f"{preset}, {light} light", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
