#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The evaluation harness: fidelity and cost of the neural aggregated model against explicit fibers.

    bash scripts/evaluate.sh --out DIR [--quick] [--presets P ...] [--lights L ...] [--methods M ...]
        [--scenes closeup] [--spp 64 256] [--seeds 1] [--ref-spp 1024] [--ref-rotations 8] [--width 160 --height 80]
        [--distances 12 48 160]
        [--threads N] [--timeout 1800]

Renders every (scene, method, preset, light, spp, seed) with the patched standalone Cycles
(build/cycles/bin/cycles) and measures it against a reference: explicit fibers at --ref-spp, twice per
(scene, preset, light) — reference A is the reference, B against A is the noise floor. Each is the mean of
--ref-rotations renders of the ply turned about its axis (B's angles halfway between A's, other seeds), so
that it holds the mean over the cross-section's orientation, as the maps do (D20), and each render draws its
own fiber cross-section (--ref-layouts each, D42), so that A and B are independent draws of the yarn.
References are cached in DIR/refs and reused when the scene files, the sample count and the Cycles binary are
the same.

Scenes: `garment` (on request; --garment-stitches, default 40 x 40: a plain-knit sleeve of 3-ply yarn,
scripts/garment.py, seen whole at 320 x 240 or --garment-size, the point lights moved out with the camera; its central region is
the middle half of the frame, all fabric; explicit fibers only up to ~50 M curve keys, a 10 x 10 piece for
fleece, larger pieces are refused and recorded as failed), `knit` and `twill` (on request: a 4 x 4 plain knit
and a 6 x 6 twill of 3-ply yarns, scripts/garment.py patch_plies, as examples/make_examples.py draws them, seen
whole in a square image as wide as --width, the point lights moved out with the camera; central region the
middle half of the frame; references of one orientation, as the garment's), and `closeup`, the single-ply close-up of `neuralyarn cycles-scene` (ply radius 1 along x, camera at
distance 12 — or each of --distances, in ply radii: the ply is about height / (0.483 distance) pixels wide —
the ply 48 long, or longer with the distance, so that its ends are out of the frame), and `yarn` (on request), the
same close-up of one straight 3-ply yarn (scripts/garment.py straight_yarn_plies: the garment's plying; the
camera distances are in ply radii, the yarn is 2.33 of them thick). Methods: `explicit` (the fibers
themselves, the reference's method, at the test's samples), `native` (`--model models/<preset>.json`:
one thick curve with the neural_yarn_bsdf closure), on request `yarns` (the yarn level, D27: on the yarn and
the garment, each yarn one thick curve with `--model models/<preset>_yarn.json`), `surface` (the surface level,
D44: on the garment only, the sleeve's mid-surface with stock closures fitted once a run by `neuralyarn surface`
from the yarn-level model on a flat 14 x 14 knit, DIR/scenes/surface_<preset>.json), `osl` and `nodes`: the add-on's
stock-Blender fallbacks on the native method's scene, rendered by the bpy wheel's Cycles
(the scene's description, `cycles-scene --out X.json`, built by the add-on's builder: scripts/fallback_render.py,
with the scene's own model), and the baselines an artist would
use instead, on the native method's geometry (`neuralyarn cycles-scene --list-baselines`: `chiang`, `huang`
(Principled Hair), `sheen` (Principled BSDF)), each with the colour whose central-region mean under the
uniform environment matches reference A's there (fitted per preset, DIR/baselines.json; decisions D23).
Lights: the rigs of `neuralyarn cycles-scene --list-lights`, or sun-DEG-normal / sun-DEG-axis (a distant light DEG
degrees from the view, in the plane normal to the ply or toward its axis).

