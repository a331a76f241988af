# SPDX-License-Identifier: GPL-3.0-or-later
"""Neural yarn model files (docs/file_formats.md, "Model file") as the add-on sees them.

No bpy here: this module parses and validates a model's JSON and hands out what the fallbacks need
(the view-dependent energy tables of the "fallback" object and a few scalars). The C++ core
(`neuralyarn bake/fit/fallback`) writes these files; the native closure of a patched Cycles reads the same
file. Every problem is a ModelFileError whose message names the file and the key, so an operator can
report it to the user instead of rendering garbage.
"""

from __future__ import annotations

import functools
import json
import math
import os
from dataclasses import dataclass

from .fallback import schema

FORMAT = "neuralyarn-model"
SUPPORTED_VERSIONS = (2, 3, 4, 5)
#: Version 5: a yarn-level model (layout 4 plus the "structure" it was baked for, docs/decisions.md D27).
YARN_VERSION = 5
#: Model files are a few hundred KB; anything beyond this is not a model and is refused before parsing.
MAX_MODEL_BYTES = 64 * 1024 * 1024


class ModelFileError(ValueError):
    """A model file is missing, unreadable, of another format or version, or inconsistent."""


@dataclass
class YarnModel:
    """A parsed model file: the raw JSON (kept verbatim for packing) and the parts the add-on uses."""

    source: str  # file path or Text datablock name, for messages
    text: str  # the JSON text exactly as read
    data: dict
    preset_name: str
    alpha: float  # the R lobe's surface-fiber twist (the kernel array's): the preset's, or the yarn's surface twist
    level: str = "plies"  # "plies", or "yarns" for a yarn-level model
    plies: int = 1  # a yarn-level model's plies per yarn
    ply_twist: float = 0.0

    @functools.cached_property
    def fallback(self) -> schema.FallbackTables:
        """The fallback tables, validated once (parse_model asks for them first) and kept: the data is not
        changed after parsing."""
        try:
            return schema.parse(self.data)
        except ValueError as e:
            raise _fail(self.source, str(e)) from None


def _fail(where: str, message: str) -> ModelFileError:
    return ModelFileError(f"{where}: {message}")


# The kernel array's layout (cpp_core/include/neuralyarn/kernel/yarn_bsdf.h, YarnFlatField; mlp.h).
_FLAT_HEADERS = {3: 24, 4: 26, 5: 27, 6: 28}  # layout 3: no TT fields, azimuth rows without the TT share; 4: no
# free path; 5: no R node frames
_R_NODES, _R_FRAME_STRIDE = 4, 6  # kYarnRNodes, kYarnRFrameStride: a yarn's R nodes as its surface fibers (D51)
_MAX_FREE_PATH = 2.0  # kYarnMaxFreePath: the R lobe's mean free path, ply radii
_MLP_MAX_LAYERS, _MLP_MAX_WIDTH = 8, 64
_HEAD_SIGMOID, _HEAD_EXP = 1, 2
_CAL_STRIDE = 7


def _network_ok(f: list, offset: int, end: int, inputs: int, outputs: int, head: int, header: int) -> bool:
    """yarn_flat_network_ok: the header of one network at `offset` and its size within [offset, end)."""
    if offset < header or offset + 3 > end:
        return False
    L = f[offset]
    if not (1 <= L <= _MLP_MAX_LAYERS and L == int(L)) or offset + int(L) + 3 > end:
        return False
    L = int(L)
    widths = f[offset + 1: offset + L + 2]
    if not all(1 <= w <= _MLP_MAX_WIDTH and w == int(w) for w in widths):
        return False
    widths = [int(w) for w in widths]
    count = L + 3 + sum(widths[l + 1] * widths[l] + widths[l + 1] + (widths[l + 1] if l < L - 1 else 0)
                        for l in range(L))
    return widths[0] == inputs and widths[L] == outputs and f[offset + L + 2] == head and offset + count <= end


def _r_node_frames(f: list) -> list | None:
    """A layout 6 array's R node frames (right after its header), or None when its offset field says none."""
    if f[27] == 0.0:
        return None
    header = _FLAT_HEADERS[6]
    return f[header:header + _R_NODES * _R_FRAME_STRIDE]


