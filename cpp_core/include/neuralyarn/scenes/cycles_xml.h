// SPDX-License-Identifier: Apache-2.0
//
// A scene description (scenes/scene.h) as Cycles XML for the patched standalone Cycles (`cycles scene.xml`,
// cycles_patch/): its reader's elements and attribute names (Cycles 4.3, app/cycles_xml.cpp, with the
// neural_yarn_bsdf and khungurn_fiber_bsdf nodes of cycles_patch/).
#pragma once

#include <string>

#include "neuralyarn/scenes/scene.h"

namespace neuralyarn::scenes {

/* The scene's XML; a neural yarn material's model path relative to `scene_path`'s directory. */
std::string cycles_xml(const Scene &scene, const std::string &scene_path);

}  // namespace neuralyarn::scenes
