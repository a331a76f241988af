#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The stability suite (issue 19): where each method holds and where it fails.

    bash scripts/stability.sh --out DIR [--quick] [--sweeps views scale units samples layers bakes furnace]
        [--presets P ...] [--methods explicit native osl nodes] [--scale-px W ...] [--layers N ...]
        [--ref-spp N] [--ref-rotations N] [--append] [--threads N] [--timeout S]

Sweeps, on the evaluation harness's scene (scripts/evaluate.py, `neuralyarn cycles-scene`), every method
against an explicit-fiber reference of the same scene (the mean over orientations of the ply, as the harness):
  views    one distant light from the camera's direction (0) through grazing (89.9) to straight behind (180),
           in the plane normal to the ply and along its axis, and the uniform environment;
  scale    the ply from ~300 pixels wide to half a pixel (camera distance);
  units    the whole scene 2.5e-4 (a 0.5 mm yarn in metres) and 1e3 times the ply radius 1, against unit 1;
  samples  1 ... 1024 samples per pixel, several seeds (bias and variance against the reference);
  layers   2, 8, 32 cloth layers (sheets of plies) under a back light and the environment, with the
           references' bounce limits and with the artist's (Blender's defaults, the add-on's 64 transparent);
  bakes    fiber parameters beyond the presets (alpha 0, rho, N, beta_R, C_TT (1, 1, 1), very dark fibers,
           impossible packings): success, time, albedo error, white furnace;
  furnace  the white furnace of the presets' shipped models (`neuralyarn furnace`, at the bin centres and
           inside the bins).

