// SPDX-License-Identifier: Apache-2.0
//
// A scene description (scenes/scene.h) as the JSON file "neuralyarn-scene 1" (docs/file_formats.md), which the
// add-on's Blender builder (addon/scene_bpy.py, through addon/scene_description.py) turns into a Blender scene:
// the same camera, pixel filter, integrator, lights, curves and materials as the Cycles XML of the scene.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "neuralyarn/scenes/scene.h"

namespace neuralyarn::scenes {

/* The format name the file states ("format"). */
constexpr const char *kSceneFormat = "neuralyarn-scene 1";

/* The scene as JSON; a neural yarn material's model path relative to `scene_path`'s directory. */
nlohmann::json scene_json(const Scene &scene, const std::string &scene_path);

}  // namespace neuralyarn::scenes
