# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the add-on finds its shipped files: the five models and the OSL generator.

An installed add-on (the zip made by scripts/package_addon.sh) carries them inside the package
(`models/`, `osl/`); a development checkout loads the add-on straight from the repository's `addon/`
directory, where they are the repository's top-level `models/` and `osl/`. No bpy here.
"""

from __future__ import annotations

import importlib.util
import os
import sys

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
PRESETS = ("fleece", "silk", "polyester", "cotton", "gabardine")


def _candidates(sub: str) -> list[str]:
    return [os.path.join(PACKAGE_DIR, sub), os.path.join(os.path.dirname(PACKAGE_DIR), sub)]


def resource_dir(sub: str) -> str:
    """The first of <package>/<sub> and <package>/../<sub> that exists; FileNotFoundError otherwise."""
    for d in _candidates(sub):
        if os.path.isdir(d):
            return d
    raise FileNotFoundError(f"the add-on's '{sub}' directory is missing (looked in {', '.join(_candidates(sub))}); "
                            f"reinstall the add-on from a zip made by scripts/package_addon.sh")


def preset_model_path(name: str, level: str = "plies") -> str:
    """Path of a shipped model file: the ply level's <name>.json or the yarn level's <name>_yarn.json (3 plies at
    ply twist 0.5, the add-on's default plying); ValueError for an unknown preset or level, FileNotFoundError if
    it is missing."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset '{name}' (one of {', '.join(PRESETS)})")
    if level not in ("plies", "yarns"):
        raise ValueError(f"shipped models are of the plies and yarns levels, not '{level}'")
    path = os.path.join(resource_dir("models"), name + ("_yarn" if level == "yarns" else "") + ".json")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"the shipped model '{path}' is missing; reinstall the add-on")
    return path


_generator = None


def osl_generator():
    """The module osl/generate_osl.py (loaded once, under a private name so that it cannot clash)."""
    global _generator
    if _generator is None:
        path = os.path.join(resource_dir("osl"), "generate_osl.py")
        spec = importlib.util.spec_from_file_location("_neural_yarn_generate_osl", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
        _generator = module
    return _generator