def kernel_flat_problem(f: list, layout: int = 6) -> str | None:
    """What is wrong with a layout 6 kernel array (the native closure's input), or None: the same checks as
    the C++ loader's yarn_flat_check, so that the add-on packs no model the patched Cycles would refuse.
    Layouts 4 and 5 (no R free path, no R node frames: the C++ loader and the Cycles patch move them to layout
    6 with zeros there) and layout 3 (version 3 files, which it rebuilds with no TT share) get the checks they
    had."""
    n = len(f)
    header = _FLAT_HEADERS[layout]
    if n < header:
        return "shorter than the header"
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in f):
        return "holds a non-finite number or a non-number"
    if f[0] != float(layout):
        return "has another layout version than this add-on reads"
    if f[1] != n:
        return "its size field disagrees with its length"
    if not (0.0 <= f[7] <= 1.0 and 0.0 <= f[10] <= 1.0 and f[6] > 0.0 and f[8] > 0.0 and f[9] > 0.0 and
            (layout == 3 or (f[24] > 0.0 and f[25] > 0.0)) and
            (layout < 5 or 0.0 <= f[26] <= _MAX_FREE_PATH)):
        return "has sampling parameters out of range"
    frames = _r_node_frames(f) if layout >= 6 else None
    if frames is not None:
        size = _R_NODES * _R_FRAME_STRIDE
        if f[27] != header or f[26] != 0.0 or len(frames) < size or not f[14] >= header + size:
            return "has R node frames out of place"
        if any(abs(frames[i] ** 2 + frames[i + 1] ** 2 - 1.0) > 1e-4 for i in range(0, size, 2)):
            return "has an R node frame that is not a rotation"
        header += size
    oT, oR, oM, oC, oA = f[14], f[15], f[16], f[17], f[20]
    if not (0.0 <= oT <= oR <= oM <= oC <= oA <= n) or oA != int(oA):
        return "has network offsets out of order"
    if not _network_ok(f, int(oT), int(oR), 3, 1, _HEAD_SIGMOID, header):
        return "has a malformed T network (3 -> 1, sigmoid head)"
    if not (_network_ok(f, int(oR), int(oM), 3, 1, _HEAD_EXP, header) or
            _network_ok(f, int(oR), int(oM), 3, 3, _HEAD_EXP, header)):  # 3 -> 3: RGB (D65)
        return "has a malformed R network (3 -> 1 or 3 -> 3, exp head)"
    if not (_network_ok(f, int(oM), int(oC), 6, 3, _HEAD_EXP, header) or
            _network_ok(f, int(oM), int(oC), 6, 6, _HEAD_EXP, header)):  # 6 -> 6: two-sided (D45)
        return "has a malformed M network (6 -> 3 or 6 -> 6, exp head)"
    nt, np_ = f[18], f[19]
    if not (0 <= nt <= 4096 and 0 <= np_ <= 4096) or nt != int(nt) or np_ != int(np_) or \
            int(oC) + int(nt) * int(np_) * _CAL_STRIDE != int(oA):
        return "has a calibration table of the wrong size"
    at, ap, ab = f[21], f[22], f[23]
    no_table = at == 0 and ap == 0 and ab == 0
    if not no_table and (not (1 <= at <= 1024 and 1 <= ap <= 1024 and 2 <= ab <= 1024) or
                         at != int(at) or ap != int(ap) or ab != int(ab)):
        return "has an R azimuth table of the wrong shape"
    stride = int(ab) + (3 if layout >= 4 else 0)  # the densities, then (layout 4 on) the TT share r, g, b
    if int(oA) + (0 if no_table else int(at) * int(ap) * stride) != n:
        return "has an R azimuth table of the wrong size"
    if any(v < 0.0 for v in f[int(oA):]):
        return "has a negative R azimuth density"
    if any(v > 1.0 for i, v in enumerate(f[int(oA):]) if i % stride >= int(ab)):
        return "has an R TT share above 1"
    return None


def _refuse_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


