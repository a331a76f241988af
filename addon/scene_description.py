# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene descriptions ("neuralyarn-scene 1", docs/file_formats.md): the JSON form of the one description of a
scene that `neuralyarn cycles-scene` also writes as Cycles XML (cpp_core/include/neuralyarn/scenes/scene.h).
This module reads and checks a file without bpy (the standard library only, no relative imports); the Blender
builder is scene_bpy.py. Every field is required: a description leaves nothing to a renderer's defaults."""

from __future__ import annotations

import json
import math
import os

FORMAT = "neuralyarn-scene 1"
#: Version 2: also `meshes` (the surface level's cloth), which a reader of version 1 would drop.
FORMAT_MESHES = "neuralyarn-scene 2"
#: The surface level's closures (docs/decisions.md D44).
SURFACE_CLOSURES = ("transparent", "diffuse", "translucent", "ggx")

#: Integrator settings, as the file names them (Cycles' own names) and their type.
INTEGRATOR = {
    "max_bounce": int, "max_diffuse_bounce": int, "max_glossy_bounce": int, "max_transmission_bounce": int,
    "transparent_max_bounce": int, "min_bounce": int, "sample_clamp_direct": float, "sample_clamp_indirect": float,
    "filter_glossy": float, "light_sampling_threshold": float, "use_adaptive_sampling": bool, "seed": int,
}
PIXEL_FILTERS = ("box", "gaussian", "blackman_harris")
#: Material types and the fields each has besides "type".
MATERIALS = {
    "neural_yarn": ("model",),
    "khungurn_fiber": ("C_R", "C_TT", "beta_R", "beta_TT", "gamma_TT"),
    "principled_hair_chiang": ("colour",),
    "principled_hair_huang": ("colour",),
    "sheen": ("colour",),
    "diffuse": ("colour",),
}


class SceneDescriptionError(ValueError):
    """A file that is not a valid scene description; the message names the file and the field."""


def _reject(where: str, what: str):
    raise SceneDescriptionError(f"{where}: {what}")


def _field(d, key: str, where: str):
    if not isinstance(d, dict):
        _reject(where, "expected an object")
    if key not in d:
        _reject(where, f"missing '{key}'")
    return d[key]


def _number(v, where: str, kind=float, lo=-math.inf, hi=math.inf):
    if kind is bool:
        if not isinstance(v, bool):
            _reject(where, f"expected true or false, got {v!r}")
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (kind is int and not isinstance(v, int)):
        _reject(where, f"expected {'an integer' if kind is int else 'a number'}, got {v!r}")
    if not (math.isfinite(v) and lo <= v <= hi):
        _reject(where, f"{v!r} is not finite or not in [{lo:g}, {hi:g}]")
    return kind(v)


def _vector(v, where: str, n: int = 3, lo=-math.inf, hi=math.inf) -> tuple[float, ...]:
    if not isinstance(v, list) or len(v) != n:
        _reject(where, f"expected {n} numbers")
    return tuple(_number(x, f"{where}[{i}]", float, lo, hi) for i, x in enumerate(v))


def _curves(c, where: str) -> dict:
    keys = _field(c, "keys", where)
    radius = _field(c, "radius", where)
    points = _field(c, "points", where)
    if not isinstance(keys, list) or not keys or not all(isinstance(k, int) and not isinstance(k, bool) and k >= 2
                                                         for k in keys):
        _reject(f"{where}.keys", "expected a non-empty list of point counts, each at least 2")
    if not isinstance(radius, list) or len(radius) != len(keys):
        _reject(f"{where}.radius", f"expected one radius per curve ({len(keys)})")
    radii = [_number(r, f"{where}.radius[{i}]", float, 0.0) for i, r in enumerate(radius)]
    if any(r <= 0.0 for r in radii):
        _reject(f"{where}.radius", "every radius must be positive")
    if not isinstance(points, list) or len(points) != 3 * sum(keys):
        _reject(f"{where}.points", f"expected 3 x {sum(keys)} coordinates, got "
                                   f"{len(points) if isinstance(points, list) else type(points).__name__}")
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in points):
        _reject(f"{where}.points", "every coordinate must be a finite number")
    return {"keys": keys, "radius": radii, "points": points}