Metrics against reference A (linear HDR images):
  mean_colour_error        per channel, mean colour / reference mean colour - 1, over the central region:
                           the middle half of the width, the rows whose pixel centres see the ply's bounding
                           cylinder (from the scene's camera), less one row at each silhouette; where the ply
                           is too thin for that (under 3 rows), over the whole frame (the run's `region`);
  mean_colour_error_frame  the same over the whole frame;
  mean_luminance_error     the same for Rec. 709 luminance, central region;
  flip                     mean HDR-FLIP (NVIDIA, PyPI flip-evaluator), 67 pixels per degree, whole frame;
  flip_colour_matched      the same after each channel of the image is scaled to the reference's whole-frame
                           mean: the error of the image's structure alone (a pattern missing or misplaced), so
                           flip - flip_colour_matched is what a right mean colour would gain;
  relmse                   mean over pixels of mean_c (x - r)^2 / (r^2 + 0.01), the top 0.1 % discarded;
  ssim                     scripts/images.py: display images (the reference's 99.5th percentile
                           maps to 1, clamped, sRGB), Gaussian window sigma 1.5.
Cost: seconds_load (wall time of a 1-sample render of the same scene, the median of three; of one in --quick), seconds_render
(wall time minus that), peak_rss_mb (/usr/bin/time %M), baseline_rss_mb (an empty scene's in the method's own
renderer: the standalone Cycles, or Blender for osl and nodes; both in results.json's `baseline_rss_mb`),
curve_keys (cycles-scene's report of the scene). Speed against error (scripts/evaluate_charts.py): per (scene, preset, light) FLIP against render
time over --spp, one curve per method; results.json's `summary` has per scene and method the speed-up over
explicit fibers at equal FLIP and at equal samples, and the memory ratio above the baseline.

Writes DIR/results.json, DIR/summary.md (also printed), DIR/strips/<scene>_<preset>_<light>.png
(reference | native | explicit at the first --spp, one exposure), DIR/charts/ (error against time with two
or more --spp, error against the ply's size on screen with two or more --distances).
One progress line per render on
stderr. Exit codes: 0 all rendered, 1 bad arguments or a missing build/model (one line on stderr, nothing
rendered), 2 some renders failed (recorded in results.json with the reason).
"""
from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import math
import os
import platform
import re
import signal
import subprocess
import sys
import functools
import tempfile
import time
import types
from collections.abc import Callable

import numpy as np

from evaluate_charts import (CLOSEUP_DISTANCE, REFERENCE_METHOD, auto_summary, auto_table, error_distance_charts,
                             error_time_charts, group_of, label, level_summary, speed_summary, stem, summary_table)
from garment import PATCHES, flat_knit_plies, garment_plies, patch_plies, straight_yarn_plies, yarn_radius
from images import LUMINANCE, display, display_ssim, exposure_of, read_exr, write_exr

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
BUILD = os.environ.get("NY_BUILD_DIR", os.path.join(ROOT, "build"))
CLI = os.path.join(BUILD, "cpp_core", "neuralyarn")
CYCLES = os.path.join(BUILD, "cycles", "bin", "cycles")
MODELS = os.path.join(ROOT, "models")

with open(os.path.join(ROOT, "cpp_core", "data", "presets.json"), encoding="utf-8") as _f:
    PRESETS = list(json.load(_f)["presets"])  # the core's preset list, in its order
SCENES = ["closeup", "yarn", *PATCHES, "garment"]
#: Scenes seen from --distances (the others frame themselves).
DISTANCE_SCENES = ("closeup", "yarn")
#: Scenes of many plies, framed whole: their central region is the middle half of the frame, their references
#: one orientation (the plies already show the cross-section turned by the golden angle from ply to ply).
FRAMED_SCENES = (*PATCHES, "garment")
DEFAULT_SCENES = ["closeup"]
#: The garment (scripts/garment.py: a plain-knit sleeve of 3-ply yarn): image size, explicit fibers' keys per
#: helix turn (the examples' patches use as many), the frame's margin around the tube, references of one
#: orientation (its plies already show the cross-section turned by the golden angle from ply to ply).
GARMENT = {"width": 320, "height": 240, "segments_per_turn": 12, "margin": 1.08, "ref_rotations": 1}
METHODS = ["explicit", "native", "yarns", "surface", "osl", "nodes"]  # + the baselines of the CLI (cli_table)
DEFAULT_METHODS = ["explicit", "native"]
#: Methods rendered by Blender (the bpy wheel) from the native method's scene.
FALLBACKS = ("osl", "nodes")
#: The baselines' colour fit (fit_baseline): samples per fitting render, renders at most, and the largest
#: relative error per channel of the central-region mean that ends it.
BASELINE_FIT = {"spp": 64, "renders": 8, "tolerance": 0.005}
FALLBACK_RENDER = os.path.join(ROOT, "scripts", "fallback_render.py")
# Cycles integrator seeds: the runs use 1..--seeds, the references two seeds of their own.
REFERENCE_SEEDS = {"A": 1001, "B": 1002}
# Whether each render a reference averages has its own fiber cross-section ("each", the default) or all share
# the one the maps are gathered on ("one", the references before D42). With one, A and B show the same fibers
# and the noise floor (B against A) leaves out the fibers' own texture, which no far-field model renders.
REFERENCE_LAYOUTS = ("each", "one")
# A reference is the mean of renders of the explicit ply turned about its axis to evenly spaced angles (A at
# k 360/K, B halfway between, each with seed base + 2k and 1/K of the samples): the camera of the close-up sees
# about a third of a twist period or less (silk is untwisted), so one render shows one orientation of the
# random cross-section, while the maps and the model hold the mean over all of them. Under the back light one
# orientation of silk differs from the next by up to a factor 3.8 (docs/decisions.md D20).
PLY_RADIUS = 1.0  # cycles-scene's unit
# The close-up's ply is longer than cycles-scene's default (16): its ends must lie outside the frame (the
# frame is 23 radii wide at the ply, 2:1) and far enough from the central region that light entering through
# an end cap does not reach it (the axis rig: with 16 it does; docs/benchmarks.md).
CLOSEUP_PLY_LENGTH = 48.0
CLOSEUP_FOV = 0.9  # cycles-scene's field of view (radians, of the image's shorter side)
FLIP_PPD = 67.0
RELMSE_EPS = 0.01
RELMSE_DISCARD = 0.001
# load_renders: 1-sample renders whose median is a method's load time (the quick run checks that the numbers
# exist, not their noise: one, which saves two loads of every explicit-fiber scene in CI).
QUICK = {"width": 96, "height": 48, "ref_spp": 64, "ref_rotations": 2, "spp": [4], "presets": ["fleece"],
         "lights": ["key-rim", "grazing"], "load_renders": 1}
DEFAULTS = {"width": 160, "height": 80, "ref_spp": 1024, "ref_rotations": 8, "spp": [64], "presets": PRESETS,
            "lights": None, "load_renders": 3}


class Usage(Exception):
    """A bad argument, a missing build or model: one line on stderr, exit code 1."""


class RenderFailed(Exception):
    pass


def log(msg: str) -> None:
    print(f"evaluate: {msg}", file=sys.stderr, flush=True)


# --- command line ------------------------------------------------------------------------------------

class Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own errors: one line and exit code 1, as every other error
        raise Usage(message)


def names(values: list[str] | None) -> list[str] | None:
    """`a b`, `a,b` or a mix."""
    if values is None:
        return None
    return [n for v in values for n in v.split(",") if n]


def parse_args(argv: list[str], rigs: dict[str, str], baselines: list[str]) -> argparse.Namespace:
    ap = Parser(prog="evaluate.sh", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="output directory (created; references cached there)")
    ap.add_argument("--quick", action="store_true",
                    help="96x48, reference 64 spp, 4 spp, fleece, lights key-rim and grazing (unless given)")
    ap.add_argument("--scenes", nargs="+", help=f"scenes ({', '.join(SCENES)}; default {', '.join(DEFAULT_SCENES)})")
    ap.add_argument("--garment-stitches", type=int, default=40,
                    help="the garment's stitches around and rows (default 40: 40 x 40)")
    ap.add_argument("--garment-size", type=int, nargs=2, metavar=("W", "H"),
                    default=[GARMENT["width"], GARMENT["height"]],
                    help=f"the garment's image size (default {GARMENT['width']} {GARMENT['height']}; smaller: "
                         "the yarns below a pixel, where the surface level is meant)")
    ap.add_argument("--methods", nargs="+",
                    help=f"methods ({', '.join(METHODS)}; default {', '.join(DEFAULT_METHODS)})")
    ap.add_argument("--presets", nargs="+", help=f"presets ({', '.join(PRESETS)}; default all)")
    ap.add_argument("--lights", nargs="+", help=f"light rigs ({', '.join(rigs)}, or sun-DEG-normal / sun-DEG-axis: "
                                                "a distant light DEG degrees from the view; default the rigs)")
    ap.add_argument("--yarn", action="append", default=[], metavar="NAME=PARAMS.json,MODEL.json",
                    help="a yarn beyond the presets: its fiber parameter file and model (repeatable; added to "
                         "--presets)")
    ap.add_argument("--spp", nargs="+", help="samples per pixel of the tested renders (default 64)")
    ap.add_argument("--seeds", type=int, help="seeds per render (Cycles seeds 1..N; default 1)")
    ap.add_argument("--ref-spp", type=int, help="samples per pixel of the references (default 1024)")
    ap.add_argument("--ref-rotations", type=int,
                    help="orientations of the explicit ply about its axis that a reference averages, sharing "
                         "its samples, each its own fiber cross-section (default 8; measured floors of B against A "
                         "under 5 %%: 16 for the environment, front and grazing lights, 128 for back, 256 for "
                         "axis, where silk's and cotton's glints want more --ref-spp too: docs/benchmarks.md)")
    ap.add_argument("--ref-layouts", choices=REFERENCE_LAYOUTS, default="each",
                    help="each: every render a reference averages has its own fiber cross-section, so that A and B "
                         "are independent draws of the yarn (default); one: all on the maps' cross-section (before "
                         "D42)")
    ap.add_argument("--width", type=int, help="image width (default 160)")
    ap.add_argument("--height", type=int, help="image height (default 80)")
    ap.add_argument("--distances", nargs="+",
                    help="camera distances from the ply axis in ply radii (default 12: the close-up; 160 makes the "
                         "ply about a pixel wide at height 80)")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1, help="Cycles threads (default: all cores)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds before a render counts as failed")
    a = ap.parse_args(argv)
    base = QUICK if a.quick else DEFAULTS
    a.scenes = names(a.scenes) or DEFAULT_SCENES
    if not 1 <= a.garment_stitches <= 400:
        raise Usage(f"--garment-stitches must be in [1, 400], got {a.garment_stitches}")
    if not all(8 <= v <= 8192 for v in a.garment_size):
        raise Usage(f"--garment-size must be two sizes in [8, 8192], got {a.garment_size[0]} {a.garment_size[1]}")
    a.methods = names(a.methods) or DEFAULT_METHODS
    a.presets = names(a.presets) or base["presets"]
    a.lights = names(a.lights) or base["lights"] or list(rigs)
    for n in a.lights:
        if n not in rigs and n.startswith("sun-"):
            rigs.update(cli_table("--describe-light", n))  # sun-DEG-normal, sun-DEG-axis (one parser: the CLI's)
    a.yarns = {}
    for spec in a.yarn:
        name, _, files = spec.partition("=")
        params, _, model = files.partition(",")
        if not (name and params and model) or name in PRESETS or not re.fullmatch(r"[A-Za-z0-9_-]+", name):
            raise Usage(f"--yarn: '{spec}' is not NAME=PARAMS.json,MODEL.json with a new name of letters and digits")
        for f in (params, model):
            if not os.path.isfile(f):
                raise Usage(f"--yarn {name}: '{f}' does not exist")
        a.yarns[name] = {"params": os.path.abspath(params), "model": os.path.abspath(model)}
    a.baselines = [m for m in a.methods if m in baselines]
    for kind, given, known in (("scene", a.scenes, SCENES), ("method", a.methods, METHODS + baselines),
                               ("preset", a.presets, PRESETS + list(a.yarns)), ("light", a.lights, list(rigs))):
        for n in given:
            if n not in known:
                raise Usage(f"unknown {kind} '{n}' (known: {', '.join(known)})")
    try:
        a.spp = [int(s) for s in names(a.spp)] if a.spp else base["spp"]
    except ValueError:
        raise Usage(f"--spp must be whole numbers, got {' '.join(a.spp)}")
    a.width = a.width if a.width is not None else base["width"]
    a.height = a.height if a.height is not None else base["height"]
    a.ref_spp = a.ref_spp if a.ref_spp is not None else base["ref_spp"]
    a.ref_rotations = a.ref_rotations if a.ref_rotations is not None else base["ref_rotations"]
    a.load_renders = base["load_renders"]
    a.seeds = a.seeds if a.seeds is not None else 1
    try:
        a.distances = [float(d) for d in names(a.distances)] if a.distances else [CLOSEUP_DISTANCE]
    except ValueError:
        raise Usage(f"--distances must be numbers, got {' '.join(a.distances)}")
    for d in a.distances:
        if not (1.0001 <= d <= 1e4) or ply_length(d, a) > 1000.0:
            raise Usage(f"--distances: {d:g} is not in [1.0001, 1e4] ply radii with a ply of at most 1000 radii in the frame")
    for flag, v in (("--spp", min(a.spp)), ("--ref-spp", a.ref_spp), ("--ref-rotations", a.ref_rotations),
                    ("--seeds", a.seeds), ("--width", a.width),
                    ("--height", a.height), ("--threads", a.threads)):
        if v < 1:
            raise Usage(f"{flag} must be at least 1, got {v}")
    if not a.timeout > 0:
        raise Usage(f"--timeout must be positive, got {a.timeout}")
    if a.ref_spp % a.ref_rotations:
        raise Usage(f"--ref-spp ({a.ref_spp}) must be a multiple of --ref-rotations ({a.ref_rotations})")
    a.presets += [y for y in a.yarns if y not in a.presets]
    if "native" in a.methods or any(m in FALLBACKS for m in a.methods) or a.baselines:
        for p in a.presets:
            if not os.path.isfile(model_path(a.yarns, p)):
                raise Usage(f"method native: model '{model_path(a.yarns, p)}' is missing (scripts/bake_models.sh makes it)")
    if "yarns" in a.methods:
        if a.yarns:
            raise Usage("method yarns renders the presets only (their yarn-level models)")
        if "closeup" in a.scenes or any(p in a.scenes for p in PATCHES):
            raise Usage("method yarns draws yarns: scenes yarn and garment (the close-up is one ply, the patches' "
                        "plies files have no yarns)")
        for p in a.presets:
            if not os.path.isfile(yarn_model_path(p)):
                raise Usage(f"method yarns: model '{yarn_model_path(p)}' is missing "
                            "(NY_LEVEL=yarn scripts/bake_models.sh makes it)")
    if "surface" in a.methods:
        if a.yarns:
            raise Usage("method surface renders the presets only (it is fitted from their yarn-level models)")
        if any(sc != "garment" for sc in a.scenes):
            raise Usage("method surface draws a cloth surface: scene garment only")
        for p in a.presets:
            if not os.path.isfile(yarn_model_path(p)):
                raise Usage(f"method surface: model '{yarn_model_path(p)}' is missing "
                            "(NY_LEVEL=yarn scripts/bake_models.sh makes it)")
    return a


def model_path(yarns: dict, preset: str) -> str:
    """The model of a preset (models/), or of a --yarn (`yarns`: name -> {"params", "model"})."""
    return yarns[preset]["model"] if preset in yarns else os.path.join(MODELS, f"{preset}.json")


def yarn_model_path(preset: str) -> str:
    """A preset's yarn-level model (models/<preset>_yarn.json)."""
    return os.path.join(MODELS, f"{preset}_yarn.json")


def yarn_args(yarns: dict, preset: str) -> list[str]:
    """cycles-scene's fiber source: a preset's name, or a --yarn's parameter file."""
    return ["--params", yarns[preset]["params"]] if preset in yarns else ["--preset", preset]


# --- scenes and renders --------------------------------------------------------------------------------

def run_cli(args: list[str]) -> str:
    try:
        r = subprocess.run([CLI, *args], capture_output=True, text=True)
    except OSError as e:
        raise RenderFailed(f"neuralyarn {args[0]}: {e}")
    if r.returncode != 0:
        raise RenderFailed(f"neuralyarn {' '.join(args)}: {(r.stderr or r.stdout).strip()}")
    return r.stdout


def cli_table(flag: str, *values: str) -> dict[str, str]:
    """name -> description of `neuralyarn cycles-scene --list-lights`, `--list-baselines` (the one table of
    each, cpp_core/src/scenes/ply_scene.cpp) or `--describe-light NAME` (a sun-DEG-normal / sun-DEG-axis)."""
    r = subprocess.run([CLI, "cycles-scene", flag, *values], capture_output=True, text=True)
    if r.returncode != 0:
        raise Usage(f"neuralyarn cycles-scene {' '.join((flag, *values))} failed: {r.stderr.strip().splitlines()[0]}")
    table = {}
    for line in r.stdout.splitlines():
        name, _, desc = line.strip().partition(" ")
        table[name] = desc.strip()
    return table


def light_rigs() -> dict[str, str]:
    return cli_table("--list-lights")


def map_header(path: str) -> dict:
    """A radiance distribution map file's JSON header, with `payload_start` (the payload's byte offset in the
    file) added (docs/file_formats.md)."""
    with open(path, "rb") as f:
        if f.read(8) != b"NYRDM\r\n\x1a":
            raise ValueError(f"{path}: not a radiance distribution map file (.nyrdm)")
        f.read(4)  # the format version
        length = int.from_bytes(f.read(8), "little")
        header = json.loads(f.read(length))
    header["payload_start"] = 20 + length
    return header


def map_gather(path: str) -> dict:
    """The `gather` object of a radiance distribution map file's header (paths, seed, ...)."""
    return map_header(path)["gather"]


def ply_length(distance: float, a) -> float:
    """The close-up's ply length at a camera distance: 48 at the close-up's 12, growing with the frame's width
    at the ply (its ends out of the frame and far from the central region)."""
    across = 2.0 * distance * math.tan(0.5 * CLOSEUP_FOV) * max(a.width, a.height) / min(a.width, a.height)
    return round(max(CLOSEUP_PLY_LENGTH, 2.1 * across), 1)


def fallback_of(method: str) -> str | None:
    """The add-on's body (osl, nodes) Blender renders a method with; None: the standalone Cycles renders it."""
    return method if method in FALLBACKS else None


def scene_ext(method: str) -> str:
    """A method's scene file: Cycles XML, or for Blender the scene description its builder reads."""
    return "json" if fallback_of(method) else "xml"


def scene_path(a, scene: str, method: str, preset: str, light: str, seed: int, rotation: float = 0.0,
               distance: float | None = CLOSEUP_DISTANCE, packing_seed: int | None = None) -> str:
    """Where write_scene writes the scene of one render (scene_ext)."""
    turned = f"_rot{rotation:g}" if rotation else ""
    layout = f"_packing{packing_seed}" if packing_seed is not None else ""
    return os.path.join(a.out, "scenes", f"{stem((scene, preset, light, distance))}_{method}_seed{seed}{turned}"
                                         f"{layout}.{scene_ext(method)}")


def for_scene(a, scene: str):
    """The settings as one scene renders with them (the garment's own image size, a patch's square one, and
    their references of one orientation)."""
    if scene == "garment":
        return types.SimpleNamespace(**{**vars(a), "width": a.garment_size[0], "height": a.garment_size[1],
                                        "ref_rotations": GARMENT["ref_rotations"]})
    if scene in PATCHES:
        return types.SimpleNamespace(**{**vars(a), "height": a.width, "ref_rotations": 1})
    return a


@functools.lru_cache(maxsize=None)
def patch_scene_args(out: str, kind: str) -> tuple[str, ...]:
    """cycles-scene's arguments for a patch (garment.patch_plies): its plies file (OUT/<kind>_plies.json, written
    once a run) and a camera that frames it (the close-up's field of view)."""
    p = patch_plies(kind)
    return framed_plies_args(os.path.join(out, f"{kind}_plies.json"), p, 0.55 * p["size"] / math.tan(0.5 * CLOSEUP_FOV))


def framed_plies_args(path: str, plies: dict, distance: float) -> tuple[str, ...]:
    """cycles-scene's arguments for a plies file's content (written to `path`) seen from `distance` ply radii: the
    close-up's point lights moved out with the camera (the same irradiance), the garment's keys per helix turn
    for the explicit fibers."""
    with open(path, "w") as f:
        json.dump(plies, f, separators=(",", ":"))
    return ("--plies", path, "--camera-distance", f"{distance:.4f}", "--light-scale",
            f"{distance / CLOSEUP_DISTANCE:.6g}", "--segments-per-turn", str(GARMENT["segments_per_turn"]))


def garment_scene_args(a) -> list[str]:
    return list(garment_framing(a.out, a.garment_stitches, a.width / a.height))


@functools.lru_cache(maxsize=None)
def garment_framing(out: str, n: int, aspect: float) -> tuple[str, ...]:
    """cycles-scene's arguments for the garment: its plies file (DIR/scenes/garment_SxS.json, written once a
    run), the camera that frames the whole tube in an image of that aspect, the point lights moved out with it."""
    g = garment_plies(n, n)
    return framed_plies_args(os.path.join(out, "scenes", f"garment_{n}x{n}.json"), g, garment_distance(g, aspect))


def garment_distance(g: dict, aspect: float) -> float:
    """The camera distance (ply radii) that frames the whole tube of garment_plies' content `g`, with a margin, in
    an image of that aspect (width / height)."""
    t = math.tan(0.5 * CLOSEUP_FOV)  # the shorter side's: the height here
    return GARMENT["margin"] * max(0.5 * g["height"] / t, 0.5 * g["width"] / (t * aspect))


#: The surface level's fit (D44): the flat knit it walks through (the garment's pattern, wide enough that few
#: paths leave near its edge) and the paths (over both faces and 8 view bins).
SURFACE_FIT = {"rows": 14, "stitches": 14, "paths": "8e6", "seed": 1}


@functools.lru_cache(maxsize=None)
def surface_file(out: str, preset: str) -> str:
    """The surface level's BSDF of a preset's knit (DIR/scenes/surface_<preset>.json, fitted once a run by
    `neuralyarn surface` from the preset's yarn-level model on the flat knit)."""
    flat = os.path.join(out, "scenes", "flat_knit.json")
    if not os.path.isfile(flat):
        with open(flat, "w") as f:
            json.dump(flat_knit_plies(SURFACE_FIT["rows"], SURFACE_FIT["stitches"]), f, separators=(",", ":"))
    path = os.path.join(out, "scenes", f"surface_{preset}.json")
    t0 = time.monotonic()
    run_cli(["surface", "--plies", flat, "--model", yarn_model_path(preset), "--paths", SURFACE_FIT["paths"],
             "--seed", str(SURFACE_FIT["seed"]), "--quiet", "--out", path])
    log(f"surface level of {preset}: fitted in {time.monotonic() - t0:.1f} s")
    return path


@functools.lru_cache(maxsize=None)
def straight_yarn_file(out: str, length: float) -> str:
    """The yarn close-up's plies file (DIR/scenes/yarn_L.json, written once a run)."""
    path = os.path.join(out, "scenes", f"yarn_{length:g}.json")
    with open(path, "w") as f:
        json.dump(straight_yarn_plies(length), f, separators=(",", ":"))
    return path


def write_scene(a, scene: str, method: str, preset: str, light: str, seed: int, rotation: float = 0.0,
                colour: list[float] | None = None, distance: float = CLOSEUP_DISTANCE,
                packing_seed: int | None = None) -> str:
    """The scene file of one render (`neuralyarn cycles-scene`: the close-up, or with `--plies` the garment);
    `rotation` turns the explicit ply (each ply) about its axis (degrees), `packing_seed` draws its fiber
    cross-section (default: cycles-scene's, the maps'); a baseline method needs its `colour`."""
    path = scene_path(a, scene, method, preset, light, seed, rotation, distance, packing_seed)
    args = [*yarn_args(a.yarns, preset), "--lights", light, "--seed", str(seed), "--width", str(a.width),
            "--height", str(a.height), "--out", path]
    if scene == "garment":
        args += garment_scene_args(a)
    elif scene in PATCHES:
        args += patch_scene_args(os.path.join(a.out, "scenes"), scene)
    elif scene == "yarn":
        args += ["--plies", straight_yarn_file(a.out, ply_length(distance, a)), "--camera-distance", f"{distance:g}"]
    else:
        args += ["--ply-length", f"{ply_length(distance, a):g}"]
        if distance != CLOSEUP_DISTANCE:
            args += ["--camera-distance", f"{distance:g}"]
    if rotation:
        args += ["--ply-rotation", f"{rotation:g}"]
    if packing_seed is not None:
        args += ["--packing-seed", str(packing_seed)]
    if method == "native" or method in FALLBACKS:
        args += ["--model", model_path(a.yarns, preset)]
    elif method == "yarns":
        args += ["--level", "yarns", "--model", yarn_model_path(preset)]
    elif method == "surface":
        args += ["--level", "surface", "--surface", surface_file(a.out, preset)]
    elif method in a.baselines:
        args += ["--baseline", method, "--baseline-colour", *(f"{c:.6f}" for c in colour)]
    cycles_scene(args)
    return path


#: What `neuralyarn cycles-scene` reported of each scene file it wrote in this run (cycles_scene()): its curves,
#: curve keys and camera. The harness takes them from the writer, never from the scene's text.
WRITTEN: dict[str, dict] = {}
WROTE = re.compile(r"wrote (.+) \((\d+) curves, (\d+) curve keys; camera at (\S+) (\S+) (\S+), fov (\S+)\)")


def cycles_scene(args: list[str]) -> None:
    """Runs `neuralyarn cycles-scene ARGS` and records what it reports of every file it wrote (WRITTEN). Raises
    RenderFailed with the tool's message."""
    reported = [WROTE.fullmatch(line.strip()) for line in run_cli(["cycles-scene", *args]).splitlines()]
    for m in filter(None, reported):
        WRITTEN[m.group(1)] = {"curves": int(m.group(2)), "curve_keys": int(m.group(3)),
                               "camera_position": [float(m.group(k)) for k in (4, 5, 6)], "fov": float(m.group(7))}
    if not any(reported):
        raise RenderFailed(f"neuralyarn cycles-scene {' '.join(args)}: reported no scene written")


def written(scene: str) -> dict:
    if scene not in WRITTEN:
        raise RenderFailed(f"{scene}: not written by cycles-scene in this run")
    return WRITTEN[scene]


def render_image(a, scene_args: list[str], stem: str, spp: int, finite: bool = True,
                 edit: Callable[[str], str] | None = None) -> np.ndarray:
    """`neuralyarn cycles-scene SCENE_ARGS` written to STEM.xml (its text passed through `edit`, a test's fixture, if
    given), rendered by the patched Cycles to STEM.exr (render(): its progress line, its errors as RenderFailed, with
    `finite` non-finite pixels among them): the image's RGB."""
    cycles_scene([*scene_args, "--out", stem + ".xml"])
    if edit is not None:
        with open(stem + ".xml") as f:
            text = edit(f.read())
        with open(stem + ".xml", "w") as f:
            f.write(text)
    render(a, stem + ".xml", spp, stem + ".exr", f"{os.path.basename(stem)}, {spp} spp", finite=finite)
    return read_exr(stem + ".exr")[..., :3]


def with_diffuse_quad(text: str, name: str, colour: tuple[float, float, float],
                      corners: tuple[tuple[float, float, float], ...]) -> str:
    """A scene's XML text with a diffuse quad added before its end (a test's fixture for render_image's `edit`: a
    floor, a wall): shader and mesh named `name`, `corners` its four (x, y, z) in order."""
    points = " ".join(f"{v:g}" for c in corners for v in c)
    quad = (f'<shader name="{name}">\n  <diffuse_bsdf name="d" color="{" ".join(f"{v:g}" for v in colour)}" />\n'
            f'  <connect from="d bsdf" to="output surface" />\n</shader>\n<state shader="{name}">\n'
            f'  <mesh P="{points}" nverts="4" verts="0 1 2 3" />\n</state>\n')
    return text.replace("</cycles>", quad + "</cycles>")


def empty_scene(a, ext: str = "xml") -> str:
    """Camera and a black background only: the renderer's own memory (baseline_rss_mb); `ext` json for Blender."""
    path = os.path.join(a.out, "scenes", f"empty.{ext}")
    cycles_scene(["--empty", "--width", str(a.width), "--height", str(a.height), "--out", path])
    return path


def render(a, scene: str, spp: int, exr: str, what: str, fallback: str | None = None,
           finite: bool = True) -> dict:
    """Renders with the patched Cycles, or with `fallback` (osl or nodes) a scene description with that body of
    the add-on's node in Blender (scripts/fallback_render.py); returns seconds (wall) and peak_rss_mb, and logs
    the time. Raises RenderFailed with the reason
    (exit code, signal, timeout, no image, and with `finite` non-finite pixels): the caller logs it."""
    t0 = time.monotonic()
    with tempfile.NamedTemporaryFile("r", suffix=".time") as tf:
        if fallback:
            tool = [sys.executable, FALLBACK_RENDER, scene, exr, "--body", fallback, "--samples", str(spp),
                    "--threads", str(a.threads)]
        else:
            tool = [CYCLES, "--background", "--quiet", "--samples", str(spp), "--threads", str(a.threads),
                    "--width", str(a.width), "--height", str(a.height), "--output", exr, scene]
        cmd = ["/usr/bin/time", "-f", "%M", "-o", tf.name, *tool]
        if os.path.exists(exr):
            os.remove(exr)
        # A session of its own, so that a timeout kills Cycles too, not only /usr/bin/time.
        try:
            p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 start_new_session=True)
        except OSError as e:
            raise RenderFailed(f"cannot run cycles: {e}")
        try:
            out, err = p.communicate(timeout=a.timeout)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.communicate()
            raise RenderFailed(f"timed out after {a.timeout:g} s")
        seconds = time.monotonic() - t0
        lines = [ln for ln in tf.read().splitlines() if ln.strip()]
    tail = " ".join((err or out or "").strip().splitlines()[-3:])
    if p.returncode != 0:
        reason = f"{'blender' if fallback else 'cycles'} exited with {p.returncode}" + (
            f" ({signal.Signals(p.returncode - 128).name})" if p.returncode > 128 else "")
        raise RenderFailed(f"{reason}: {tail}" if tail else reason)
    if not os.path.isfile(exr):
        raise RenderFailed(f"cycles wrote no image: {tail}")
    img = read_exr(exr)
    if finite and not np.isfinite(img).all():
        raise RenderFailed(f"{int((~np.isfinite(img)).sum())} non-finite pixel values")
    log(f"{what}: {seconds:.1f} s")
    return {"seconds": seconds, "peak_rss_mb": float(lines[-1]) / 1024.0 if lines else None}


@functools.lru_cache(maxsize=None)
def cycles_sha256() -> str:
    return sha256(CYCLES)


def sha256(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def curve_keys(scene: str) -> int:
    """Curve control points in a scene written in this run (cycles-scene's report)."""
    return written(scene)["curve_keys"]


def camera(scene: str) -> tuple[float, float]:
    """(distance, fov) of the close-up's camera in a scene written in this run (cycles-scene's report): at
    (0, 0, -distance) looking along +z."""
    w = written(scene)
    x, y, z = w["camera_position"]
    if x != 0.0 or y != 0.0 or z >= 0.0:
        raise RenderFailed(f"{scene}: the camera is at {x:g} {y:g} {z:g}, not on the -z axis as the close-up's")
    return -z, w["fov"]


def central_region(distance: float, fov: float, width: int, height: int,
                   radius: float = PLY_RADIUS) -> tuple[slice, slice]:
    """Rows and columns of the central region: the middle half of the width; the rows whose pixel-centre
    rays (x = 0) hit the ply's bounding cylinder y^2 + z^2 = R^2, less one row at each silhouette, where the
    pixel filter mixes ply and background."""
    # Cycles' standalone camera applies the field of view to the shorter side of the image.
    t = math.tan(0.5 * fov) * (1.0 if width >= height else height / width)
    # A ray from (0, 0, -d) with direction (0, v, 1) passes the axis at distance d |v| / sqrt(1 + v^2).
    v_max = radius / math.sqrt(distance * distance - radius * radius)
    rows = [py for py in range(height) if abs((1.0 - 2.0 * (py + 0.5) / height) * t) <= v_max]
    if len(rows) < 3:
        raise RenderFailed(f"{width}x{height}: the ply covers {len(rows)} rows, too few for a central region")
    return slice(rows[0] + 1, rows[-1]), slice(width // 4, width - width // 4)


def framed_region(width: int, height: int) -> tuple[slice, slice]:
    """Rows and columns of a framed scene's central region: the middle half of the frame, the fabric."""
    return slice(height // 4, height - height // 4), slice(width // 4, width - width // 4)


def ply_band(region: tuple[slice, slice]) -> tuple[slice, slice]:
    """The ply's rows over a central region's columns: the region and the silhouette row it leaves out on
    each side."""
    rows, cols = region
    return slice(rows.start - 1, rows.stop + 1), cols


# --- metrics -------------------------------------------------------------------------------------------

def region_share(ref: np.ndarray, region: tuple[slice, slice], around: tuple[slice, slice] | None = None) -> float | None:
    """The share of the reference's light (Rec. 709 luminance) in `around` (default: the frame) that falls in
    the region. For the ply scenes `around` is the ply's rows over the region's columns: the region plus a
    silhouette row on each side, so that a lit background (the environment) does not count. Where the share
    is small (a dark ply lit from behind glows only at its silhouette rows) the region's mean is a faint
    remainder and its relative error says little about the look: read the frame's error there."""
    lum = ref @ LUMINANCE  # read_exr gives (H, W, 3)
    total = float(lum[around if around is not None else (slice(None), slice(None))].sum())
    return float(lum[region].sum()) / total if total > 0.0 else None


def metrics(img: np.ndarray, ref: np.ndarray, region: tuple[slice, slice]) -> dict:
    import flip_evaluator

    def rel(a, b):
        return [float(x) for x in (a / b - 1.0)]

    m_img, m_ref = img[region].mean(axis=(0, 1)), ref[region].mean(axis=(0, 1))
    f_img, f_ref = img.mean(axis=(0, 1)), ref.mean(axis=(0, 1))
    out = {
        "mean_colour_error": rel(m_img, m_ref),
        "mean_colour_error_frame": rel(f_img, f_ref),
        "mean_luminance_error": float(m_img @ LUMINANCE / (m_ref @ LUMINANCE) - 1.0),
        "mean_luminance_error_frame": float(f_img @ LUMINANCE / (f_ref @ LUMINANCE) - 1.0),
    }
    def flip(test):
        _, mean_flip, _ = flip_evaluator.evaluate(np.ascontiguousarray(ref, dtype=np.float32),
                                                  np.ascontiguousarray(test, dtype=np.float32), "HDR",
                                                  applyMagma=False, parameters={"ppd": FLIP_PPD})
        return float(mean_flip)

    out["flip"] = flip(img)
    # A black channel stays black: no scale makes it the reference's, and dividing by zero would make NaN.
    scale = np.where(f_img > 0.0, f_ref / np.where(f_img > 0.0, f_img, 1.0), 1.0)
    out["flip_colour_matched"] = flip(img * scale)
    e = (((img - ref) ** 2) / (ref ** 2 + RELMSE_EPS)).mean(axis=2).ravel()
    keep = np.sort(e)[: max(1, int(math.ceil(e.size * (1.0 - RELMSE_DISCARD))))]
    out["relmse"] = float(keep.mean())
    out["ssim"] = display_ssim(ref, img, exposure_of(ref))
    return out


METRIC_KEYS = ["flip", "flip_colour_matched", "relmse", "ssim", "mean_colour_error", "mean_colour_error_frame",
               "mean_luminance_error", "mean_luminance_error_frame"]


# --- the run -------------------------------------------------------------------------------------------

def git_revision() -> dict:
    def git(*args):
        r = subprocess.run(["git", "-C", ROOT, *args], capture_output=True, text=True)
        return r.stdout.strip() if r.returncode == 0 else None
    rev = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"revision": rev, "dirty": bool(status) if status is not None else None}


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


class Progress:
    def __init__(self, total: int):
        self.done, self.total = 0, total

    def __call__(self, what: str) -> str:
        self.done += 1
        return f"[{self.done}/{self.total}] {what}"


def reference_parts(which: str, k_count: int, layouts: str = "each") -> list[tuple[int, float, int | None]]:
    """(Cycles seed, ply rotation in degrees, packing seed) of the k_count renders that reference `which` (A or
    B) averages: A at k 360/K, B halfway between, each with seed base + 2k; with layouts "each" the fiber
    cross-section's packing seed is that seed too (every render its own cross-section, none shared between A
    and B), with "one" None (cycles-scene's default, the cross-section the maps are gathered on)."""
    if layouts not in REFERENCE_LAYOUTS:
        raise ValueError(f"layouts must be one of {', '.join(REFERENCE_LAYOUTS)}, got '{layouts}'")
    offset = 0.0 if which == "A" else 0.5
    return [(REFERENCE_SEEDS[which] + 2 * k, (k + offset) * 360.0 / k_count,
             REFERENCE_SEEDS[which] + 2 * k if layouts == "each" else None) for k in range(k_count)]


def reference_scene(a, scene: str, preset: str, light: str, distance: float | None = CLOSEUP_DISTANCE) -> str:
    """The scene file of reference A's first render (its camera is the scene's camera)."""
    seed, rot, packing = reference_parts("A", a.ref_rotations, a.ref_layouts)[0]
    return scene_path(a, scene, REFERENCE_METHOD, preset, light, seed, rot, distance, packing)


def reference(a, scene: str, preset: str, light: str, which: str, what: str,
              distance: float = CLOSEUP_DISTANCE) -> dict:
    """Reference `which` (A or B) of (scene, preset, light): the mean of a.ref_rotations renders of the
    explicit ply turned about its axis (REFERENCE_SEEDS), or reused from DIR/refs when the scene files and the
    samples are the same."""
    k_count, spp = a.ref_rotations, a.ref_spp // a.ref_rotations
    parts = reference_parts(which, k_count, a.ref_layouts)
    xmls = [write_scene(a, scene, REFERENCE_METHOD, preset, light, seed, rot, distance=distance, packing_seed=packing)
            for seed, rot, packing in parts]
    name = f"{stem((scene, preset, light, distance))}_{which}"
    exr = os.path.join(a.out, "refs", name + ".exr")
    meta_path = os.path.join(a.out, "refs", name + ".json")
    key = {"scene_sha256": hashlib.sha256("".join(sha256(x) for x in xmls).encode()).hexdigest(),
           "spp": a.ref_spp, "rotations": k_count, "layouts": a.ref_layouts, "width": a.width, "height": a.height,
           # the renderer too: a rebuilt Cycles may sample the fibers differently (decisions D31)
           "cycles_sha256": cycles_sha256()}
    if os.path.isfile(exr) and os.path.isfile(meta_path):
        with open(meta_path) as f:
            meta = json.load(f)
        if all(meta.get(k) == v for k, v in key.items()):
            log(f"{what}: cached")
            return {**meta, "image": os.path.relpath(exr, a.out), "cached": True}
    total, seconds, peak = None, 0.0, 0.0
    for k, ((seed, rot, _), xml) in enumerate(zip(parts, xmls)):
        part = os.path.join(a.out, "refs", f"{name}_part.exr")
        cost = render(a, xml, spp, part, f"{what} [{k + 1}/{k_count}: {rot:g} deg, {spp} spp]")
        img = read_exr(part)
        total = img if total is None else total + img
        seconds += cost["seconds"]
        peak = max(peak, cost["peak_rss_mb"] or 0.0)
        os.remove(part)
    write_exr(exr, total / k_count)
    meta = {**key, "seeds": [s for s, _, _ in parts], "rotations_deg": [r for _, r, _ in parts],
            "packing_seeds": [p for _, _, p in parts], "seconds": seconds,
            "peak_rss_mb": peak or None}
    with open(meta_path, "w") as f:
        json.dump(meta, f, indent=1)
    return {**meta, "image": os.path.relpath(exr, a.out), "cached": False}


def fit_baseline(a, scene: str, preset: str, method: str, env_ref: dict, what: str) -> dict:
    """The colour of a baseline for a preset: the one whose mean colour over the central region under the uniform
    environment matches reference A's there — what an artist matching the yarn's colour under even light would
    pick (the neural model is calibrated to the same thing, D23). Per channel, colour -> mean is monotonic: a
    multiplicative step, then secant steps in log-log, clamped to [1e-4, 1]: where a stock closure's own white
    specular outshines the target (fleece's dark red), the channel ends at the bound, its error recorded. Reused from DIR/baselines.json when
    the reference, the image size and the fit settings are the same. Returns {"colour", "error" (relative, per
    channel, of the last render), "renders", "converged", "cached"}."""
    path = os.path.join(a.out, "baselines.json")
    table = {}
    if os.path.isfile(path):
        with open(path) as f:
            table = json.load(f)
    key = {"reference": env_ref["scene_sha256"], "ref_spp": env_ref["spp"], "width": a.width, "height": a.height,
           "cycles_sha256": env_ref["cycles_sha256"], **BASELINE_FIT}
    name = f"{scene}_{preset}_{method}"
    if name in table and table[name]["key"] == key:
        log(f"{what}: cached")
        return {**table[name]["fit"], "cached": True}
    ref = read_exr(os.path.join(a.out, env_ref["image"]))
    # The camera of the reference's own scene (reference() wrote it).
    xml = reference_scene(a, scene, preset, "environment")
    region = central_region(*camera(xml), a.width, a.height)
    target = ref[region].mean(axis=(0, 1))
    colour = np.clip(target, 1e-3, 1.0)  # the environment is white: the mean is an albedo
    history: list[tuple[np.ndarray, np.ndarray]] = []
    for k in range(BASELINE_FIT["renders"]):
        xml = write_scene(a, scene, method, preset, "environment", 1, colour=list(colour))
        exr = os.path.join(a.out, "renders", f"{name}_fit.exr")
        render(a, xml, BASELINE_FIT["spp"], exr, f"{what} [{k + 1}: {' '.join(f'{c:.4f}' for c in colour)}]")
        mean = read_exr(exr)[region].mean(axis=(0, 1))
        history.append((colour.copy(), mean))
        error = mean / target - 1.0
        stuck = ((colour <= 1e-4) & (error > 0)) | ((colour >= 1.0) & (error < 0))
        if np.all((np.abs(error) <= BASELINE_FIT["tolerance"]) | stuck):
            break
        slope = np.ones(3)
        if len(history) > 1:
            (c0, m0), (c1, m1) = history[-2], history[-1]
            with np.errstate(divide="ignore", invalid="ignore"):
                slope = np.log(m1 / m0) / np.log(c1 / c0)
            slope = np.where(np.isfinite(slope), np.clip(slope, 0.2, 5.0), 1.0)
        colour = np.clip(colour * (target / np.maximum(mean, 1e-12)) ** (1.0 / slope), 1e-4, 1.0)
    fit = {"colour": [float(c) for c in history[-1][0]], "error": [float(e) for e in error],
           "renders": len(history), "converged": bool(np.all(np.abs(error) <= BASELINE_FIT["tolerance"]))}
    table[name] = {"key": key, "fit": fit}
    with open(path, "w") as f:
        json.dump(table, f, indent=1)
    return {**fit, "cached": False}


def load_seconds(a, xml: str, exr: str, what: str, fallback) -> dict:
    """The load cost: the median wall time of a.load_renders 1-sample renders (three but in the quick run: one is
    as noisy as the renders of a few samples it is subtracted from); peak memory of the first."""
    n = a.load_renders
    costs = [render(a, xml, 1, exr, f"{what} {k + 1}/{n}", fallback) for k in range(n)]
    return {"seconds": float(np.median([c["seconds"] for c in costs])), "peak_rss_mb": costs[0]["peak_rss_mb"]}


def evaluate(a, rigs: dict[str, str]) -> tuple[dict, int]:
    for sub in ("scenes", "refs", "renders", "strips"):
        os.makedirs(os.path.join(a.out, sub), exist_ok=True)
    groups = [(s, p, l, d) for s in a.scenes for p in a.presets for l in a.lights
              for d in (a.distances if s in DISTANCE_SCENES else [None])]
    n_runs = len(a.methods) * len(a.spp) * a.seeds
    # The baselines' colours are fitted on the close-up (one ply under even light) for every scene.
    fits = [("closeup", p) for p in a.presets] if a.baselines else []
    # The renderers' own memory: the standalone Cycles', and Blender's for the methods it renders.
    renderers = ["cycles"] + (["blender"] if any(m in FALLBACKS for m in a.methods) else [])
    progress = Progress(len(renderers) + len(fits) * (1 + len(a.baselines)) +
                        len(groups) * (2 + len(a.methods) + n_runs))
    failures = 0

    empty_rss = {}
    for renderer in renderers:
        try:
            blender = renderer == "blender"
            empty_rss[renderer] = render(a, empty_scene(a, "json" if blender else "xml"), 1,
                                         os.path.join(a.out, "renders", f"empty_{renderer}.exr"),
                                         progress(f"empty scene in {renderer} (baseline memory) 1 spp"),
                                         "nodes" if blender else None)["peak_rss_mb"]
        except RenderFailed as e:
            empty_rss[renderer], failures = None, failures + 1
            log(f"the empty scene in {renderer}: FAILED, {e}")

    # The baselines' colours (preset, method) -> RGB, from the close-up's reference A under the environment.
    colours, baseline_fits = {}, []
    for scene, preset in fits:
        what = progress(f"reference A {scene} {preset} environment {a.ref_spp} spp (for the baselines' colours)")
        try:
            env_ref = reference(a, scene, preset, "environment", "A", what)
        except RenderFailed as e:
            failures += 1
            log(f"{what}: FAILED, {e}")
            env_ref = None
        for method in a.baselines:
            what = progress(f"{method} {scene} {preset} colour fit")
            rec = {"scene": scene, "preset": preset, "method": method, "failed": False}
            try:
                if env_ref is None:
                    raise RenderFailed("the environment's reference failed")
                fit = fit_baseline(a, scene, preset, method, env_ref, what)
                colours[(preset, method)] = fit["colour"]
                rec.update(fit)
            except RenderFailed as e:
                failures += 1
                rec["failed"] = f"colour fit failed: {e}"
                log(f"{what}: FAILED, {e}")
            baseline_fits.append(rec)

    references, noise_floor, runs, cameras = [], [], [], {}
    settings = a
    for scene, preset, light, distance in groups:
        a = for_scene(settings, scene)
        group = {"scene": scene, "preset": preset, "light": light, "distance": distance}
        name = stem((scene, preset, light, distance))
        at = f"{scene} {preset} {light}" + (f" distance {distance:g}" if distance not in (None, CLOSEUP_DISTANCE) else "")
        refs, failed = {}, {}
        for which in ("A", "B"):
            what = progress(f"reference {which} {at} {a.ref_spp} spp")
            try:
                refs[which] = reference(a, scene, preset, light, which, what, distance)
            except RenderFailed as e:
                failed[which] = f"reference {which} failed: {e}"
                failures += 1
                log(f"{what}: FAILED, {e}")
        references.append({**group, "spp": a.ref_spp, "rotations": a.ref_rotations, "layouts": a.ref_layouts,
                           "seeds": REFERENCE_SEEDS,
                           "failed": "; ".join(failed.values()) or False,
                           **{f"image_{w}": r["image"] for w, r in refs.items()},
                           **{f"seconds_{w}": r["seconds"] for w, r in refs.items()}})
        ref_failed = failed.get("A")  # the runs need reference A only, the noise floor both
        ref_img, region, region_name = None, None, None
        ref_scene = reference_scene(a, scene, preset, light, distance)
        if os.path.isfile(ref_scene):  # (reference() writes it even when it cannot render)
            cam_distance, fov = camera(ref_scene)
            if distance is None:  # the garment's or a patch's own camera
                group["distance"] = distance = cam_distance
            cameras.setdefault(scene, {"distance": CLOSEUP_DISTANCE, "fov": fov, "ply_length": CLOSEUP_PLY_LENGTH,
                                       "distances": {}} if scene in DISTANCE_SCENES else
                               {"distance": cam_distance, "fov": fov,
                                **({"stitches": a.garment_stitches} if scene == "garment" else {}),
                                "width": a.width, "height": a.height, "distances": {}})
            cameras[scene]["distances"][f"{distance:g}"] = {
                "ply_length": ply_length(distance, a) if scene in DISTANCE_SCENES else None,
                "ply_pixels": 2.0 * min(a.width, a.height) / (2.0 * cam_distance * math.tan(0.5 * fov))}
        if not ref_failed:
            ref_img = read_exr(os.path.join(a.out, refs["A"]["image"]))
            try:
                if scene in FRAMED_SCENES:
                    region, region_name = framed_region(a.width, a.height), "central"
                else:  # the ply's, or the yarn's bounding cylinder
                    radius = yarn_radius() if scene == "yarn" else PLY_RADIUS
                    region, region_name = central_region(cam_distance, fov, a.width, a.height, radius), "central"
            except RenderFailed:  # the ply is too thin for a central region: the whole frame
                region, region_name = (slice(None), slice(None)), "frame"
        floor = {**group, "region": region_name, "failed": "; ".join(failed.values()) or False,
                 "region_share": None if ref_failed else region_share(
                     ref_img, region, ply_band(region) if scene in DISTANCE_SCENES and region_name == "central" else None)}
        if not failed:
            floor.update(metrics(read_exr(os.path.join(a.out, refs["B"]["image"])), ref_img, region))
        else:
            floor.update({k: None for k in METRIC_KEYS})
        noise_floor.append(floor)

        strip = {"reference": ref_img}
        for method in a.methods:
            # Load cost: a 1-sample render of the same scene (seed 1), once per method.
            xml, load, load_failed = None, None, None
            what = progress(f"{method} {at} 1 spp (load)")
            colour = colours.get((preset, method))
            try:
                if method in a.baselines and colour is None:
                    raise RenderFailed("no colour (its fit failed)")
                xml = write_scene(a, scene, method, preset, light, 1, colour=colour, distance=distance)
                load = load_seconds(a, xml, os.path.join(a.out, "renders", f"{name}_{method}_1spp.exr"),
                                    what, fallback_of(method))
            except RenderFailed as e:
                load_failed = f"load render failed: {e}"
                failures += 1
                log(f"{what}: FAILED, {e}")
            keys = curve_keys(xml) if xml else None
            for spp in a.spp:
                for seed in range(1, a.seeds + 1):
                    rec = {**group, "method": method, "spp": spp, "region": region_name,
                           "seed": seed, "seconds_load": None, "seconds_render": None, "peak_rss_mb": None,
                           "baseline_rss_mb": empty_rss["blender" if fallback_of(method) else "cycles"],
                           "curve_keys": keys, **{k: None for k in METRIC_KEYS},
                           "image": None, "failed": False}
                    what = progress(f"{method} {at} {spp} spp seed {seed}")
                    if load_failed:
                        rec["failed"] = load_failed
                        log(f"{what}: skipped ({rec['failed']})")
                        runs.append(rec)
                        continue
                    exr = os.path.join(a.out, "renders", f"{name}_{method}_{spp}spp_seed{seed}.exr")
                    try:
                        xml_s = xml if seed == 1 else write_scene(a, scene, method, preset, light, seed, colour=colour,
                                                                  distance=distance)
                        cost = render(a, xml_s, spp, exr, what, fallback_of(method))
                    except RenderFailed as e:
                        rec["failed"] = str(e)
                        failures += 1
                        log(f"{what}: FAILED, {e}")
                        runs.append(rec)
                        continue
                    img = read_exr(exr)
                    # (A few-sample render can finish faster than the 1-sample one: timing noise, not a cost.)
                    rec.update({"seconds_load": load["seconds"],
                                "seconds_render": max(0.0, cost["seconds"] - load["seconds"]),
                                "peak_rss_mb": cost["peak_rss_mb"], "image": os.path.relpath(exr, a.out)})
                    if ref_img is not None:
                        rec.update(metrics(img, ref_img, region))
                    else:  # the cost is measured; the error needs the reference
                        rec["no_reference"] = ref_failed
                    runs.append(rec)
                    if spp == a.spp[0] and seed == 1:
                        strip[method] = img
        if ref_img is not None:
            write_strip(a, name, strip)
    a = settings

    results = {
        "format": "neuralyarn-evaluate 1",
        "command": ["scripts/evaluate.sh", *sys.argv[1:]],
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "git": git_revision(),
        "machine": {"cpu": cpu_model(), "cores": os.cpu_count(), "system": platform.platform()},
        "settings": {"width": a.width, "height": a.height, "ref_spp": a.ref_spp, "distances": a.distances,
                     "ref_rotations": a.ref_rotations, "ref_layouts": a.ref_layouts, "spp": a.spp, "seeds": a.seeds,
                     "threads": a.threads, "timeout_s": a.timeout, "reference_method": REFERENCE_METHOD,
                     "reference_seeds": REFERENCE_SEEDS, "flip_ppd": FLIP_PPD, "relmse_eps": RELMSE_EPS,
                     "relmse_discard": RELMSE_DISCARD, "quick": a.quick},
        "scenes": cameras,
        "lights": {l: rigs[l] for l in a.lights},
        "methods": a.methods,
        "baselines": baseline_fits,
        "presets": a.presets,
        "yarns": a.yarns,
        "references": references,
        "noise_floor": noise_floor,
        "baseline_rss_mb": empty_rss,
        "runs": runs,
    }
    results["summary"] = speed_summary(results)
    results["summary_over_plies"] = level_summary(results)
    results["auto"] = auto_summary(results)
    return results, failures


def write_strip(a, name: str, images: dict) -> None:
    """reference | native | explicit (| yarns | surface, when rendered), side by side on one exposure (the
    reference's); a missing or failed method is a grey panel. Small images are enlarged (whole pixels) to at least
    320 pixels a panel."""
    import matplotlib.image
    ref = images["reference"]
    x = exposure_of(ref)
    gap = np.ones((ref.shape[0], 1, 3))
    panels = []
    for k in ("reference", "native", "explicit") + tuple(m for m in ("yarns", "surface") if m in images):
        panels += [display(images[k], x) if k in images else np.full_like(ref, 0.5), gap]
    strip = np.clip(np.concatenate(panels[:-1], axis=1), 0.0, 1.0)
    k = max(1, math.ceil(320 / ref.shape[1]))
    matplotlib.image.imsave(os.path.join(a.out, "strips", f"{name}.png"),
                            np.repeat(np.repeat(strip, k, axis=0), k, axis=1))


def contact_sheet(out: str, results: dict) -> str:
    """DIR/strips.png: every (scene, preset, light, distance) strip in one picture, a row per preset (and
    distance) and a column per light, each titled. Returns its path."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image
    import matplotlib.pyplot as plt
    presets, lights = results["presets"], list(results["lights"])
    scenes = sorted({r["scene"] for r in results["references"]})
    distances = results["settings"].get("distances", [CLOSEUP_DISTANCE])
    rows = [(sc, p, d) for sc in scenes for p in presets for d in (distances if sc == "closeup" else [None])]
    fig, axes = plt.subplots(len(rows), len(lights), squeeze=False,
                             figsize=(3.2 * len(lights), 0.9 * len(rows) + 0.4))
    for i, (sc, p, d) in enumerate(rows):
        for j, l in enumerate(lights):
            ax = axes[i][j]
            path = os.path.join(out, "strips", f"{stem((sc, p, l, d))}.png")
            if os.path.isfile(path):
                ax.imshow(matplotlib.image.imread(path))
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{sc}, {p}, {l}" if d is None else f"{p}, {l}" + (f", distance {d:g}" if len(distances) > 1 else ""),
                         fontsize=8)
    fig.suptitle("reference | native | explicit (one exposure per strip: the reference's)", fontsize=9)
    fig.tight_layout()
    path = os.path.join(out, "strips.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def summary(results: dict) -> str:
    s = results["settings"]
    lines = [f"# Evaluation: {s['width']}x{s['height']}, reference explicit fibers at {s['ref_spp']} spp "
             f"over {s.get('ref_rotations', 1)} orientations"
             f"{', each its own fiber cross-section' if s.get('ref_layouts') == 'each' else ''}",
             "",
             f"`{' '.join(results['command'])}`; {results['date']}; git {results['git']['revision']}"
             f"{' (dirty)' if results['git']['dirty'] else ''}; {results['machine']['cpu']}, "
             f"{results['machine']['cores']} cores, {s['threads']} threads.",
             "",
             "Errors over the central region of the ply (the whole frame where the ply is under 3 rows), against "
             "reference A; noise floor: reference B against A. Mean over seeds. `closeup d48`: the close-up's camera "
             "at 48 ply radii. frame lum %: the luminance error of the whole frame, and its floor (reference B "
             "against A over the whole frame: under back light the silhouette's few pixels make it the larger one); "
             "region light %: the share of "
             "reference A's light on the ply's rows (over the region's columns) that is in the region (where it is "
             "small, the light is at the ply's silhouettes, outside the region: read the frame's error). FLIP mc: FLIP "
             "with the image's mean colour matched to the reference's (its structure's error alone).",
             "",
             "| scene | preset | light | method | spp | R % | G % | B % | lum % | lum floor % | frame lum % "
             "| frame floor % | region light % | FLIP | FLIP mc | FLIP floor | render s | load s | peak MB | failed |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    floors = {(label(group_of(f)), f["preset"], f["light"]): f for f in results["noise_floor"]}
    groups: dict = {}
    for r in results["runs"]:
        groups.setdefault((label(group_of(r)), r["preset"], r["light"], r["method"], r["spp"]), []).append(r)

    def mean(vals):
        vals = [v for v in vals if v is not None]
        return sum(vals) / len(vals) if vals else None

    def fmt(v, spec):
        return format(v, spec) if v is not None else "-"

    def percent(v):  # None where nothing was measured (runs without a reference, files older than a field)
        return 100 * v if v is not None else None

    for (scene, preset, light, method, spp), rs in groups.items():
        cost = [r for r in rs if not r["failed"]]
        ok = [r for r in cost if r["flip"] is not None]  # measured against a reference
        fl = floors[(scene, preset, light)]
        rgb = [mean([r["mean_colour_error"][c] for r in ok]) for c in range(3)]
        pct = [fmt(100 * v if v is not None else None, "+.1f") for v in rgb]
        failed = "; ".join(sorted({str(r["failed"]) for r in rs if r["failed"]} |
                                  {"no reference" for r in cost if r.get("no_reference")})) or ""
        lines.append(
            f"| {scene} | {preset} | {light} | {method} | {spp} | {' | '.join(pct)} | "
            f"{fmt(percent(mean([r['mean_luminance_error'] for r in ok])), '+.1f')} | "
            f"{fmt(percent(fl['mean_luminance_error']), '+.1f')} | "
            f"{fmt(percent(mean([r.get('mean_luminance_error_frame') for r in ok])), '+.1f')} | "
            f"{fmt(percent(fl.get('mean_luminance_error_frame')), '+.1f')} | "
            f"{fmt(percent(fl.get('region_share')), '.0f')} | "
            f"{fmt(mean([r['flip'] for r in ok]), '.3f')} | "
            f"{fmt(mean([r.get('flip_colour_matched') for r in ok]) if ok else None, '.3f')} | {fmt(fl['flip'], '.3f')} | "
            f"{fmt(mean([r['seconds_render'] for r in cost]), '.2f')} | {fmt(mean([r['seconds_load'] for r in cost]), '.2f')} | "
            f"{fmt(mean([r['peak_rss_mb'] for r in cost]), '.0f')} | {failed.replace('|', '/')[:80]} |")
    if results.get("baselines"):
        lines += ["", "Baselines' colours (fitted to reference A's central-region mean under the environment):", "",
                  "| scene | preset | method | colour | error R / G / B % | renders | failed |", "|---|---|---|---|---|---|---|"]
        for b in results["baselines"]:
            lines.append(f"| {b['scene']} | {b['preset']} | {b['method']} | "
                         f"{' '.join(f'{c:.4f}' for c in b.get('colour', []))} | "
                         f"{' / '.join(f'{100 * e:+.1f}' for e in b.get('error', []))} | {b.get('renders', '-')} | "
                         f"{b['failed'] or ''} |")
    if results.get("summary"):
        lines += ["", "Speed against explicit fibers (scripts/evaluate_charts.py):", "", summary_table(results).rstrip()]
    if results.get("summary_over_plies"):
        lines += ["", "Speed of the levels of detail against the ply level (native):", "",
                  summary_table(results, "summary_over_plies", "native").rstrip()]
    if results.get("auto"):
        lines += ["", "The add-on's Auto level (addon/geometry/lod.py) against the levels rendered, at the most samples "
                  "(issue 18's goal: FLIP and time each within 10 %; ✗ where not):", "", auto_table(results["auto"]).rstrip()]
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    try:
        for tool in (CLI, CYCLES):
            if not os.access(tool, os.X_OK):
                raise Usage(f"{tool} is not built (scripts/setup.sh builds it)")
        rigs = light_rigs()
        a = parse_args(argv, rigs, list(cli_table("--list-baselines")))
        a.out = os.path.abspath(a.out)
        os.makedirs(a.out, exist_ok=True)
    except Usage as e:
        print(f"evaluate: error: {e}", file=sys.stderr)
        return 1
    t0 = time.monotonic()
    results, failures = evaluate(a, rigs)
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    table = summary(results)
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write(table)
    contact_sheet(a.out, results)
    if len(a.spp) > 1:
        error_time_charts(a.out, results)
    error_distance_charts(a.out, results)
    print(table, end="")
    log(f"wrote {os.path.join(a.out, 'results.json')}, summary.md, strips/, strips.png in {time.monotonic() - t0:.0f} s"
        + (f"; {failures} render(s) FAILED" if failures else ""))
    return 2 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