#: A model's near field (decisions D68, D72): per band of |cos| between the light and the ply's axis, the signed
#: quantiles of how far along the ply scattered light travels before it leaves (through the far side, and on the
#: side it entered), at the C++ core's levels (kernel/exit_placement.h, whose exit_side_from_json this mirrors: the
#: patched Cycles refuses, and renders in magenta, what this refuses). Models from before D72 hold six unsigned
#: quantiles pooled over the bands ('axial_exit_through', 'axial_exit_reflected'), which the core converts.
NEAR_FIELD_BANDS = 5
NEAR_FIELD_QUANTILES = 9
#: Where around the ply the light came in (D73): rows of the leaving point's h across the width, per band.
NEAR_FIELD_ENTRY_ROWS = 10
_NEAR_FIELD_LEGACY_QUANTILES = 6
_MAX_EXIT_OFFSET = 1000.0


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _quantiles_problem(q, lo: float, hi: float, count: str, out_of_range: str) -> str | None:
    """What is wrong with nine quantiles in [lo, hi], or None (kernel/exit_placement.h quantiles_check: value by
    value, the first fault names the message)."""
    if not isinstance(q, list) or len(q) != NEAR_FIELD_QUANTILES:
        return count
    for k, v in enumerate(q):
        if not (_finite(v) and lo <= v <= hi):
            return out_of_range
        if k > 0 and v < q[k - 1]:
            return "decreases: quantiles at higher levels must not be smaller"
    return None


def _band_problem(q) -> str | None:
    return _quantiles_problem(
        q, -_MAX_EXIT_OFFSET, _MAX_EXIT_OFFSET, "must hold nine quantiles per band (at 1, 5, 10, 25, 50, 75, 90, 95 and 99 %)",
        f"holds a value that is not a finite number in [-{_MAX_EXIT_OFFSET:g}, {_MAX_EXIT_OFFSET:g}] ply radii")


def _entry_problem(bands) -> str | None:
    """What is wrong with one side's entry h (decisions D73: per band, NEAR_FIELD_ENTRY_ROWS rows of nine quantiles
    in [-1, 1]), or None (kernel/exit_placement.h entry_side_from_json, value by value)."""
    if not isinstance(bands, list) or len(bands) != NEAR_FIELD_BANDS:
        return "must hold five bands (of |cos| between the light and the ply's axis) of ten rows"
    for rows in bands:
        if not isinstance(rows, list) or len(rows) != NEAR_FIELD_ENTRY_ROWS:
            return "must hold ten rows per band (of the leaving point's h across the width: -1 ... 1)"
        for q in rows:
            problem = _quantiles_problem(q, -1.0, 1.0,
                                         "must hold nine quantiles per row (at 1, 5, 10, 25, 50, 75, 90, 95 and 99 %)",
                                         "holds a value that is not a number in [-1, 1] (across the ply's width)")
            if problem is not None:
                return problem
    return None


def near_field_problem(near_field) -> str | None:
    """What is wrong with a model's "near_field" object, or None: each side its 'through_bands' /
    'reflected_bands', else the pre-D72 'axial_exit_through' / 'axial_exit_reflected'; the far side required; each
    side's optional entry h ('through_entry', 'reflected_entry', D73) with its side's offsets."""
    if not isinstance(near_field, dict):
        return "must be an object"
    for side in ("through", "reflected"):
        key, legacy = f"{side}_bands", f"axial_exit_{side}"
        if key in near_field:
            bands = near_field[key]
            if not isinstance(bands, list) or len(bands) != NEAR_FIELD_BANDS:
                return f"'{key}' must hold five bands (of |cos| between the light and the ply's axis: 0-0.2 ... 0.8-1)"
            for q in bands:
                if (problem := _band_problem(q)) is not None:
                    return f"'{key}' {problem}"
        elif legacy in near_field:
            q = near_field[legacy]
            if not (isinstance(q, list) and len(q) == _NEAR_FIELD_LEGACY_QUANTILES
                    and all(_finite(v) and 0.0 <= v <= _MAX_EXIT_OFFSET for v in q)
                    and all(b >= a for a, b in zip(q, q[1:]))):
                return (f"'{legacy}' must hold six non-decreasing quantiles in [0, 1000] ply radii (at 25, 50, 75, "
                        "90, 95 and 99 %)")
        elif side == "through":
            return "must hold 'through_bands' (or a model's from before D72: 'axial_exit_through')"
        entry = f"{side}_entry"
        if entry in near_field:
            if (problem := _entry_problem(near_field[entry])) is not None:
                return f"'{entry}' {problem}"
            if key not in near_field and legacy not in near_field:
                return f"'{entry}' needs the offsets of its side ('{key}') as well"
    return None


