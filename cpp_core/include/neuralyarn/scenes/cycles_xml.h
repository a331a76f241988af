// SPDX-License-Identifier: Apache-2.0
//
// Scenes for the patched standalone Cycles (`cycles scene.xml`, cycles_patch/): the paper's single-ply
// close-up — a straight ply across the frame, seen from the side, lit by one of the light rigs below
// (by default a sphere light in front and one behind it, for transmission) — in two versions from the
// same preset and packing seed: explicit (the ply's fibers as <hair> curves shaded by the
// khungurn_fiber_bsdf closure) and aggregated (one thick curve of the ply's radius shaded by the
// neural_yarn_bsdf closure with a model file). Units: the ply radius is 1; the ply lies along x through
// the origin, the camera looks along +z from z = -12. The stability suite (scripts/stability.py) varies
// the camera's distance, the scene's unit, the light's angle and stacks cloth layers of plies. The
// evaluation harness (scripts/evaluate.py) also renders the aggregated geometry with a stock Cycles closure
// instead of the neural one: the baselines an artist would use (Principled Hair, Principled BSDF's sheen).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "neuralyarn/presets.h"

namespace neuralyarn::scenes {

/* The close-up's camera: at (0, 0, -distance), looking along +z, field of view (radians) of the shorter
 * side of the image. */
constexpr double kCloseupCameraDistance = 12.0, kCloseupCameraFov = 0.9;

/* The pixel filter of every scene: a box one pixel wide, the standalone Cycles' default, written into the
 * scene (<film>) so that Blender (scripts/fallback_render.py, whose own default is Blackman-Harris 1.5 px)
 * renders the same pixels and the prediction (closeup_prediction.h) integrates the same footprint. */
constexpr double kPixelFilterWidth = 1.0;

/* One light of a rig. */
struct RigLight {
  enum class Kind { point, distant };
  Kind kind = Kind::point;
  double x = 0, y = 0, z = 0; /* point: the position; distant: the unit vector from the ply toward the light */
  double strength = 0;        /* point: power, W; distant: irradiance on a plane facing the light, W/m^2 */
  double size = 0;            /* point: the sphere's radius; distant: the light's angular diameter, degrees */
};

/* A named lighting of the close-up. */
struct LightRig {
  std::string name, description;
  bool environment = false; /* a uniform white background of strength 1 (otherwise black) */
  std::vector<RigLight> lights;
};

/* The rigs, in a fixed order; the first, "key-rim", is the default. */
const std::vector<LightRig> &light_rigs();
/* "key-rim, environment, ...": the rigs' names in order. */
std::string light_rig_names();
/* The rig of that name, or a parametric distant light "sun-DEG-normal" / "sun-DEG-axis": DEG (0 to 180)
 * degrees from the view direction, tilted in the plane normal to the ply (toward +y) or along its axis
 * (toward +x) — the grazing rig is sun-80-normal. Throws std::runtime_error listing the known names
 * otherwise. */
LightRig find_light_rig(const std::string &name);

/* Cycles' bounce limits (integrator max_bounce, max_diffuse_bounce, ...), each in [0, 65535] (total >= 1). */
struct BounceLimits {
  int total = 1024, diffuse = 1024, glossy = 1024, transmission = 1024, transparent = 1024;
  /* Blender's defaults (12, 4, 4, 12) with the add-on's transparent limit (addon/scene_setup.py): what an
   * artist's scene renders with. */
  static BounceLimits blender_addon();
};

struct PlySceneOptions {
  int width = 320, height = 160;
  double ply_length = 16.0;     /* along x, centred on the origin (a 2:1 frame is 23 wide at the ply: the ends show) */
  int segments_per_turn = 32;   /* curve keys per helix turn (Cycles interpolates them smoothly) */
  uint64_t packing_seed = 1;
  double ply_rotation_deg = 0.0; /* explicit version: the fibers turned about the ply axis (right-handed about +x):
                                  * a slowly twisted ply shows the camera one orientation of its random
                                  * cross-section, which the maps (and the model) average over */
  std::string lights = "key-rim"; /* the light rig (light_rigs()) */
  bool white_furnace = false;    /* the "environment" rig without Russian roulette (lights must stay the default
                                  * or be "environment"): every path runs until it leaves */
  int max_bounce = 1024;         /* Cycles' bounce limits (all kinds); low limits bias bright fibers dark */
  bool artist_bounces = false;   /* instead: BounceLimits::blender_addon() (the stability suite's stacks) */
  double camera_distance = kCloseupCameraDistance; /* from the ply axis, in ply radii (> 1): the ply's size in pixels */
  double unit_scale = 1.0;       /* every length (ply, camera, lights) times this: a ply of radius 1e-3 or 1e3 */
  int layers = 1;                /* > 1: cloth layers, each a sheet of parallel plies side by side (along y),
                                  * stacked away from the camera (+z) — light through all of them */
  std::string plies;             /* instead of the straight ply: these ply centrelines (scenes/ply_curves.h, e.g. a
                                  * garment); explicit: each ply's fibers swept along it (geometry/sweep.h) */
  std::string level = "plies";   /* aggregated version of `plies`: "plies" (each ply a curve, a ply-level model) or
                                  * "yarns" (each of the file's yarns one curve of its radius, a yarn-level model
                                  * of the file's plying: D27) */
  double light_scale = 1.0;      /* point lights' positions and sizes times this, their power times its square
                                  * (a scene larger than the close-up keeps the rig's look) */
  int seed = 0;                  /* Cycles' integrator seed: independent noise per value */
  std::string model;             /* aggregated version: the model file (written relative to the scene) */
  bool embed_model = false;      /* write the model's JSON into the scene (model_json), not its path */
  std::string baseline;          /* instead of --model: the aggregated geometry with a stock closure (baselines()) */
  double baseline_colour[3] = {0.5, 0.5, 0.5}; /* its colour, each in [0, 1] (the harness fits it, D23) */
};

/* A stock closure on the aggregated ply: what an artist would use instead of the neural model. */
struct Baseline {
  std::string name, description;
};
/* chiang, huang (Principled Hair, Blender's defaults but for the colour: "Direct coloring", and for Huang a
 * round cross-section), sheen (Principled BSDF with sheen 1 and Blender's default specular). */
const std::vector<Baseline> &baselines();

/* The most curve keys an explicit-fiber scene of ply curves may have (about 1.4 GB of scene text, ~6 GB in
 * Cycles: docs/benchmarks.md); more is refused before anything is written. */
constexpr int64_t kMaxExplicitKeys = 50'000'000;

/* Writes the scene; throws std::runtime_error naming the path when it cannot be written. */
void write_ply_scene(const FiberPreset &preset, const PlySceneOptions &options, const std::string &path);

/* A colour in double precision. */
struct Rgb3 {
  double r = 0, g = 0, b = 0;
};

}  // namespace neuralyarn::scenes
