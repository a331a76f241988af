# SPDX-License-Identifier: GPL-3.0-or-later
"""The "fallback" object of a model file (docs/file_formats.md; model/fallback.h, version 2), validated
once for the add-on and the OSL generator, as strictly as the C++ loader (cpp_core/src/model/fallback.cpp):
a bad table is a ValueError that names its key, never a shader built from garbage."""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

VERSION = 2
MAX_BINS = 1024
MAX_ENERGY = 1.5
MAX_WEIGHT = 100.0

CLOSURES = ("ggx", "diffuse", "translucent")
MAX_LOBES = 8
# Cycles clamps GGX roughness to [0, 1]. The core writes alpha in [0.1, 1] since D60; files written before it
# (down to 0.001) still read: their tables were fitted to their own lobes.
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


@dataclass
class FallbackTables:
    """View-dependent lobe energies and weights over the front-facing directions of a thick curve.

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
    twist_tilt_rad: float  # the surface fibers' tilt against the yarn tangent (the GGX lobes' t_f)
    kernel_flat_fnv1a64: str  # the kernel array the tables were computed for
    scalars: dict  # every number of the object: beta_R_rad, beta_M_rad, gamma_M_rad, kappa_M, ...

    @property
    def cells(self) -> int:
        return self.theta_bins * self.phi_bins


def parse(model: dict) -> FallbackTables:
    """The model's fallback tables, checked: present, of this version, of consistent sizes, within their
    ranges, and computed for the model's current kernel array. ValueError otherwise."""
    fb = model.get("fallback")
    if fb is None:
        raise ValueError("has no \"fallback\" tables; re-run `neuralyarn fallback MODEL` "
                         "(models baked before the fallback existed lack them)")
    if not isinstance(fb, dict):
        raise ValueError("fallback: must be an object")
    if fb.get("version") != VERSION or isinstance(fb.get("version"), bool):
        raise ValueError(f"fallback: version {fb.get('version')!r} is not supported (this add-on reads "
                         f"version {VERSION}); re-run `neuralyarn fallback MODEL`")
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
    lobes = parse_lobes(fb)
    tables = FallbackTables(
        theta_bins=nt,
        phi_bins=np_,
        P_T=_table(fb, "P_T", n, 0.0, 1.0),
        E_R=_table(fb, "E_R", 3 * n, 0.0, MAX_ENERGY),
        E_M_up=_table(fb, "E_M_up", 3 * n, 0.0, MAX_ENERGY),
        E_M_down=_table(fb, "E_M_down", 3 * n, 0.0, MAX_ENERGY),
        lobes=lobes,
        W=_table(fb, "W", 3 * len(lobes) * n, 0.0, MAX_WEIGHT),
        twist_tilt_rad=_scalar(fb, "twist_tilt_rad", -0.5 * math.pi, 0.5 * math.pi),
        kernel_flat_fnv1a64=check_kernel_flat_digest(model),
        scalars={k: v for k, v in fb.items() if _is_number(v)},
    )
    for k, v in tables.scalars.items():
        if not math.isfinite(v):
            raise ValueError(f"fallback: '{k}' is not finite")
    return tables


def check_kernel_flat_digest(model: dict) -> str:
    """The tables' kernel_flat_fnv1a64, after checking that it is the model's kernel array's: tables left
    stale by a later change of the model are refused (the C++ loader refuses them too). ValueError."""
    fb = model.get("fallback") if isinstance(model.get("fallback"), dict) else {}
    digest = fb.get("kernel_flat_fnv1a64")
    if not isinstance(digest, str):
        raise ValueError("fallback: missing string 'kernel_flat_fnv1a64'")
    flat = model.get("kernel_flat")
    if isinstance(flat, list):
        if not all(_is_number(x) and math.isfinite(x) for x in flat):
            raise ValueError("'kernel_flat' holds a non-finite number or a non-number")
        try:
            actual = fnv1a64_hex(flat)
        except (struct.error, OverflowError) as e:
            raise ValueError(f"'kernel_flat' holds a value that is not a float ({e})") from None
        if actual != digest:
            raise ValueError(f"fallback: the tables were computed for another model (kernel_flat_fnv1a64 "
                             f"{digest}, the model's is {actual}); re-run `neuralyarn fallback MODEL`")
    return digest


def fnv1a64_hex(values) -> str:
    """FNV-1a 64 of the values as little-endian float32 bytes (model/fallback.h fnv1a64_hex)."""
    h = 0xCBF29CE484222325
    for b in struct.pack("<%df" % len(values), *values):
        h ^= b
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return "%016x" % h


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