Each cell of DIR/results.json `cells` holds: sweep, method, preset, the swept parameters, spp, seeds,
nan_pixels, inf_pixels, negative_pixels, firefly_pixels, furnace_max (the largest white-furnace value seen:
of the model anywhere inside its incident bins, or of the environment-lit render's brightest row; absent
where none applies; models also furnace_max_centres, at the bin centres), bias, variance,
seconds, failed (false or the reason). Definitions:
  bias      mean Rec. 709 luminance of the seeds' mean image / the reference's - 1, over the harness's central
            region (the whole frame where the ply is under 3 rows);
  variance  the mean over that region of the per-pixel variance across seeds (one render's), divided by the
            reference's mean luminance squared (a relative variance; absent with one seed);
  firefly   a pixel (any channel) above 10 times the reference's largest value in its 5 x 5 neighbourhood
            plus 5 % of the reference's frame mean (fireflies against black must stand out from noise).
DIR/stability_map.png: one heatmap per sweep (methods against the swept value, |bias| in %, NaN/Inf or
failures marked). Exit codes: 0 the suite ran (failing cells are results, not errors), 1 bad arguments or a
missing build.
"""
from __future__ import annotations

import datetime
import json
import math
import os
import re
import subprocess
import sys
import time
import types

import numpy as np

import evaluate as ev
from images import LUMINANCE, read_exr, write_exr

FIREFLY_FACTOR = 10.0
FIREFLY_WINDOW = 5
FIREFLY_FLOOR = 0.05
SWEEPS = ["views", "scale", "units", "samples", "layers", "bakes", "furnace"]
RENDER_METHODS = ["explicit", "native", "osl", "nodes"]

QUICK = {
    "width": 64, "height": 32, "ref_spp": 64, "ref_rotations": 2, "spp": 16, "seeds": 2, "presets": ["fleece"],
    "methods": ["explicit", "native"],
    "views": ["sun-0-normal", "sun-60-normal", "sun-89.9-normal", "sun-89.9-axis", "sun-180-normal", "environment"],
    "scale_px": [30.0, 3.0, 0.5],
    "units": [2.5e-4, 1.0, 1e3],
    "samples": [1, 4, 16, 64],
    "layers": [2, 8],
    "bakes": ["c_tt_one", "unpackable"],
    "bake_paths": "1e5",
    # Coarse maps and a short M training: the quick bake checks that a stress bake succeeds and stays
    # bounded, not its fidelity (the full run bakes at the paper's resolution).
    "bake_options": ["--bins", "12x48x24x48", "--m-steps", "5000"],
}
FULL = {
    "width": 128, "height": 64, "ref_spp": 512, "ref_rotations": 4, "spp": 64, "seeds": 3,
    "presets": list(ev.PRESETS), "methods": RENDER_METHODS,
    "views": ["sun-0-normal", "sun-30-normal", "sun-60-normal", "sun-80-normal", "sun-89-normal",
              "sun-89.9-normal", "sun-45-axis", "sun-80-axis", "sun-89.9-axis", "sun-150-normal", "sun-180-normal",
              "environment"],
    "scale_px": [300.0, 30.0, 3.0, 1.0, 0.5],
    "units": [2.5e-4, 1.0, 1e3],
    "samples": [1, 4, 16, 64, 256, 1024],
    "layers": [2, 8, 32],
    "bakes": ["alpha_zero", "rho_low", "rho_high", "n_few", "n_many", "beta_r_narrow", "beta_r_wide", "c_tt_one",
              "dark", "unpackable"],
    "bake_paths": "4e6",
    "bake_options": [],
}
#: Fiber parameters of the bake sweep: changes to the fleece preset (cpp_core/data/presets.json).
BAKES = {
    "alpha_zero": {"alpha": 0.0},
    "rho_low": {"rho": 0.05},
    "rho_high": {"rho": 0.6},
    "n_few": {"N": 10},
    "n_many": {"N": 1500},
    "beta_r_narrow": {"beta_R_deg": 0.5},
    "beta_r_wide": {"beta_R_deg": 30.0},
    "c_tt_one": {"C_TT": [1.0, 1.0, 1.0]},
    "dark": {"C_R": [0.01, 0.01, 0.01], "C_TT": [0.02, 0.02, 0.02]},
    "unpackable": {"N": 1500, "rho": 0.9},
}
#: A distant light for the scale, units and samples sweeps (in front, 45 degrees off the view).
SWEEP_LIGHT = "sun-45-normal"
LAYER_LIGHTS = ["sun-170-normal", "environment"]
LAYER_CAMERA_DISTANCE = 6.0
LAYER_PLY_LENGTH = 16.0


def log(msg: str) -> None:
    print(f"stability: {msg}", file=sys.stderr, flush=True)


class Progress:
    def __init__(self):
        self.done, self.t0 = 0, time.monotonic()

    def __call__(self, what: str) -> str:
        self.done += 1
        return f"[{self.done}, {time.monotonic() - self.t0:.0f} s] {what}"


# --- scenes and renders ----------------------------------------------------------------------------------

def scene_args(s: dict) -> list[str]:
    """cycles-scene's arguments of a scene spec (preset, light, width, height, camera_distance, unit_scale,
    layers, artist_bounces, ply_length)."""
    args = ["--preset", s["preset"], "--lights", s["light"], "--width", str(s["width"]), "--height", str(s["height"]),
            "--ply-length", f"{s['ply_length']:g}", "--camera-distance", f"{s['camera_distance']:g}",
            "--unit-scale", f"{s['unit_scale']:g}", "--layers", str(s["layers"])]
    return args + (["--artist-bounces"] if s["artist_bounces"] else [])


def spec(a, preset: str, light: str, **kw) -> dict:
    s = {"preset": preset, "light": light, "width": a.width, "height": a.height, "camera_distance": 12.0,
         "unit_scale": 1.0, "layers": 1, "artist_bounces": False, "ply_length": ev.CLOSEUP_PLY_LENGTH}
    s.update(kw)
    return s


def key_of(s: dict) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", "_".join(f"{v}" for v in s.values()))


def write_scene(a, s: dict, method: str, seed: int, rotation: float = 0.0) -> str:
    path = os.path.join(a.out, "scenes", f"{key_of(s)}_{method}_seed{seed}_rot{rotation:g}.{ev.scene_ext(method)}")
    args = [*scene_args(s), "--seed", str(seed), "--out", path]
    if rotation:
        args += ["--ply-rotation", f"{rotation:g}"]
    if method != "explicit":
        args += ["--model", os.path.join(ev.MODELS, f"{s['preset']}.json")]
    ev.cycles_scene(args)
    return path


def render_spec(a, s: dict, xml: str, spp: int, exr: str, what: str, fallback=None, finite: bool = True) -> dict:
    """ev.render at the spec's image size (the harness reads it from its settings)."""
    return ev.render(types.SimpleNamespace(**{**vars(a), "width": s["width"], "height": s["height"]}), xml, spp, exr,
                     what, fallback, finite=finite)