def parse_model(text: str, source: str) -> YarnModel:
    """Parses and checks a model's JSON text. `source` names it in error messages."""
    try:
        # NaN and Infinity: Python's json takes them, the C++ loader (nlohmann) does not.
        data = json.loads(text, parse_constant=_refuse_constant)
    except json.JSONDecodeError as e:
        raise _fail(source, f"not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    except ValueError as e:
        raise _fail(source, f"not valid JSON ({e})") from None
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
    level, plies, ply_twist = "plies", 1, 0.0
    structure = data.get("structure")
    if version == YARN_VERSION:
        if not isinstance(structure, dict) or structure.get("level") != "yarn":
            raise _fail(source, "a version 5 (yarn-level) model needs 'structure' with \"level\": \"yarn\"")
        plies, ply_twist, alpha = (structure.get(k) for k in ("plies", "ply_twist", "surface_alpha"))
        if not (isinstance(plies, int) and not isinstance(plies, bool) and 2 <= plies <= 16):
            raise _fail(source, f"'structure' 'plies' must be an integer in [2, 16] (got {plies!r})")
        for key, v in (("ply_twist", ply_twist), ("surface_alpha", alpha)):
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise _fail(source, f"'structure' '{key}' must be a finite number (got {v!r})")
        if ply_twist < 0:
            raise _fail(source, f"'structure' 'ply_twist' must be >= 0 (got {ply_twist!r})")
        level = "yarns"
    elif structure is not None:
        raise _fail(source, "'structure' (a yarn-level model) needs format version 5")
    flat = data.get("kernel_flat")
    if not isinstance(flat, list):
        raise _fail(source, "missing 'kernel_flat' (the array the native closure uploads)")
    if version == 2:
        # Layout 2: the C++ loader only checks its version and numbers (it rebuilds the array).
        if len(flat) < 20 or flat[0] != 2.0 or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in flat):
            raise _fail(source, "'kernel_flat' is not a layout 2 array of finite numbers")
    else:
        # Version 4 and 5 files hold layout 4 (no R free path), 5 (no R node frames) or 6 (this code's), as
        # their array says.
        layout = 3 if version == 3 else int(flat[0]) if flat and flat[0] in (5.0, 6.0) else 4
        problem = kernel_flat_problem(flat, layout)
        if problem:
            raise _fail(source, f"'kernel_flat' {problem}")
        free_path = data.get("r_free_path", 0.0 if layout < 5 else None)
        if layout < 5 and "r_free_path" in data:
            raise _fail(source, "'r_free_path' needs a layout 5 'kernel_flat'")
        if "r_surface_frames" in data and (layout < 6 or level != "yarns"):
            raise _fail(source, "'r_surface_frames' needs a yarn-level model with a layout 6 'kernel_flat'")
        # The frames are the array's and the file's alike, or neither's (the C++ loader rebuilds the array).
        surface = data.get("r_surface_frames")
        frames = surface.get("frames") if isinstance(surface, dict) else None
        in_flat = _r_node_frames(flat) if layout >= 6 else None
        if (surface is not None or in_flat is not None) and (
                not isinstance(frames, list) or in_flat is None or
                [v for fr in frames for v in (fr if isinstance(fr, list) else [None])] != in_flat):
            raise _fail(source, "'r_surface_frames' disagrees with the kernel array's R node frames")
        if layout >= 5 and (not isinstance(free_path, (int, float)) or isinstance(free_path, bool) or
                            not math.isfinite(free_path) or not 0.0 <= free_path <= _MAX_FREE_PATH or
                            abs(flat[26] - free_path) > 1e-6 * max(1.0, free_path)):
            raise _fail(source, f"'r_free_path' must be a number in [0, {_MAX_FREE_PATH}] equal to the "
                                f"kernel array's (got {free_path!r})")
    if "near_field" in data:
        problem = near_field_problem(data["near_field"])
        if problem:
            raise _fail(source, f"'near_field' {problem}")
    model = YarnModel(source=source, text=text, data=data, preset_name=preset["name"], alpha=float(alpha),
                      level=level, plies=int(plies), ply_twist=float(ply_twist))
    if flat and flat[0] in (4.0, 5.0, 6.0) and abs(flat[2] - model.alpha) > 1e-6 * max(1.0, abs(model.alpha)):
        raise _fail(source, "'kernel_flat' twist disagrees with the model's "
                            + ("surface twist" if level == "yarns" else "preset alpha"))
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
