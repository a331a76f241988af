# SPDX-License-Identifier: GPL-3.0-or-later
"""Neural yarn model files (docs/file_formats.md, "Model file") as the add-on sees them.

No bpy here: this module parses and validates a model's JSON and hands out what the fallbacks need
(the view-dependent energy tables of the "fallback" object and a few scalars). The C++ core
(`neuralyarn bake/fit/fallback`) writes these files; the native closure of a patched Cycles reads the same
file. Every problem is a ModelFileError whose message names the file and the key, so an operator can
report it to the user instead of rendering garbage.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass

from . import resources

FORMAT = "neuralyarn-model"
SUPPORTED_VERSIONS = (2, 3)
FALLBACK_VERSION = 2
FALLBACK_MAX_WEIGHT = 100.0
PRESETS = ("fleece", "silk", "polyester", "cotton", "gabardine")
#: Model files are a few hundred KB; anything beyond this is not a model and is refused before parsing.
MAX_MODEL_BYTES = 64 * 1024 * 1024


class ModelFileError(ValueError):
    """A model file is missing, unreadable, of another format or version, or inconsistent."""


@dataclass
class FallbackTables:
    """View-dependent lobe energies over the front-facing directions of a thick curve.

    Cell centres: theta = -90 + (i + 1/2) 180 / theta_bins degrees (longitudinal angle, positive toward the
    yarn tangent), phi = -90 + (j + 1/2) 180 / phi_bins degrees (azimuth, 0 along the surface normal).
    Row-major [theta][phi]; colour tables have 3 floats per cell.
    """

    theta_bins: int
    phi_bins: int
    P_T: list  # theta_bins * phi_bins
    E_R: list  # theta_bins * phi_bins * 3
    E_M_up: list
    E_M_down: list
    lobes: list  # [{"closure": "ggx", "alpha_x", "alpha_y"} | {"closure": "diffuse" | "translucent"}]
    W: list  # theta_bins * phi_bins * len(lobes) * 3: the lobes' fitted RGB weights
    scalars: dict  # beta_R_rad, twist_tilt_rad, beta_M_rad, gamma_M_rad, kappa_M, ...


@dataclass
class YarnModel:
    """A parsed model file: the raw JSON (kept verbatim for packing) and the parts the add-on uses."""

    source: str  # file path or Text datablock name, for messages
    text: str  # the JSON text exactly as read
    data: dict
    preset_name: str
    alpha: float

    @property
    def fallback(self) -> FallbackTables:
        return _fallback_tables(self.data, self.source)


def _fail(where: str, message: str) -> ModelFileError:
    return ModelFileError(f"{where}: {message}")


def _finite_list(values, n: int, key: str, where: str, lo=-math.inf, hi=math.inf) -> list:
    if not isinstance(values, list) or len(values) != n:
        got = len(values) if isinstance(values, list) else type(values).__name__
        raise _fail(where, f"fallback '{key}' must be a list of {n} numbers (got {got})")
    out = []
    for k, v in enumerate(values):
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise _fail(where, f"fallback '{key}'[{k}] is not a finite number ({v!r})")
        if not lo <= v <= hi:
            raise _fail(where, f"fallback '{key}'[{k}] = {v} is outside [{lo}, {hi}]")
        out.append(float(v))
    return out


def _fallback_tables(data: dict, where: str) -> FallbackTables:
    fb = data.get("fallback")
    if fb is None:
        raise _fail(where, "has no 'fallback' tables (made by an older neuralyarn); "
                           "run `neuralyarn fallback MODEL` to add them")
    if not isinstance(fb, dict):
        raise _fail(where, "'fallback' must be an object")
    if fb.get("version") != FALLBACK_VERSION:
        raise _fail(where, f"fallback version {fb.get('version')!r} is not supported (expected {FALLBACK_VERSION})")
    tb, pb = fb.get("theta_bins"), fb.get("phi_bins")
    if not (isinstance(tb, int) and isinstance(pb, int) and 2 <= tb <= 1024 and 2 <= pb <= 1024):
        raise _fail(where, f"fallback bins must be integers in [2, 1024] (got {tb!r} x {pb!r})")
    cells = tb * pb
    try:
        lobes = resources.osl_generator().parse_lobes(fb)  # one validation, shared with the OSL generator
    except ValueError as e:
        raise _fail(where, str(e)) from None
    scalars = {k: v for k, v in fb.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    for k, v in scalars.items():
        if not math.isfinite(v):
            raise _fail(where, f"fallback '{k}' is not finite")
    return FallbackTables(
        theta_bins=tb,
        phi_bins=pb,
        P_T=_finite_list(fb.get("P_T"), cells, "P_T", where, 0.0, 1.0),
        E_R=_finite_list(fb.get("E_R"), 3 * cells, "E_R", where, 0.0, 1.5),
        E_M_up=_finite_list(fb.get("E_M_up"), 3 * cells, "E_M_up", where, 0.0, 1.5),
        E_M_down=_finite_list(fb.get("E_M_down"), 3 * cells, "E_M_down", where, 0.0, 1.5),
        lobes=lobes,
        W=_finite_list(fb.get("W"), 3 * len(lobes) * cells, "W", where, 0.0, FALLBACK_MAX_WEIGHT),
        scalars=scalars,
    )


def parse_model(text: str, source: str) -> YarnModel:
    """Parses and checks a model's JSON text. `source` names it in error messages."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise _fail(source, f"not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise _fail(source, f"not a neural yarn model file (expected \"format\": \"{FORMAT}\")")
    version = data.get("version")
    if version not in SUPPORTED_VERSIONS:
        raise _fail(source, f"model format version {version!r} is not supported by this add-on "
                            f"(supported: {', '.join(map(str, SUPPORTED_VERSIONS))})")
    preset = data.get("preset")
    if not isinstance(preset, dict) or not isinstance(preset.get("name"), str):
        raise _fail(source, "missing 'preset' object with a 'name'")
    alpha = preset.get("alpha")
    if not isinstance(alpha, (int, float)) or not math.isfinite(alpha) or alpha < 0:
        raise _fail(source, f"preset 'alpha' must be a finite number >= 0 (got {alpha!r})")
    flat = data.get("kernel_flat")
    if not isinstance(flat, list) or len(flat) < 20:
        raise _fail(source, "missing 'kernel_flat' (the array the native closure uploads)")
    model = YarnModel(source=source, text=text, data=data, preset_name=preset["name"], alpha=float(alpha))
    model.fallback  # validates the tables now, so a bad file is reported when it is loaded, not at render time
    return model


def load_model_file(path: str) -> YarnModel:
    """Reads a model file from disk (see parse_model)."""
    if not path:
        raise ModelFileError("no model file given")
    if not os.path.isfile(path):
        raise ModelFileError(f"{path}: model file not found")
    size = os.path.getsize(path)
    if size > MAX_MODEL_BYTES:
        raise _fail(path, f"{size} bytes is far too large for a model file")
    try:
        with open(path, "r", encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise _fail(path, f"cannot be read ({e})") from None
    return parse_model(text, path)
