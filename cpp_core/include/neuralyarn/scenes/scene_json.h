// SPDX-License-Identifier: Apache-2.0
//
// A scene description (scenes/scene.h) as the JSON file "neuralyarn-scene 1" or 2 (docs/file_formats.md), which the
// add-on's Blender builder (addon/scene_bpy.py, through addon/scene_description.py) turns into a Blender scene:
// the same camera, pixel filter, integrator, lights, curves, meshes and materials as the Cycles XML of the scene.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "neuralyarn/scenes/scene.h"

namespace neuralyarn::scenes {

/* The format name the file states ("format"): version 1 without meshes, 2 with the surface level's meshes (which a
 * reader of version 1 would drop: it refuses the name instead). */
constexpr const char *kSceneFormat = "neuralyarn-scene 1";
constexpr const char *kSceneFormatMeshes = "neuralyarn-scene 2";

/* The format of a surface level's material on its own (`neuralyarn surface --material-out`): what the add-on draws
 * its cloth surface with. */
constexpr const char *kClothSurfaceFormat = "neuralyarn-cloth-surface 1";

/* A material as the description writes it; a neural yarn material's model path relative to `scene_path`'s
 * directory. */
nlohmann::json material_json(const Material &m, const std::string &scene_path);

/* The scene as JSON; a neural yarn material's model path relative to `scene_path`'s directory. */
nlohmann::json scene_json(const Scene &scene, const std::string &scene_path);

}  // namespace neuralyarn::scenes
