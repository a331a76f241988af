# SPDX-License-Identifier: GPL-3.0-or-later
"""The built-in lobes that the fallback tables weight (model/fallback.h, version 2): GGX reflections about
the surface fibers' tangent, diffuse and translucent. What the OSL shader and the stock-node body build from
a lobe that schema.parse_lobes has validated: its OSL closure and its inputs in Blender's Glossy/Anisotropic
BSDF node."""

from __future__ import annotations

import math


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

