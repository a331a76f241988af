#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Bake a neural yarn model file into the OSL fallback shader for stock Cycles.

The model file must carry the view-dependent fallback tables (its "fallback" object, written by
`neuralyarn bake`, `fit` and `fallback`); the template neural_yarn_fallback.osl.in, next to this file,
receives them as constant arrays. Standard library only; importable (generate_osl) and runnable:

    python3 osl/generate_osl.py models/fleece.json -o fleece_fallback.osl

What the shader computes (P_T transparent() plus the fitted weights of built-in GGX, diffuse and
translucent lobes) is documented in osl/README.md and in the template's header.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import struct
import sys

TEMPLATE_NAME = "neural_yarn_fallback.osl.in"
FALLBACK_VERSION = 2
MAX_ENERGY = 1.5
MAX_WEIGHT = 100.0
MAX_BINS = 1024
MAX_LOBES = 8
# Cycles clamps GGX roughness to [0, 1]; the fit (model/fallback.h) keeps alpha in [0.001, 1].
ALPHA_MIN, ALPHA_MAX = 0.001, 1.0
CLOSURES = ("ggx", "diffuse", "translucent")


def _template_path() -> str:
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), TEMPLATE_NAME)


def parse_lobes(fb: dict) -> list[dict]:
    """The fallback's built-in lobes ("lobes": {"closure": "ggx", "alpha_x", "alpha_y"} | {"closure":
    "diffuse"} | {"closure": "translucent"}), validated."""
    lobes = fb.get("lobes")
    if not isinstance(lobes, list) or not 1 <= len(lobes) <= MAX_LOBES:
        raise ValueError(f"fallback: 'lobes' must be a list of 1 to {MAX_LOBES} lobes")
    out = []
    for i, lobe in enumerate(lobes):
        if not isinstance(lobe, dict) or lobe.get("closure") not in CLOSURES:
            raise ValueError(f"fallback: lobe {i} must be an object whose 'closure' is one of {', '.join(CLOSURES)}")
        item = {"closure": lobe["closure"]}
        if lobe["closure"] == "ggx":
            for key in ("alpha_x", "alpha_y"):
                x = lobe.get(key)
                if not _is_number(x) or not math.isfinite(x) or not ALPHA_MIN <= x <= ALPHA_MAX:
                    raise ValueError(f"fallback: lobe {i} '{key}' must be a number in [{ALPHA_MIN:g}, {ALPHA_MAX:g}], "
                                     f"got {x!r}")
                item[key] = float(x)
        out.append(item)
    return out


def glossy_node_inputs(alpha_x: float, alpha_y: float) -> tuple[float, float]:
    """(Roughness, Anisotropy) of Blender's Glossy/Anisotropic BSDF node (GGX, tangent linked) that gives
    Cycles' alpha_x along the tangent and alpha_y across, alpha_x <= alpha_y: Cycles squares the roughness
    (r = Roughness^2) and sets alpha_x = r (1 - a), alpha_y = r / (1 - a) for anisotropy a >= 0."""
    if alpha_x > alpha_y:
        raise ValueError("glossy_node_inputs: alpha_x must not exceed alpha_y")
    r = math.sqrt(alpha_x * alpha_y)
    return math.sqrt(r), 1.0 - math.sqrt(alpha_x / alpha_y)


def osl_closure(lobe: dict) -> str:
    """The OSL closure call of a lobe, in the shader's frame (n, t_f)."""
    if lobe["closure"] == "ggx":
        return f'microfacet("ggx", n, t_f, {_osl_float(lobe["alpha_x"])}, {_osl_float(lobe["alpha_y"])}, 1.0, 0)'
    return f'{lobe["closure"]}(n)'


def _fnv1a64_hex(values) -> str:
    """FNV-1a 64 of the values as little-endian float32 bytes (model/fallback.h fnv1a64_hex)."""
    h = 0xCBF29CE484222325
    for b in struct.pack("<%df" % len(values), *values):
        h ^= b
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return "%016x" % h


def _osl_float(x: float) -> str:
    s = "%.9g" % x
    if not any(ch in s for ch in ".en"):
        s += ".0"
    return s


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _table(fb: dict, key: str, size: int, lo: float, hi: float) -> list[float]:
    a = fb.get(key)
    if not isinstance(a, list):
        raise ValueError(f"fallback: missing array '{key}'")
    if len(a) != size:
        raise ValueError(f"fallback: '{key}' has {len(a)} values, expected {size} for its bins")
    for i, x in enumerate(a):
        if not _is_number(x):
            raise ValueError(f"fallback: '{key}' entry {i} is not a number (NaN is written as null)")
        if not math.isfinite(x) or not lo <= x <= hi:
            raise ValueError(f"fallback: '{key}' entry {i} = {x!r} is outside [{lo:g}, {hi:g}]")
    return [float(x) for x in a]


def _scalar(fb: dict, key: str, lo: float, hi: float) -> float:
    x = fb.get(key)
    if not _is_number(x) or not math.isfinite(x) or not lo <= x <= hi:
        raise ValueError(f"fallback: '{key}' must be a finite number in [{lo:g}, {hi:g}], got {x!r}")
    return float(x)


def _identifier(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_]", "_", text)
    if not s or s[0].isdigit():
        s = "_" + s
    return s


def _format_list(values: list[float], per_line: int) -> str:
    lines = []
    for i in range(0, len(values), per_line):
        lines.append(", ".join(_osl_float(v) for v in values[i:i + per_line]))
    return ",\n    ".join(lines)


