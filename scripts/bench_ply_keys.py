#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""How many keys per ply turn the garment's plies need (issue 16, decisions D24 addendum): the native closure's
sleeve rendered with its plies at each --keys per ply turn about the yarn, two seeds each, the same camera and
lights (evaluate.sh's garment framing), compared with the first --keys at the same seed and against that
render's own seed-to-seed difference (the noise floor).

    cd scripts && ../.venv/bin/python bench_ply_keys.py --stitches 4 10 --keys 16 8 --out ../build/bench_ply_keys
        [--preset fleece] [--light key-rim] [--spp 64]

Prints per size and keys: curve keys, peak memory, and against the first keys at seed 1 (seed 2 against seed 2)
the whole frame's mean luminance and per-channel error and FLIP; writes OUT/bench_ply_keys.json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import types

import evaluate as ev
import garment
from images import read_exr

FULL = (slice(None), slice(None))


def render(a, out: str, framed: tuple[str, ...], seed: int, what: str) -> tuple[dict, object]:
    """Writes and renders the native sleeve of the plies file and camera `framed` (evaluate.framed_plies_args)."""
    xml = os.path.join(out, f"native_s{seed}.xml")
    ev.cycles_scene(["--preset", a.preset, "--model", ev.model_path({}, a.preset), "--lights", a.light, "--seed",
                     str(seed), "--width", str(ev.GARMENT["width"]), "--height", str(ev.GARMENT["height"]),
                     "--out", xml, *framed])
    r = types.SimpleNamespace(width=ev.GARMENT["width"], height=ev.GARMENT["height"], threads=a.threads,
                              timeout=a.timeout)
    exr = xml[:-4] + ".exr"
    cost = ev.render(r, xml, a.spp, exr, f"{what}, seed {seed}")
    return {"curve_keys": ev.written(xml)["curve_keys"], **cost}, read_exr(exr)


def compare(img, ref) -> dict:
    m = ev.metrics(img, ref, FULL)
    return {"frame_luminance_pct": 100.0 * m["mean_luminance_error_frame"],
            "frame_rgb_pct": [100.0 * v for v in m["mean_colour_error_frame"]], "flip": m["flip"]}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stitches", type=int, nargs="+", default=[4, 10])
    ap.add_argument("--keys", type=int, nargs="+", default=[16, 8], help="keys per ply turn; the first is the reference")
    ap.add_argument("--preset", default="fleece")
    ap.add_argument("--light", default="key-rim")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=1800.0)
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    if len(a.keys) < 2 or min(a.keys) < 4 or min(a.stitches) < 1:
        ap.error("--keys needs two or more values >= 4, --stitches values >= 1")
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for n in a.stitches:
        plies = {k: garment.garment_plies(n, n, k) for k in a.keys}
        # One camera for every keys count: the harness's framing of the first.
        d = ev.garment_distance(plies[a.keys[0]], ev.GARMENT["width"] / ev.GARMENT["height"])
        images = {}
        for k in a.keys:
            out = os.path.join(a.out, f"{n}x{n}_k{k}")
            os.makedirs(out, exist_ok=True)
            framed = ev.framed_plies_args(os.path.join(out, "plies.json"), plies[k], d)
            for seed in (1, 2):
                cost, images[k, seed] = render(a, out, framed, seed, f"{n}x{n}, {k} keys per turn")
                if seed == 1:
                    rows.append({"stitches": n, "keys_per_turn": k, **cost})
        ref = a.keys[0]
        for row in rows[-len(a.keys):]:
            k = row["keys_per_turn"]
            row["vs_first_seed1"] = compare(images[k, 1], images[ref, 1])
            row["vs_first_seed2"] = compare(images[k, 2], images[ref, 2])
            row["floor_seed2_vs_seed1"] = compare(images[k, 2], images[k, 1])
    print(f"\n{a.preset}, {a.light}, {a.spp} spp, whole frame; against {a.keys[0]} keys per turn at the same seed "
          "(seed 1 | seed 2), and the seeds' own difference:\n")
    print("| stitches | keys per turn | curve keys | peak MB | lum % (s1, s2) | R / G / B % (s1) | FLIP (s1, s2) | floor: lum %, FLIP |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        s1, s2, fl = r["vs_first_seed1"], r["vs_first_seed2"], r["floor_seed2_vs_seed1"]
        print(f"| {r['stitches']} x {r['stitches']} | {r['keys_per_turn']} | {r['curve_keys']:,} | {r['peak_rss_mb']:.0f} | "
              f"{s1['frame_luminance_pct']:+.2f}, {s2['frame_luminance_pct']:+.2f} | "
              f"{' / '.join(f'{v:+.2f}' for v in s1['frame_rgb_pct'])} | {s1['flip']:.4f}, {s2['flip']:.4f} | "
              f"{fl['frame_luminance_pct']:+.2f}, {fl['flip']:.4f} |")
    with open(os.path.join(a.out, "bench_ply_keys.json"), "w") as f:
        json.dump({"preset": a.preset, "light": a.light, "spp": a.spp, "rows": rows,
                   "machine": ev.cpu_model(), "code": ev.git_revision()}, f, indent=1)
    sys.stdout.flush()
    os._exit(0)  # flip_evaluator's import may keep threads alive


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