def render_view(a, s: dict, method: str, spp: int, seed: int, what: str) -> tuple[np.ndarray, float]:
    """One render of the scene spec by a method; (image, seconds). Non-finite pixels are kept (counted)."""
    xml = write_scene(a, s, method, seed)
    exr = os.path.join(a.out, "renders", f"{key_of(s)}_{method}_{spp}spp_seed{seed}.exr")
    cost = render_spec(a, s, xml, spp, exr, what, ev.fallback_of(method), finite=False)
    return read_exr(exr), cost["seconds"]


def reference(a, s: dict, progress) -> np.ndarray:
    """Explicit fibers at a.ref_spp, the mean over a.ref_rotations orientations as the harness's reference A
    (cached in DIR/refs by spec and Cycles binary: a rebuilt Cycles may sample the fibers differently, D31)."""
    exr = os.path.join(a.out, "refs", f"{key_of(s)}_{a.ref_spp}spp_{a.ref_rotations}rot.exr")
    stamp = exr[:-len(".exr")] + ".json"
    renderer = {"cycles_sha256": ev.cycles_sha256()}
    if os.path.isfile(exr) and os.path.isfile(stamp):
        with open(stamp) as f:
            if json.load(f) == renderer:
                return read_exr(exr)
    k, spp = a.ref_rotations, max(1, a.ref_spp // a.ref_rotations)
    total = None
    for i, (seed, rotation, _) in enumerate(ev.reference_parts("A", k, "one")):
        xml = write_scene(a, s, "explicit", seed, rotation)
        part = exr + ".part.exr"
        render_spec(a, s, xml, spp, part, progress(f"reference {key_of(s)} [{i + 1}/{k}]"))
        img = read_exr(part)
        os.remove(part)
        total = img if total is None else total + img
    write_exr(exr, total / k)
    with open(stamp, "w") as f:
        json.dump(renderer, f)
    return total / k


# --- measures ---------------------------------------------------------------------------------------------

def closeup_fov(a) -> float:
    """The close-up camera's field of view, from a scene cycles-scene writes (its one definition)."""
    xml = os.path.join(a.out, "scenes", "fov_probe.xml")
    ev.cycles_scene(["--lights", "environment", "--model", os.path.join(ev.MODELS, "fleece.json"), "--out", xml])
    return ev.camera(xml)[1]


def region_of(a, s: dict) -> tuple[slice, slice] | None:
    """The harness's central region of the (first) ply, or None where the ply covers under 3 rows."""
    try:
        return ev.central_region(s["camera_distance"] * s["unit_scale"], a.fov, s["width"], s["height"],
                                 radius=s["unit_scale"])
    except ev.RenderFailed:
        return None


def local_max(img: np.ndarray, k: int) -> np.ndarray:
    """The largest value of each pixel's k x k neighbourhood (any channel)."""
    m = img.max(axis=2)
    r = k // 2
    pad = np.pad(m, r, mode="edge")
    out = np.full_like(m, -np.inf)
    for dy in range(k):
        for dx in range(k):
            out = np.maximum(out, pad[dy:dy + m.shape[0], dx:dx + m.shape[1]])
    return out


def measure(images: list[np.ndarray], ref: np.ndarray, region, environment: bool) -> dict:
    stack = np.stack(images)
    finite = np.isfinite(stack)
    out = {"nan_pixels": int(np.isnan(stack).any(axis=3).sum()),
           "inf_pixels": int(np.isinf(stack).any(axis=3).sum()),
           "negative_pixels": int((np.where(finite, stack, 0.0) < 0.0).any(axis=3).sum())}
    clean = np.where(finite, stack, 0.0)
    limit = FIREFLY_FACTOR * (local_max(ref, FIREFLY_WINDOW) + FIREFLY_FLOOR * float(ref.mean()))
    out["firefly_pixels"] = int((clean.max(axis=3) > limit[None]).sum())
    reg = region if region is not None else (slice(None), slice(None))
    lum = clean @ LUMINANCE  # (seeds, H, W)
    ref_lum = float((ref[reg] @ LUMINANCE).mean())
    mean_img = clean.mean(axis=0)
    out["bias"] = float((mean_img[reg] @ LUMINANCE).mean() / ref_lum - 1.0) if ref_lum > 0 else None
    out["variance"] = (float(lum[(slice(None), *reg)].var(axis=0, ddof=1).mean() / ref_lum ** 2)
                       if len(images) > 1 and ref_lum > 0 else None)
    out["region"] = "central" if region is not None else "frame"
    if environment and region is not None:
        # Uniform white light of radiance 1: no pixel's expected value may exceed 1 (the rows' mean keeps
        # the noise of single pixels out of it).
        out["furnace_max"] = float(mean_img[reg].mean(axis=1).max())
    return out


# --- the sweeps -------------------------------------------------------------------------------------------

def render_cells(a, sweep: str, s: dict, params: dict, methods: list[str], spp: int, seeds: int, progress,
                 ref_spec: dict | None = None) -> list[dict]:
    """Cells of the methods on scene spec s against the explicit reference of ref_spec (default s)."""
    cells = []
    try:
        ref = reference(a, ref_spec or s, progress)
    except ev.RenderFailed as e:
        log(f"reference of {key_of(ref_spec or s)}: FAILED, {e}")
        return [{"sweep": sweep, "method": m, "preset": s["preset"], **params, "spp": spp, "seeds": seeds,
                 "failed": f"reference failed: {e}"} for m in methods]
    region = region_of(a, s)
    for method in methods:
        cell = {"sweep": sweep, "method": method, "preset": s["preset"], **params, "spp": spp, "seeds": seeds,
                "failed": False}
        if method in ev.FALLBACKS and (s["layers"] > 1 or s["preset"] not in ev.PRESETS):
            continue
        images, seconds = [], 0.0
        try:
            for seed in range(1, seeds + 1):
                img, t = render_view(a, s, method, spp, seed, progress(f"{sweep} {method} {params} {spp} spp seed {seed}"))
                images.append(img)
                seconds += t
        except ev.RenderFailed as e:
            cell["failed"] = str(e)
            log(f"{sweep} {method} {params}: FAILED, {e}")
            cells.append(cell)
            continue
        cell.update(measure(images, ref, region, s["light"] == "environment"))
        cell["seconds"] = seconds / seeds
        cells.append(cell)
    return cells


def sweep_views(a, preset, progress):
    cells = []
    for light in a.cfg["views"]:
        cells += render_cells(a, "views", spec(a, preset, light), {"light": light}, a.methods, a.cfg["spp"],
                              a.cfg["seeds"], progress)
    return cells


def sweep_scale(a, preset, progress):
    cells = []
    for px in a.cfg["scale_px"]:
        # The ply's width in pixels is 2 radii over the frame's height 2 d tan(fov / 2) at distance d.
        h = a.height if px < 0.5 * a.height else 2 * a.height
        w = 2 * h
        d = max(1.1, h / (px * math.tan(0.5 * a.fov)))
        length = min(1000.0, max(ev.CLOSEUP_PLY_LENGTH, 1.2 * 2 * d * math.tan(0.5 * a.fov) * w / h))
        s = spec(a, preset, SWEEP_LIGHT, width=w, height=h, camera_distance=round(d, 4), ply_length=round(length, 1))
        px_true = h / (s["camera_distance"] * math.tan(0.5 * a.fov))
        cells += render_cells(a, "scale", s, {"light": SWEEP_LIGHT, "ply_pixels": round(px_true, 2)}, a.methods,
                              a.cfg["spp"], a.cfg["seeds"], progress)
    return cells


def sweep_units(a, preset, progress):
    cells, base = [], spec(a, preset, SWEEP_LIGHT)
    for u in a.cfg["units"]:
        s = spec(a, preset, SWEEP_LIGHT, unit_scale=u)
        # The reference at unit scale 1: a scene scaled as a whole renders the same image.
        cells += render_cells(a, "units", s, {"light": SWEEP_LIGHT, "unit_scale": u},
                              [m for m in a.methods if m in ("explicit", "native")], a.cfg["spp"], a.cfg["seeds"],
                              progress, ref_spec=base)
    return cells


def sweep_samples(a, preset, progress):
    cells, s = [], spec(a, preset, SWEEP_LIGHT)
    for spp in a.cfg["samples"]:
        cells += render_cells(a, "samples", s, {"light": SWEEP_LIGHT}, a.methods, spp, max(2, a.cfg["seeds"]),
                              progress)
    return cells


def sweep_layers(a, preset, progress):
    cells = []
    for light in LAYER_LIGHTS:
        for n in a.cfg["layers"]:
            kw = {"layers": n, "camera_distance": LAYER_CAMERA_DISTANCE, "ply_length": LAYER_PLY_LENGTH}
            ref_spec = spec(a, preset, light, **kw)
            for artist in (False, True):
                s = spec(a, preset, light, artist_bounces=artist, **kw)
                methods = ["native"] + (["explicit"] if artist else [])
                cells += render_cells(a, "layers", s, {"light": light, "layers": n,
                                                       "bounces": "artist" if artist else "reference"},
                                      methods, a.cfg["spp"], a.cfg["seeds"], progress, ref_spec=ref_spec)
    return cells


def sweep_bakes(a, progress):
    """Bakes of fiber parameters beyond the presets: time, success (or the message), albedo error against
    independent maps, white furnace."""
    with open(os.path.join(ev.ROOT, "cpp_core", "data", "presets.json")) as f:
        base = json.load(f)["presets"]["fleece"]
    cells = []
    for name in a.cfg["bakes"]:
        params = {**base, "name": f"stress_{name}", "description": "stability suite", **BAKES[name]}
        pfile = os.path.join(a.out, "bakes", f"{name}.json")
        model = os.path.join(a.out, "bakes", f"{name}_model.json")
        with open(pfile, "w") as f:
            json.dump(params, f)
        cell = {"sweep": "bakes", "method": "bake", "preset": "fleece", "bake": name,
                "changed": BAKES[name], "paths": a.cfg["bake_paths"], "failed": False}
        what = progress(f"bake {name} {BAKES[name]}")
        t0 = time.monotonic()
        args = [ev.CLI, "bake", "--params", pfile, "--paths", a.cfg["bake_paths"], "--check-paths",
                a.cfg["bake_paths"], *a.cfg["bake_options"], "--quiet", "--threads", str(a.threads), "--out", model]
        try:
            r = subprocess.run(args, capture_output=True, text=True, timeout=a.timeout)
        except subprocess.TimeoutExpired:
            cell.update(failed=f"timed out after {a.timeout:g} s", seconds=a.timeout)
            cells.append(cell)
            continue
        cell["seconds"] = time.monotonic() - t0
        if r.returncode != 0:
            cell["failed"] = (r.stderr or r.stdout).strip().splitlines()[-1] if (r.stderr or r.stdout).strip() \
                else f"exit {r.returncode}"
            log(f"{what}: failed in {cell['seconds']:.1f} s: {cell['failed']}")
            cells.append(cell)
            continue
        m = re.search(r"albedo vs map\s+mean abs error \S+, mean relative error ([0-9.]+) %", r.stdout)
        cell["albedo_error"] = float(m.group(1)) / 100.0 if m else None
        cell.update(furnace(model))
        log(f"{what}: {cell['seconds']:.1f} s, albedo error {cell['albedo_error']}, furnace {cell.get('furnace_max')}")
        cells.append(cell)
    return cells


def furnace(model: str) -> dict:
    """furnace_max: the largest white-furnace value of the model at 3 x 3 directions inside every incident bin
    and at theta_i 89.975 deg (`neuralyarn furnace --inside`); furnace_max_centres: at the bin centres, where
    the calibration bounds it."""
    out = {}
    for key, extra in (("furnace_max", ["--inside"]), ("furnace_max_centres", [])):
        r = subprocess.run([ev.CLI, "furnace", model, *extra], capture_output=True, text=True)
        m = re.search(r"white furnace max (\S+)", r.stdout)
        out[key] = float(m.group(1)) if m else None
        if not m:
            out["failed"] = (r.stderr or r.stdout).strip()
    return out


def sweep_furnace(a, presets, progress):
    cells = []
    for p in presets:
        progress(f"furnace {p}")
        cells.append({"sweep": "furnace", "method": "native", "preset": p, "failed": False,
                      **furnace(os.path.join(ev.MODELS, f"{p}.json"))})
    return cells


# --- the map ----------------------------------------------------------------------------------------------

SWEPT = {"views": "light", "scale": "ply_pixels", "units": "unit_scale", "samples": "spp", "layers": "layers"}


def row_name(c: dict) -> str:
    """A cell's row in the map and the summary: preset and method, and for the layers its light and bounces."""
    extra = f" {c['light']} ({c['bounces']} bounces)" if c["sweep"] == "layers" else ""
    return f"{c['preset']} {c['method']}{extra}"


def stability_map(cells: list[dict], path: str) -> None:
    """One heatmap per render sweep: methods (and variants) against the swept value, coloured by |bias| in %
    and labelled with the bias; X where a cell failed or has NaN/Inf/negative pixels, F where it has
    firefly pixels."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sweeps = [s for s in SWEPT if any(c["sweep"] == s for c in cells)]
    if not sweeps:
        return
    fig, axes = plt.subplots(len(sweeps), 1, figsize=(11, 2.3 * len(sweeps) + 0.6), squeeze=False)
    for ax, sw in zip(axes[:, 0], sweeps):
        cs = [c for c in cells if c["sweep"] == sw]
        rows = list(dict.fromkeys(row_name(c) for c in cs))
        cols = list(dict.fromkeys(c[SWEPT[sw]] for c in cs))
        grid = np.full((len(rows), len(cols)), np.nan)
        marks = {}
        for c in cs:
            i, j = rows.index(row_name(c)), cols.index(c[SWEPT[sw]])
            bad = c["failed"] or c.get("nan_pixels") or c.get("inf_pixels") or c.get("negative_pixels")
            if c.get("bias") is not None:
                grid[i, j] = 100 * abs(c["bias"])
            text = f"{100 * c['bias']:+.0f}" if c.get("bias") is not None else "-"
            marks[(i, j)] = "X" if bad else text + (" F" if c.get("firefly_pixels") else "")
        im = ax.imshow(np.minimum(grid, 100), cmap="magma_r", vmin=0, vmax=50, aspect="auto")
        for (i, j), t in marks.items():
            ax.text(j, i, t, ha="center", va="center", fontsize=7,
                    color="white" if not math.isnan(grid[i, j]) and grid[i, j] > 25 else "black")
        ax.set_yticks(range(len(rows)), rows, fontsize=7)
        ax.set_xticks(range(len(cols)), [str(c) for c in cols], fontsize=7, rotation=20, ha="right")
        ax.set_title(f"{sw}: bias of the mean luminance against explicit fibers, % (colour: |bias|; X failed or "
                     "NaN/Inf/negative pixels, F firefly pixels)", fontsize=8)
        fig.colorbar(im, ax=ax, fraction=0.02)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def summary(results: dict) -> str:
    """Markdown: per render sweep a table of methods (rows) against the swept value (columns), each cell
    "bias % / relative variance" with the counts of bad and firefly pixels where non-zero; bakes and furnace
    values as lists."""
    cells, lines = results["cells"], []
    for sw, key in SWEPT.items():
        cs = [c for c in cells if c["sweep"] == sw]
        if not cs:
            continue
        cols = list(dict.fromkeys(c[key] for c in cs))
        rows: dict = {}
        for c in cs:
            name = row_name(c)
            if c["failed"]:
                text = "failed"
            else:
                text = f"{100 * c['bias']:+.1f}" if c.get("bias") is not None else "-"
                text += f" / {c['variance']:.2g}" if c.get("variance") is not None else ""
                bad = sum(c.get(k) or 0 for k in ("nan_pixels", "inf_pixels", "negative_pixels"))
                text += f" **{bad} bad**" if bad else ""
                text += f" ({c['firefly_pixels']} ff)" if c.get("firefly_pixels") else ""
            rows.setdefault(name, {})[c[key]] = text
        lines += [f"**{sw}** ({key}; bias % / relative variance of one render; bad = NaN/Inf/negative pixels, "
                  "ff = firefly pixels)", "",
                  "| method | " + " | ".join(str(c) for c in cols) + " |", "|---" * (len(cols) + 1) + "|"]
        lines += [f"| {n} | " + " | ".join(r.get(c, "") for c in cols) + " |" for n, r in rows.items()]
        lines.append("")
    bakes = [c for c in cells if c["sweep"] == "bakes"]
    if bakes:
        lines += ["**bakes** (fleece with one change)", "",
                  "| bake | change | s | albedo error % | furnace max (inside the bins) | failed |",
                  "|---|---|---|---|---|---|"]
        def fmt(v, spec):
            return format(v, spec) if v is not None else "-"
        for c in bakes:
            err = c.get("albedo_error")
            lines.append(f"| {c['bake']} | {json.dumps(c['changed'])} | {c.get('seconds', 0):.0f} | "
                         f"{fmt(100 * err if err is not None else None, '.2f')} | {fmt(c.get('furnace_max'), '.4f')} | "
                         f"{str(c['failed'] or '').replace('|', '/')} |")
        lines.append("")
    furn = [c for c in cells if c["sweep"] == "furnace"]
    if furn:
        lines += ["**white furnace** of the shipped models (bin centres / inside the bins and at theta_i 89.975 deg): " +
                  ", ".join(f"{c['preset']} {c.get('furnace_max_centres') or 0:.4f} / {c['furnace_max']:.4f}"
                            for c in furn if c.get("furnace_max") is not None), ""]
    return "\n".join(lines)


# --- main -------------------------------------------------------------------------------------------------

def main(argv: list[str]) -> int:
    ap = ev.Parser(prog="stability.sh", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--quick", action="store_true", help="fleece, 64x32, few cells (CI)")
    ap.add_argument("--sweeps", nargs="+", help=f"sweeps ({', '.join(SWEEPS)}; default all)")
    ap.add_argument("--presets", nargs="+")
    ap.add_argument("--methods", nargs="+", help=f"render methods ({', '.join(RENDER_METHODS)})")
    ap.add_argument("--scale-px", nargs="+", type=float,
                    help="ply widths in pixels of the scale sweep (default: quick 30 3 0.5, full 300 30 3 1 0.5)")
    ap.add_argument("--layers", nargs="+", type=int,
                    help="cloth layers of the layers sweep (default: quick 2 8, full 2 8 32)")
    ap.add_argument("--ref-spp", type=int, help="samples of each reference (default: quick 64, full 512)")
    ap.add_argument("--ref-rotations", type=int,
                    help="orientations each reference averages (default: quick 2, full 4)")
    ap.add_argument("--append", action="store_true",
                    help="keep the cells of DIR/results.json that this run does not redo (same sweep, preset and "
                         "method), so that one results.json, map and summary can gather several runs")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--timeout", type=float, default=1800.0)
    try:
        for tool in (ev.CLI, ev.CYCLES):
            if not os.access(tool, os.X_OK):
                raise ev.Usage(f"{tool} is not built (scripts/setup.sh builds it)")
        args = ap.parse_args(argv)
        cfg = dict(QUICK if args.quick else FULL)
        if args.scale_px:
            if not all(0.0 < v <= 1000.0 for v in args.scale_px):
                raise ev.Usage("--scale-px: widths must be in (0, 1000] pixels")
            cfg["scale_px"] = args.scale_px
        if args.layers:
            if not all(2 <= n <= 256 for n in args.layers):
                raise ev.Usage("--layers: cloth layers must be in [2, 256]")
            cfg["layers"] = args.layers
        for key, value, top in (("ref_spp", args.ref_spp, 1 << 16), ("ref_rotations", args.ref_rotations, 1024)):
            if value is not None:
                if not 1 <= value <= top:
                    raise ev.Usage(f"--{key.replace('_', '-')} must be in [1, {top}], got {value}")
                cfg[key] = value
        sweeps = ev.names(args.sweeps) or SWEEPS
        presets = ev.names(args.presets) or cfg["presets"]
        methods = ev.names(args.methods) or cfg["methods"]
        for kind, given, known in (("sweep", sweeps, SWEEPS), ("preset", presets, ev.PRESETS),
                                   ("method", methods, RENDER_METHODS)):
            for n in given:
                if n not in known:
                    raise ev.Usage(f"unknown {kind} '{n}' (known: {', '.join(known)})")
        if args.threads < 1 or not args.timeout > 0:
            raise ev.Usage("--threads must be at least 1 and --timeout positive")
    except ev.Usage as e:
        print(f"stability: error: {e}", file=sys.stderr)
        return 1
    a = types.SimpleNamespace(out=os.path.abspath(args.out), width=cfg["width"], height=cfg["height"],
                              threads=args.threads, timeout=args.timeout, yarns={}, cfg=cfg, methods=methods,
                              ref_spp=cfg["ref_spp"], ref_rotations=cfg["ref_rotations"])
    for sub in ("scenes", "refs", "renders", "bakes"):
        os.makedirs(os.path.join(a.out, sub), exist_ok=True)
    a.fov = closeup_fov(a)
    progress, cells, t0 = Progress(), [], time.monotonic()
    runners = {"views": sweep_views, "scale": sweep_scale, "units": sweep_units, "samples": sweep_samples,
               "layers": sweep_layers}
    for sw in sweeps:
        if sw in runners:
            for p in presets:
                cells += runners[sw](a, p, progress)
        elif sw == "bakes":
            cells += sweep_bakes(a, progress)
        else:
            cells += sweep_furnace(a, presets, progress)
    commands, earlier_seconds = [["scripts/stability.sh", *argv]], 0.0
    old_path = os.path.join(a.out, "results.json")
    if args.append and os.path.isfile(old_path):
        with open(old_path) as f:
            old = json.load(f)
        redone = {(c["sweep"], c["preset"], c["method"]) for c in cells}
        cells = [c for c in old["cells"] if (c["sweep"], c["preset"], c["method"]) not in redone] + cells
        commands = old["commands"] + commands
        earlier_seconds = old["seconds"]
    results = {"format": "neuralyarn-stability 1", "commands": commands,
               "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
               "git": ev.git_revision(), "machine": {"cpu": ev.cpu_model(), "cores": os.cpu_count()},
               "settings": {k: v for k, v in cfg.items()} | {"threads": a.threads, "quick": args.quick,
                                                            "firefly_factor": FIREFLY_FACTOR,
                                                            "firefly_window": FIREFLY_WINDOW,
                                                            "firefly_floor": FIREFLY_FLOOR},
               "seconds": earlier_seconds + time.monotonic() - t0,
               "cells": cells}
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    stability_map(cells, os.path.join(a.out, "stability_map.png"))
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write(summary(results))
    bad = [c for c in cells if c.get("nan_pixels") or c.get("inf_pixels") or c.get("negative_pixels")]
    log(f"{len(cells)} cells in {time.monotonic() - t0:.0f} s; {len(bad)} with NaN/Inf/negative pixels, "
        f"{sum(1 for c in cells if c['failed'])} failed; wrote {a.out}/results.json, stability_map.png")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