def check_kernel_flat_digest(model: dict) -> None:
    """Raises ValueError when the fallback tables were computed for another kernel array than the model's
    (tables left stale by a later change of the model: the C++ loader refuses them too)."""
    fb = model.get("fallback") if isinstance(model.get("fallback"), dict) else {}
    digest = fb.get("kernel_flat_fnv1a64")
    if not isinstance(digest, str):
        raise ValueError("fallback: missing string 'kernel_flat_fnv1a64'")
    flat = model.get("kernel_flat")
    if isinstance(flat, list):
        if not all(_is_number(x) and math.isfinite(x) for x in flat):
            raise ValueError("'kernel_flat' holds a non-finite number or a non-number")
        try:
            actual = _fnv1a64_hex(flat)
        except (struct.error, OverflowError) as e:
            raise ValueError(f"'kernel_flat' holds a value that is not a float ({e})") from None
        if actual != digest:
            raise ValueError(f"fallback: the tables were computed for another model (kernel_flat_fnv1a64 "
                             f"{digest}, the model's is {actual}); re-run `neuralyarn fallback MODEL`")


def generate_osl(model: dict, *, shader_name: str | None = None) -> str:
    """The OSL source of the fallback shader for `model` (a parsed model file). Raises ValueError if the
    model has no valid, current "fallback" object."""
    if not isinstance(model, dict) or model.get("format") != "neuralyarn-model":
        raise ValueError('not a neuralyarn model (the key "format" must be "neuralyarn-model")')
    fb = model.get("fallback")
    if fb is None:
        raise ValueError("the model has no \"fallback\" tables; re-run `neuralyarn fallback MODEL` "
                         "(models baked before the fallback existed lack them)")
    if not isinstance(fb, dict):
        raise ValueError("fallback: must be an object")
    if fb.get("version") != FALLBACK_VERSION or isinstance(fb.get("version"), bool):
        raise ValueError(f"fallback: version {fb.get('version')!r} is not supported (this generator reads "
                         f"version {FALLBACK_VERSION}); re-run `neuralyarn fallback MODEL`")
    bins = []
    for key in ("theta_bins", "phi_bins"):
        v = fb.get(key)
        if not isinstance(v, int) or isinstance(v, bool) or not 1 <= v <= MAX_BINS:
            raise ValueError(f"fallback: '{key}' must be an integer in [1, {MAX_BINS}], got {v!r}")
        bins.append(v)
    for key in ("theta_range_deg", "phi_range_deg"):
        if key in fb and fb[key] != [-90, 90]:
            raise ValueError(f"fallback: '{key}' must be [-90, 90], got {fb[key]!r}")
    nt, np_ = bins
    n = nt * np_
    p_t = _table(fb, "P_T", n, 0.0, 1.0)
    for key in ("E_R", "E_M_up", "E_M_down"):  # the energies: checked, used by the tests and the docs
        _table(fb, key, 3 * n, 0.0, MAX_ENERGY)
    lobes = parse_lobes(fb)
    w = _table(fb, "W", 3 * len(lobes) * n, 0.0, MAX_WEIGHT)
    tilt = _scalar(fb, "twist_tilt_rad", -0.5 * math.pi, 0.5 * math.pi)

    check_kernel_flat_digest(model)
    digest = fb["kernel_flat_fnv1a64"]

    preset = model.get("preset") if isinstance(model.get("preset"), dict) else {}
    preset_name = str(preset.get("name", "model"))
    name = _identifier(shader_name if shader_name is not None else "neural_yarn_fallback_" + preset_name)
    lobe_sum = "\n                                       + ".join(
        f"ny_weight(W, {k}, k00, k01, k10, k11, w00, w01, w10, w11) * {osl_closure(lobe)}"
        for k, lobe in enumerate(lobes))

    with open(_template_path(), encoding="utf-8") as f:
        text = f.read()
    source = re.sub(r"[^A-Za-z0-9_.,:+ -]", "_", f"model '{preset_name}' ({model.get('code_version', '?')})")
    values = {
        "SOURCE": source,
        "HASH": digest if re.fullmatch(r"[0-9a-f]{16}", digest) else "?",
        "SHADER_NAME": name,
        "THETA_BINS": str(nt),
        "PHI_BINS": str(np_),
        "CELLS": str(n),
        "CELLS_RGB": str(3 * n),
        "P_T": _format_list(p_t, 6),
        "LOBES": str(len(lobes)),
        "CELLS_LOBES_RGB": str(len(w)),
        "W": _format_list(w, 6),
        "TWIST_TILT_RAD": _osl_float(tilt),
        "LOBE_SUM": lobe_sum,
    }

    def fill(m: re.Match) -> str:
        key = m.group(1)
        if key not in values:
            raise ValueError(f"template {TEMPLATE_NAME} has an unknown placeholder @{key}@")
        return values[key]

    out = re.sub(r"@([A-Z0-9_]+)@", fill, text)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Generate the OSL fallback shader of a neural yarn model file.")
    ap.add_argument("model", help="model file (.json) with fallback tables")
    ap.add_argument("-o", "--out", help="OSL file to write (default: standard output)")
    ap.add_argument("--name", help="shader name (default: neural_yarn_fallback_<preset>)")
    args = ap.parse_args(argv)
    try:
        with open(args.model, encoding="utf-8") as f:
            model = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        print(f"generate_osl: model file '{args.model}': {e}", file=sys.stderr)
        return 1
    try:
        src = generate_osl(model, shader_name=args.name)
    except ValueError as e:
        print(f"generate_osl: model file '{args.model}': {e}", file=sys.stderr)
        return 1
    if args.out:
        tmp = args.out + ".tmp"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(src)
        os.replace(tmp, args.out)
        print(f"wrote {args.out}")
    else:
        sys.stdout.write(src)
    return 0


if __name__ == "__main__":
    sys.exit(main())
