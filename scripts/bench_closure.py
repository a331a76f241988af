# SPDX-License-Identifier: Apache-2.0
"""The neural closure against Principled Hair (Chiang) on the same aggregated curve, render time side by side
in one run (issue 21's closure goal: ≤ 1.0×), and optionally against an earlier build of the patched Cycles:

    .venv/bin/python scripts/bench_closure.py [--presets fleece cotton] [--spp 1024] [--repeats 3]
        [--baselines docs/evaluation/speed_closeup.json] [--cycles-before OLD_CYCLES_BINARY]

The close-up of `neuralyarn cycles-scene` (key-rim lights, 320 × 160 by default). Chiang gets the colour that
evaluate.sh fitted to the explicit-fiber reference under uniform light (`--baselines`, a baselines.json of an
evaluate.sh run; decisions D23), so both closures scatter about the same energy and paths have about the same
length; without it, grey 0.5. Each configuration renders `--repeats` times, interleaved; the time is the whole
process's wall time minus that of a 1-sample render of the same scene (start-up, scene and kernel loading),
the median is printed. With `--cycles-before`, the neural scene is also rendered by that binary and the
images of both builds are compared (an optimisation that must not change the result: the largest pixel
difference is printed). A benchmark: prints a table, never a test.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from evaluate import CLI, CYCLES, PRESETS
from images import read_exr

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def write_scene(preset: str, method: str, colour, a, path: str) -> None:
    args = [CLI, "cycles-scene", "--preset", preset, "--lights", a.lights, "--width", str(a.width),
            "--height", str(a.height), "--out", path]
    if method == "neural":
        args += ["--model", os.path.join(ROOT, "models", f"{preset}.json")]
    else:
        args += ["--baseline", method, "--baseline-colour", *(f"{c:.6f}" for c in colour)]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"bench_closure: {' '.join(args)}: {r.stderr.strip()}")


def render(binary: str, scene: str, spp: int, a, exr: str) -> float:
    t0 = time.monotonic()
    r = subprocess.run([binary, "--background", "--quiet", "--samples", str(spp), "--threads", str(a.threads),
                        "--width", str(a.width), "--height", str(a.height), "--output", exr, scene],
                       capture_output=True, text=True)
    seconds = time.monotonic() - t0
    if r.returncode != 0 or not os.path.isfile(exr):
        raise SystemExit(f"bench_closure: {binary} {scene} failed ({r.returncode}): {r.stderr.strip()[-300:]}")
    return seconds


def fitted_colours(path: str) -> dict:
    """Chiang's fitted colour per "closeup_<preset>_chiang" from an evaluate.sh run's baselines.json, or from
    its results.json (the "baselines" list, as kept in docs/evaluation/speed_closeup.json)."""
    with open(path) as f:
        d = json.load(f)
    if isinstance(d.get("baselines"), list):
        return {f"{b['scene']}_{b['preset']}_{b['method']}": b["colour"] for b in d["baselines"] if not b["failed"]}
    return {k: v["fit"]["colour"] for k, v in d.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--presets", nargs="+", default=PRESETS, choices=PRESETS)
    ap.add_argument("--lights", default="key-rim")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=160)
    ap.add_argument("--baselines", help="baselines.json or results.json of an evaluate.sh run (e.g. "
                    "docs/evaluation/speed_closeup.json): Chiang's fitted colour per preset")
    ap.add_argument("--cycles-before", help="an earlier build of the patched cycles binary, rendered alongside")
    a = ap.parse_args()
    fitted = fitted_colours(a.baselines) if a.baselines else {}
    builds = [("neural", CYCLES), ("chiang", CYCLES)]
    if a.cycles_before:
        builds.insert(1, ("neural-before", a.cycles_before))
    print(f"# {a.width}x{a.height}, {a.spp} spp, {a.threads} threads, lights {a.lights}, {a.repeats} repeats "
          f"(median; start-up removed)")
    head = "| preset | " + " | ".join(f"{name} s" for name, _ in builds) + " | neural / chiang |"
    if a.cycles_before:
        head += " neural / before | largest pixel difference |"
    print(head)
    print("|---" * (head.count("|") - 1) + "|")
    with tempfile.TemporaryDirectory() as tmp:
        for preset in a.presets:
            colour = fitted.get(f"closeup_{preset}_chiang", [0.5, 0.5, 0.5])
            scenes = {}
            for method in ("neural", "chiang"):
                scenes[method] = os.path.join(tmp, f"{preset}_{method}.xml")
                write_scene(preset, method, colour, a, scenes[method])
            times = {name: [] for name, _ in builds}
            startup = {}
            for name, binary in builds:
                scene = scenes[name.split("-")[0]]
                startup[name] = render(binary, scene, 1, a, os.path.join(tmp, "one.exr"))
            for _ in range(a.repeats):
                for name, binary in builds:
                    scene = scenes[name.split("-")[0]]
                    exr = os.path.join(tmp, f"{preset}_{name}.exr")
                    times[name].append(render(binary, scene, a.spp, a, exr) - startup[name])
            med = {name: statistics.median(t) for name, t in times.items()}
            row = f"| {preset} | " + " | ".join(f"{med[name]:.2f}" for name, _ in builds) + \
                  f" | {med['neural'] / med['chiang']:.2f} |"
            if a.cycles_before:
                now = read_exr(os.path.join(tmp, f"{preset}_neural.exr"))
                before = read_exr(os.path.join(tmp, f"{preset}_neural-before.exr"))
                row += f" {med['neural'] / med['neural-before']:.2f} | {float(np.abs(now - before).max()):.3g} |"
            print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