def _material(m, where: str, base: str) -> dict:
    kind = _field(m, "type", where)
    if kind not in MATERIALS:
        _reject(f"{where}.type", f"unknown material '{kind}' (known: {', '.join(MATERIALS)})")
    out = {"type": kind}
    for key in MATERIALS[kind]:
        v = _field(m, key, where)
        if key == "model":
            if not isinstance(v, str) or not v:
                _reject(f"{where}.model", "expected a model file path")
            out[key] = os.path.normpath(os.path.join(base, v))  # relative to the description's directory
        elif key in ("C_R", "C_TT", "colour"):
            out[key] = _vector(v, f"{where}.{key}", 3, 0.0, 1.0)
        else:
            out[key] = _number(v, f"{where}.{key}", float, 0.0, math.pi)
    if kind == "neural_yarn" and "model_json" in m:
        if not isinstance(m["model_json"], str):
            _reject(f"{where}.model_json", "expected the model file's text")
        out["model_json"] = m["model_json"]
    return out


def parse_cloth_surface(m, where: str) -> dict:
    """The surface level's material: closures weighted by RGB curves of x = front |N.I| + back_start Backfacing."""
    out = {"type": "cloth_surface",
           "front": _number(_field(m, "front", where), f"{where}.front", float, 0.0, 1.0),
           "back_start": _number(_field(m, "back_start", where), f"{where}.back_start", float, 0.0, 1.0)}
    closures = _field(m, "closures", where)
    if not isinstance(closures, list) or not closures:
        _reject(f"{where}.closures", "expected a non-empty list")
    out["closures"] = []
    for i, c in enumerate(closures):
        w = f"{where}.closures[{i}]"
        kind = _field(c, "closure", w)
        if kind not in SURFACE_CLOSURES:
            _reject(f"{w}.closure", f"unknown closure '{kind}' (known: {', '.join(SURFACE_CLOSURES)})")
        weight = _field(c, "weight", w)
        if not isinstance(weight, list) or len(weight) < 2:
            _reject(f"{w}.weight", "expected at least two RGB samples")
        out["closures"].append({
            "closure": kind, "alpha": _number(_field(c, "alpha", w), f"{w}.alpha", float, 0.0, 1.0),
            "weight": [_vector(v, f"{w}.weight[{k}]", 3, 0.0) for k, v in enumerate(weight)]})
    return out


def _mesh(m, where: str) -> dict:
    vertices, triangles = _field(m, "vertices", where), _field(m, "triangles", where)
    if not isinstance(vertices, list) or not vertices or len(vertices) % 3 or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in vertices):
        _reject(f"{where}.vertices", "expected x y z triples of finite numbers")
    n = len(vertices) // 3
    if not isinstance(triangles, list) or not triangles or len(triangles) % 3 or not all(
            isinstance(i, int) and not isinstance(i, bool) and 0 <= i < n for i in triangles):
        _reject(f"{where}.triangles", f"expected vertex index triples, each index in [0, {n})")
    return {"vertices": vertices, "triangles": triangles}


def _light(light, where: str) -> dict:
    kind = _field(light, "type", where)
    out = {"type": kind,
           "strength": _number(_field(light, "strength", where), f"{where}.strength", float, 0.0),
           "use_mis": _number(_field(light, "use_mis", where), f"{where}.use_mis", bool),
           "visible_to_camera": _number(_field(light, "visible_to_camera", where), f"{where}.visible_to_camera", bool)}
    if kind == "point":
        out["position"] = _vector(_field(light, "position", where), f"{where}.position")
        out["radius"] = _number(_field(light, "radius", where), f"{where}.radius", float, 0.0)
    elif kind == "distant":
        d = _vector(_field(light, "direction", where), f"{where}.direction")
        if abs(math.hypot(*d) - 1.0) > 1e-6:
            _reject(f"{where}.direction", "expected a unit vector")
        out["direction"] = d
        out["angle"] = _number(_field(light, "angle", where), f"{where}.angle", float, 0.0, math.pi)
    else:
        _reject(f"{where}.type", f"unknown light '{kind}' (known: point, distant)")
    return out


