#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Cost of the garment scene by size: explicit fibers against the native closure (issue 16, decisions D24).

    cd scripts && ../.venv/bin/python bench_garment.py --stitches 4 8 10 15 --out ../build/bench_garment [--preset fleece]
        [--spp 16] [--light key-rim] [--full 40]

Per size (S x S stitches of scripts/garment.py's sleeve, 320 x 240, framed as evaluate.sh frames it) and
method: curve keys, scene file size and the seconds `neuralyarn cycles-scene` takes to write it, the load
(the median wall time of three 1-sample renders: parsing, BVH), the render seconds per sample (a --spp
render's wall time minus the load, over --spp), peak resident memory and memory above an empty scene. Then a
least-squares line through the explicit sizes per quantity against the curve keys, and its value at the
--full size's keys (cycles-scene's own estimate, which refuses to write it): an extrapolation, printed as one;
for the time per sample also a line in log(keys) (the frame, so the pixels, stay the same: a sample's cost
grows with the BVH's depth), the lower end of the range printed.
Prints a Markdown table; writes OUT/bench_garment.json.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import sys
import time
import types

import numpy as np

import evaluate as ev


def scene(a, method: str, stitches: int) -> tuple[str, float]:
    """(path, seconds to write) of the garment scene for one method."""
    e = types.SimpleNamespace(out=a.out, garment_stitches=stitches, yarns={}, width=ev.GARMENT["width"],
                              height=ev.GARMENT["height"])
    path = os.path.join(a.out, "scenes", f"garment_{stitches}x{stitches}_{a.preset}_{method}.xml")
    args = ["--preset", a.preset, "--lights", a.light, "--width", str(ev.GARMENT["width"]),
            "--height", str(ev.GARMENT["height"]), "--out", path, *ev.garment_scene_args(e)]
    if method == "native":
        args += ["--model", os.path.join(ev.MODELS, f"{a.preset}.json")]
    t0 = time.monotonic()
    ev.cycles_scene(args)
    return path, time.monotonic() - t0


def estimated_keys(a, stitches: int) -> int:
    """cycles-scene's estimate of the explicit keys of a garment it refuses to write."""
    e = types.SimpleNamespace(out=a.out, garment_stitches=stitches, yarns={}, width=ev.GARMENT["width"],
                              height=ev.GARMENT["height"])
    try:
        ev.run_cli(["cycles-scene", "--preset", a.preset, "--out", os.path.join(a.out, "scenes", "refused.xml"),
                    *ev.garment_scene_args(e)])
    except ev.RenderFailed as err:
        m = re.search(r"be (\d+) curve keys", str(err))
        if m:
            return int(m.group(1))
        raise
    raise SystemExit(f"bench_garment: a {stitches} x {stitches} garment was written: not a size to extrapolate to")


def measure(a, method: str, stitches: int, baseline_mb: float) -> dict:
    path, write_s = scene(a, method, stitches)
    r = types.SimpleNamespace(width=ev.GARMENT["width"], height=ev.GARMENT["height"], threads=a.threads,
                              timeout=a.timeout)
    exr = os.path.join(a.out, "renders", os.path.basename(path)[:-4] + ".exr")
    loads = [ev.render(r, path, 1, exr, f"{method} {stitches}x{stitches} load {k + 1}/3") for k in range(3)]
    load = statistics.median(c["seconds"] for c in loads)
    full = ev.render(r, path, a.spp, exr, f"{method} {stitches}x{stitches} {a.spp} spp")
    peak = max([full["peak_rss_mb"]] + [c["peak_rss_mb"] for c in loads])
    return {"method": method, "stitches": stitches, "curve_keys": ev.curve_keys(path),
            "scene_mb": os.path.getsize(path) / 2 ** 20, "write_s": write_s, "load_s": load,
            "render_s_per_spp": (full["seconds"] - load) / a.spp, "peak_rss_mb": peak,
            "above_baseline_mb": peak - baseline_mb}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stitches", type=int, nargs="+", default=[4, 8, 10])
    ap.add_argument("--full", type=int, default=40, help="the size to extrapolate explicit fibers to")
    ap.add_argument("--preset", default="fleece", choices=ev.PRESETS)
    ap.add_argument("--light", default="key-rim")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--timeout", type=float, default=3600.0)
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    a.out = os.path.abspath(a.out)
    for sub in ("scenes", "renders"):
        os.makedirs(os.path.join(a.out, sub), exist_ok=True)
    e = types.SimpleNamespace(out=a.out, width=ev.GARMENT["width"], height=ev.GARMENT["height"],
                              threads=a.threads, timeout=a.timeout)
    baseline = ev.render(e, ev.empty_scene(e), 1, os.path.join(a.out, "renders", "empty.exr"), "empty scene")
    rows = []
    for s in sorted(a.stitches):
        for method in ("native", "explicit"):
            try:
                rows.append(measure(a, method, s, baseline["peak_rss_mb"]))
            except ev.RenderFailed as err:
                rows.append({"method": method, "stitches": s, "failed": str(err)})
                ev.log(f"{method} {s}x{s}: FAILED, {err}")
    rows.append(measure(a, "native", a.full, baseline["peak_rss_mb"]))
    explicit = [r for r in rows if r["method"] == "explicit" and "failed" not in r]
    fit = {}
    if len(explicit) >= 2:
        keys = np.array([r["curve_keys"] for r in explicit], dtype=float)
        full_keys = estimated_keys(a, a.full)
        for q in ("scene_mb", "write_s", "load_s", "render_s_per_spp", "above_baseline_mb"):
            slope, icpt = np.polyfit(keys, [r[q] for r in explicit], 1)
            fit[q] = {"per_million_keys": 1e6 * slope, "intercept": icpt, "at_full": icpt + slope * full_keys}
        # The frame holds the whole sleeve at every size, so the pixels are the same and a sample's cost grows
        # with the depth of the BVH rather than with the keys: also a line in log(keys), the lower estimate.
        slope, icpt = np.polyfit(np.log(keys), [r["render_s_per_spp"] for r in explicit], 1)
        fit["render_s_per_spp_log"] = {"per_e_fold_keys": slope, "intercept": icpt,
                                       "at_full": icpt + slope * np.log(full_keys)}
        fit["full_keys"] = full_keys
    res = {"command": ["scripts/bench_garment.py", *argv], "machine": ev.cpu_model(), "preset": a.preset,
           "light": a.light, "spp": a.spp, "baseline_rss_mb": baseline["peak_rss_mb"], "rows": rows,
           "explicit_fit": fit, "full": a.full}
    with open(os.path.join(a.out, "bench_garment.json"), "w") as f:
        json.dump(res, f, indent=1)
    print(f"| stitches | method | curve keys | scene MB | write s | load s | render s / spp | peak MB | above empty MB |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "failed" in r:
            print(f"| {r['stitches']} x {r['stitches']} | {r['method']} | failed: {r['failed'][:60]} |||||||")
            continue
        print(f"| {r['stitches']} x {r['stitches']} | {r['method']} | {r['curve_keys']:,} | {r['scene_mb']:.1f} | "
              f"{r['write_s']:.1f} | {r['load_s']:.2f} | {r['render_s_per_spp']:.3f} | {r['peak_rss_mb']:.0f} | "
              f"{r['above_baseline_mb']:.0f} |")
    if fit:
        print(f"| {a.full} x {a.full} (extrapolated) | explicit | {fit['full_keys']:,} | "
              f"{fit['scene_mb']['at_full']:.0f} | {fit['write_s']['at_full']:.0f} | {fit['load_s']['at_full']:.0f} | "
              f"{fit['render_s_per_spp_log']['at_full']:.2f} … {fit['render_s_per_spp']['at_full']:.2f} | - | "
              f"{fit['above_baseline_mb']['at_full']:.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
