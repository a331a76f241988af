// SPDX-License-Identifier: Apache-2.0
//
// Scenes for the patched standalone Cycles (`cycles scene.xml`, cycles_patch/): the paper's single-ply
// close-up — a straight ply across the frame, seen from the side, lit by a sphere light in front and one
// behind it (for transmission) — with the ply's explicit fibers as <hair> curves shaded by the
// khungurn_fiber_bsdf closure. Units: the ply radius is 1.
#pragma once

#include <cstdint>
#include <string>

#include "neuralyarn/presets.h"

namespace neuralyarn::scenes {

struct PlySceneOptions {
  int width = 320, height = 160;
  double ply_length = 16.0;     /* along x, centred on the origin (the frame shows about 10) */
  int segments_per_turn = 32;   /* curve keys per helix turn (Cycles interpolates them smoothly) */
  uint64_t packing_seed = 1;
  double light_strength = 2000.0; /* W, each sphere light */
  bool white_furnace = false;    /* no lights, a uniform white background of strength 1 instead */
};

/* Writes the scene; throws std::runtime_error naming the path when it cannot be written. */
void write_fiber_ply_scene(const FiberPreset &preset, const PlySceneOptions &options, const std::string &path);

}  // namespace neuralyarn::scenes