def parse_scene(data, where: str, base: str) -> dict:
    """The checked description of a parsed JSON document; model paths resolved against `base` (a directory)."""
    version = _field(data, "format", where)
    if version not in (FORMAT, FORMAT_MESHES):
        _reject(where, f"not a scene description (format {data.get('format')!r}, expected '{FORMAT}' or "
                       f"'{FORMAT_MESHES}')")
    cam = _field(data, "camera", where)
    camera = {"width": _number(_field(cam, "width", f"{where}.camera"), f"{where}.camera.width", int, 1, 65536),
              "height": _number(_field(cam, "height", f"{where}.camera"), f"{where}.camera.height", int, 1, 65536),
              "position": _vector(_field(cam, "position", f"{where}.camera"), f"{where}.camera.position"),
              "fov": _number(_field(cam, "fov", f"{where}.camera"), f"{where}.camera.fov", float, 1e-6, math.pi - 1e-6)}
    film = _field(data, "film", where)
    filter_type = _field(film, "filter_type", f"{where}.film")
    if filter_type not in PIXEL_FILTERS:
        _reject(f"{where}.film.filter_type", f"unknown pixel filter '{filter_type}' (known: {', '.join(PIXEL_FILTERS)})")
    film = {"filter_type": filter_type,
            "filter_width": _number(_field(film, "filter_width", f"{where}.film"), f"{where}.film.filter_width",
                                    float, 0.01, 10.0)}
    integ = _field(data, "integrator", where)
    integrator = {k: _number(_field(integ, k, f"{where}.integrator"), f"{where}.integrator.{k}", t,
                             *((0, 65535) if t is int and k != "seed" else ()))
                  for k, t in INTEGRATOR.items()}
    bg = _field(data, "background", where)
    background = {"strength": _number(_field(bg, "strength", f"{where}.background"), f"{where}.background.strength",
                                      float, 0.0),
                  "colour": _vector(_field(bg, "colour", f"{where}.background"), f"{where}.background.colour", 3, 0.0)}
    lights = _field(data, "lights", where)
    objects = _field(data, "objects", where)
    if not isinstance(lights, list) or not isinstance(objects, list):
        _reject(where, "'lights' and 'objects' must be lists")
    out_objects = []
    for i, o in enumerate(objects):
        w = f"{where}.objects[{i}]"
        name = _field(o, "name", w)
        if not isinstance(name, str) or not name:
            _reject(f"{w}.name", "expected a name")
        out_objects.append({"name": name, "material": _material(_field(o, "material", w), f"{w}.material", base),
                            "curves": _curves(_field(o, "curves", w), f"{w}.curves")})
    meshes = []
    if version == FORMAT_MESHES:
        listed = _field(data, "meshes", where)
        if not isinstance(listed, list) or not listed:
            _reject(f"{where}.meshes", "expected a non-empty list (version 2 is a scene with meshes)")
        for i, o in enumerate(listed):
            w = f"{where}.meshes[{i}]"
            name = _field(o, "name", w)
            if not isinstance(name, str) or not name:
                _reject(f"{w}.name", "expected a name")
            material = _field(o, "material", w)
            if _field(material, "type", f"{w}.material") != "cloth_surface":
                _reject(f"{w}.material.type", "a mesh's material is a cloth_surface")
            meshes.append({"name": name, "material": parse_cloth_surface(material, f"{w}.material"),
                           "mesh": _mesh(_field(o, "mesh", w), f"{w}.mesh")})
    elif "meshes" in data:
        _reject(f"{where}.meshes", f"meshes need format '{FORMAT_MESHES}'")
    title = data.get("title", "")
    return {"title": title if isinstance(title, str) else "", "camera": camera, "film": film,
            "integrator": integrator, "background": background,
            "lights": [_light(light, f"{where}.lights[{i}]") for i, light in enumerate(lights)],
            "objects": out_objects, "meshes": meshes}


def load_scene(path: str) -> dict:
    """The checked description in a file. Raises SceneDescriptionError naming the file and what is wrong."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f, parse_constant=lambda c: _reject(path, f"{c} is not a number JSON allows"))
    except OSError as e:
        raise SceneDescriptionError(f"{path}: cannot read the file ({e.strerror})") from None
    except json.JSONDecodeError as e:
        raise SceneDescriptionError(f"{path}: not JSON ({e})") from None
    return parse_scene(data, path, os.path.dirname(os.path.abspath(path)))
