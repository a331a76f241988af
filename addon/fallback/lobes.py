# SPDX-License-Identifier: GPL-3.0-or-later
"""The built-in lobes that the fallback tables weight (model/fallback.h, version 2): GGX reflections about
the surface fibers' tangent, diffuse and translucent. Their schema, their OSL closure and their inputs in
Blender's Glossy/Anisotropic BSDF node: what the OSL shader and the stock-node body build from a lobe."""

from __future__ import annotations

import math

CLOSURES = ("ggx", "diffuse", "translucent")
MAX_LOBES = 8
# Cycles clamps GGX roughness to [0, 1]; the fit (model/fallback.h) keeps alpha in [0.001, 1].
ALPHA_MIN, ALPHA_MAX = 0.001, 1.0


def parse_lobes(fb: dict) -> list[dict]:
    """The fallback's lobes ("lobes": {"closure": "ggx", "alpha_x", "alpha_y"} | {"closure": "diffuse"} |
    {"closure": "translucent"}), validated; ValueError otherwise."""
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


def osl_float(x: float) -> str:
    """A float literal of OSL that reads back as the same float32."""
    s = "%.9g" % x
    if not any(ch in s for ch in ".en"):
        s += ".0"
    return s


def osl_closure(lobe: dict) -> str:
    """The OSL closure call of a lobe, in the shader's frame (n, t_f)."""
    if lobe["closure"] == "ggx":
        return f'microfacet("ggx", n, t_f, {osl_float(lobe["alpha_x"])}, {osl_float(lobe["alpha_y"])}, 1.0, 0)'
    return f'{lobe["closure"]}(n)'


def glossy_node_inputs(alpha_x: float, alpha_y: float) -> tuple[float, float]:
    """(Roughness, Anisotropy) of Blender's Glossy/Anisotropic BSDF node (GGX, tangent linked) that gives
    Cycles' alpha_x along the tangent and alpha_y across, alpha_x <= alpha_y: Cycles squares the roughness
    (r = Roughness^2) and sets alpha_x = r (1 - a), alpha_y = r / (1 - a) for anisotropy a >= 0."""
    if alpha_x > alpha_y:
        raise ValueError("glossy_node_inputs: alpha_x must not exceed alpha_y")
    r = math.sqrt(alpha_x * alpha_y)
    return math.sqrt(r), 1.0 - math.sqrt(alpha_x / alpha_y)


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)
