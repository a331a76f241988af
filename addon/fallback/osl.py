# SPDX-License-Identifier: GPL-3.0-or-later
"""The OSL fallback shader of a model: its validated tables (schema) filled into the template
neural_yarn_fallback.osl.in beside this file. What the shader computes (P_T transparent() plus the fitted
weights of built-in GGX, diffuse and translucent lobes) is in osl/README.md and the template's header."""

from __future__ import annotations

import functools
import os
import re

from . import schema
from .lobes import osl_closure, osl_float

TEMPLATE_NAME = "neural_yarn_fallback.osl.in"
FORMAT = "neuralyarn-model"


def template_path() -> str:
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), TEMPLATE_NAME)


@functools.lru_cache(maxsize=1)
def _template() -> str:
    """The template's text, read once (a material rebuilds its shader before every render)."""
    with open(template_path(), encoding="utf-8") as f:
        return f.read()


def generate_osl(model: dict, *, shader_name: str | None = None) -> str:
    """The OSL source of the fallback shader for `model` (a parsed model file). ValueError if the model has
    no valid, current "fallback" object."""
    if not isinstance(model, dict) or model.get("format") != FORMAT:
        raise ValueError(f'not a neuralyarn model (the key "format" must be "{FORMAT}")')
    preset = model.get("preset") if isinstance(model.get("preset"), dict) else {}
    return shader_source(schema.parse(model), str(preset.get("name", "model")), str(model.get("code_version", "?")),
                         shader_name=shader_name)


def shader_source(fb: schema.FallbackTables, preset_name: str, code_version: str, *,
                  shader_name: str | None = None) -> str:
    """The OSL source for tables that schema.parse has validated (the add-on's model keeps them)."""
    name = _identifier(shader_name if shader_name is not None else "neural_yarn_fallback_" + preset_name)
    lobe_sum = "\n                                       + ".join(
        f"ny_weight(W, {k}, k00, k01, k10, k11, w00, w01, w10, w11) * {osl_closure(lobe)}"
        for k, lobe in enumerate(fb.lobes))
    source = re.sub(r"[^A-Za-z0-9_.,:+ -]", "_", f"model '{preset_name}' ({code_version})")
    digest = fb.kernel_flat_fnv1a64
    values = {
        "SOURCE": source,
        "HASH": digest if re.fullmatch(r"[0-9a-f]{16}", digest) else "?",
        "SHADER_NAME": name,
        "THETA_BINS": str(fb.theta_bins),
        "PHI_BINS": str(fb.phi_bins),
        "CELLS": str(fb.cells),
        "CELLS_RGB": str(3 * fb.cells),
        "P_T": _format_list(fb.P_T, 6),
        "LOBES": str(len(fb.lobes)),
        "CELLS_LOBES_RGB": str(len(fb.W)),
        "W": _format_list(fb.W, 6),
        "TWIST_TILT_RAD": osl_float(fb.twist_tilt_rad),
        "LOBE_SUM": lobe_sum,
    }

    def fill(m: re.Match) -> str:
        key = m.group(1)
        if key not in values:
            raise ValueError(f"template {TEMPLATE_NAME} has an unknown placeholder @{key}@")
        return values[key]

    return re.sub(r"@([A-Z0-9_]+)@", fill, _template())


def _identifier(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_]", "_", text)
    if not s or s[0].isdigit():
        s = "_" + s
    return s


def _format_list(values: list[float], per_line: int) -> str:
    lines = []
    for i in range(0, len(values), per_line):
        lines.append(", ".join(osl_float(v) for v in values[i:i + per_line]))
    return ",\n    ".join(lines)
