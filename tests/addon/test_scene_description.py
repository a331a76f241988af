# SPDX-License-Identifier: Apache-2.0
"""The scene description reader (addon/scene_description.py, no bpy): what `neuralyarn cycles-scene --out X.json`
writes loads as written, and a damaged description is refused with its file and field named, never built into a
scene with a renderer's defaults standing in for what is missing."""
import copy
import json
import math
import os
import subprocess

import pytest

import scene_description as sd

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir))
CLI = os.path.join(os.environ.get("NY_BUILD_DIR", os.path.join(ROOT, "build")), "cpp_core", "neuralyarn")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A description of the native close-up under the grazing light, as the CLI writes it, and its parsed JSON."""
    if not os.access(CLI, os.X_OK):
        pytest.skip(f"{CLI} is not built")
    path = tmp_path_factory.mktemp("desc") / "s.json"
    r = subprocess.run([CLI, "cycles-scene", "--preset", "fleece", "--model", os.path.join(ROOT, "models", "fleece.json"),
                        "--lights", "grazing", "--seed", "5", "--width", "64", "--height", "32", "--out", str(path)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return path, json.loads(path.read_text())


def test_a_written_description_loads_as_written(written):
    path, data = written
    d = sd.load_scene(str(path))
    assert d["camera"] == {"width": 64, "height": 32, "position": (0.0, 0.0, -12.0), "fov": pytest.approx(0.9)}
    assert d["film"] == {"filter_type": "box", "filter_width": 1.0}
    assert d["integrator"]["seed"] == 5 and d["integrator"]["max_bounce"] == 1024
    assert d["integrator"]["use_adaptive_sampling"] is False
    (light,) = d["lights"]
    assert light["type"] == "distant" and light["visible_to_camera"] is False
    # 80 degrees from the view (-z), toward +y
    assert math.degrees(math.acos(-light["direction"][2])) == pytest.approx(80.0, abs=1e-6)
    (obj,) = d["objects"]
    # The model path is relative to the description in the file and resolved against its directory here.
    assert not os.path.isabs(data["objects"][0]["material"]["model"])
    assert obj["material"] == {"type": "neural_yarn", "model": os.path.join(ROOT, "models", "fleece.json")}
    assert obj["curves"]["keys"] == [17] and obj["curves"]["radius"] == [1.0]
    assert obj["curves"]["points"][:3] == [-8.0, 0.0, 0.0]  # the default ply, 16 long along x


def _edit(data, path: str, value):
    """A copy of data with the field at the dotted path (list indices as numbers) set, or deleted for None."""
    d = copy.deepcopy(data)
    keys = [int(k) if k.isdigit() else k for k in path.split(".")]
    node = d
    for k in keys[:-1]:
        node = node[k]
    if value is None:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return d


@pytest.mark.parametrize("field, value, message", [
    ("format", "neuralyarn-plies 1", "not a scene description"),
    ("integrator.min_bounce", None, "missing 'min_bounce'"),
    ("integrator.use_adaptive_sampling", 0, "expected true or false"),
    ("integrator.max_bounce", 70000, "not in [0, 65535]"),
    ("film.filter_type", "mitchell", "unknown pixel filter 'mitchell'"),
    ("camera.fov", -1.0, "camera.fov"),
    ("camera.width", 1.5, "expected an integer"),
    ("lights.0.direction", [0.0, 0.0, 2.0], "expected a unit vector"),
    ("lights.0.type", "spot", "unknown light 'spot'"),
    ("objects.0.material.type", "velvet", "unknown material 'velvet'"),
    ("objects.0.material.model", None, "missing 'model'"),
    ("objects.0.curves.keys", [16], "expected 3 x 16 coordinates"),
    ("objects.0.curves.radius", [0.0], "every radius must be positive"),
    ("objects.0.curves.points.4", "x", "every coordinate must be a finite number"),
    ("background.colour", [1, 1], "expected 3 numbers"),
])
def test_a_damaged_description_is_refused_naming_the_field(written, tmp_path, field, value, message):
    _, data = written
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(_edit(data, field, value)))
    with pytest.raises(sd.SceneDescriptionError) as e:
        sd.load_scene(str(bad))
    assert str(bad) in str(e.value) and message in str(e.value), str(e.value)


def test_not_json_nan_and_a_missing_file_are_refused(written, tmp_path):
    _, data = written
    for text, message in (("{", "not JSON"), (json.dumps(data).replace("-12.0", "NaN", 1), "NaN is not a number")):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(sd.SceneDescriptionError, match=message):
            sd.load_scene(str(bad))
    with pytest.raises(sd.SceneDescriptionError, match="cannot read the file"):
        sd.load_scene(str(tmp_path / "missing.json"))


def _surface_mesh():
    """A version-2 description's one mesh: a quad of the surface level's material."""
    return {"name": "cloth", "material": {"type": "cloth_surface", "front": 0.49, "back_start": 0.51, "closures": [
        {"closure": "transparent", "alpha": 0.0, "weight": [[0.1, 0.1, 0.1], [0.2, 0.2, 0.2]]},
        {"closure": "ggx", "alpha": 0.25, "weight": [[0.5, 0.4, 0.3], [0.6, 0.5, 0.4], [1.5, 1.2, 0.9]]}]},
        "mesh": {"vertices": [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0], "triangles": [0, 1, 2, 0, 2, 3]}}


def test_meshes_need_version_2_and_version_2_needs_meshes(written, tmp_path):
    """The surface level's cloth is a mesh: a reader of version 1 would drop it and render the scene without its
    cloth, so a file with meshes says version 2, and either version with the other's content is refused."""
    _, data = written
    ok = tmp_path / "ok.json"
    ok.write_text(json.dumps({**data, "format": "neuralyarn-scene 2", "meshes": [_surface_mesh()]}))
    d = sd.load_scene(str(ok))
    (m,) = d["meshes"]
    assert m["material"]["closures"][1] == {"closure": "ggx", "alpha": 0.25, "weight": [
        (0.5, 0.4, 0.3), (0.6, 0.5, 0.4), (1.5, 1.2, 0.9)]}
    assert m["mesh"]["triangles"] == [0, 1, 2, 0, 2, 3] and sd.load_scene(str(written[0]))["meshes"] == []
    for doc, message in (({**data, "meshes": [_surface_mesh()]}, "meshes need format 'neuralyarn-scene 2'"),
                         ({**data, "format": "neuralyarn-scene 2"}, "missing 'meshes'")):
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps(doc))
        with pytest.raises(sd.SceneDescriptionError, match=message):
            sd.load_scene(str(bad))


@pytest.mark.parametrize("field, value, message", [
    ("material.type", "diffuse", "a mesh's material is a cloth_surface"),
    ("material.closures.0.closure", "velvet", "unknown closure 'velvet'"),
    ("material.closures.1.weight", [[1, 1, 1]], "expected at least two RGB samples"),
    ("material.closures.1.weight.2", [1, -1, 1], "not in [0, inf]"),
    ("material.front", None, "missing 'front'"),
    ("mesh.triangles", [0, 1, 4], "each index in [0, 4)"),
    ("mesh.vertices", [0, 0, 0, 1], "expected x y z triples"),
])
def test_a_damaged_mesh_is_refused_naming_the_field(written, tmp_path, field, value, message):
    _, data = written
    doc = {**data, "format": "neuralyarn-scene 2", "meshes": [_edit(_surface_mesh(), field, value)]}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(sd.SceneDescriptionError) as e:
        sd.load_scene(str(bad))
    assert "meshes[0]" in str(e.value) and message in str(e.value), str(e.value)
