# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the add-on finds its shipped files: the preset list and the presets' models.

An installed add-on (the zip made by scripts/package_addon.sh) carries them inside the package
(`presets.json`, `models/`); a development checkout loads the add-on straight from the repository's `addon/`
directory, where they are the core's `cpp_core/data/presets.json` and the top-level `models/`. No bpy here.
"""

from __future__ import annotations

import json
import os

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
_PRESETS_FILES = (os.path.join(PACKAGE_DIR, "presets.json"),
                  os.path.join(os.path.dirname(PACKAGE_DIR), "cpp_core", "data", "presets.json"))


def _presets_file() -> str:
    for path in _PRESETS_FILES:
        if os.path.isfile(path):
            return path
    raise FileNotFoundError(f"the preset list is missing (looked in {', '.join(_PRESETS_FILES)}); "
                            f"reinstall the add-on from a zip made by scripts/package_addon.sh")


def _preset_names(path: str) -> tuple[str, ...]:
    """The fiber presets' names, in the core's order, from the one preset list (cpp_core/data/presets.json)."""
    with open(path, encoding="utf-8") as f:
        data = json.load(f)
    if data.get("format") != "neuralyarn-fiber-presets" or not isinstance(data.get("presets"), dict) or \
            not data["presets"]:
        raise RuntimeError(f"'{path}' is not the neuralyarn preset list; reinstall the add-on")
    return tuple(data["presets"])


PRESETS_FILE = _presets_file()
PRESETS = _preset_names(PRESETS_FILE)


def _candidates(sub: str) -> list[str]:
    return [os.path.join(PACKAGE_DIR, sub), os.path.join(os.path.dirname(PACKAGE_DIR), sub)]


def resource_dir(sub: str) -> str:
    """The first of <package>/<sub> and <package>/../<sub> that exists; FileNotFoundError otherwise."""
    for d in _candidates(sub):
        if os.path.isdir(d):
            return d
    raise FileNotFoundError(f"the add-on's '{sub}' directory is missing (looked in {', '.join(_candidates(sub))}); "
                            f"reinstall the add-on from a zip made by scripts/package_addon.sh")


def _check_preset(name: str) -> None:
    if name not in PRESETS:
        raise ValueError(f"unknown preset '{name}' (one of {', '.join(PRESETS)})")


def _shipped(file: str, what: str) -> str:
    path = os.path.join(resource_dir("models"), file)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"the shipped {what} '{path}' is missing; reinstall the add-on")
    return path


def surface_material_path(name: str) -> str:
    """Path of a preset's shipped surface-level material (<name>_surface_knit.json: the far field of the Knitted
    Swatch at its default shape, scripts/make_surface_materials.py); ValueError for an unknown preset,
    FileNotFoundError if it is missing."""
    _check_preset(name)
    return _shipped(name + "_surface_knit.json", "surface material")


def preset_model_path(name: str, level: str = "plies") -> str:
    """Path of a shipped model file: the ply level's <name>.json or the yarn level's <name>_yarn.json (3 plies at
    ply twist 0.5, the add-on's default plying); ValueError for an unknown preset or level, FileNotFoundError if
    it is missing."""
    _check_preset(name)
    if level not in ("plies", "yarns"):
        raise ValueError(f"shipped models are of the plies and yarns levels, not '{level}'")
    return _shipped(name + ("_yarn" if level == "yarns" else "") + ".json", "model")
