// SPDX-License-Identifier: Apache-2.0
//
// The paper's single-ply close-up as a scene description (scenes/scene.h), written for the patched standalone
// Cycles (`neuralyarn cycles-scene --out X.xml`) and for the add-on's Blender builder (`--out X.json`): a
// straight ply across the frame, seen from the side, lit by one of the light rigs below (by default a sphere
// light in front and one behind it, for transmission) — in two versions from the same preset and packing
// seed: explicit (the ply's fibers as curves shaded by the khungurn_fiber_bsdf closure) and aggregated (one
// thick curve of the ply's radius shaded by the neural_yarn_bsdf closure with a model file). Units: the ply
// radius is 1; the ply lies along x through the origin, the camera looks along +z from z = -12. The stability
// suite (scripts/stability.py) varies the camera's distance, the scene's unit, the light's angle and stacks
// cloth layers of plies; a plies file replaces the straight ply by a garment's or a patch's ply curves. The
// evaluation harness (scripts/evaluate.py) also renders the aggregated geometry with a stock Cycles closure
// instead of the neural one: the baselines an artist would use (Principled Hair, Principled BSDF's sheen).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "neuralyarn/presets.h"
#include "neuralyarn/model/surface_fit.h"
#include "neuralyarn/scenes/scene.h"

namespace neuralyarn::scenes {

/* The close-up's camera: at (0, 0, -distance), looking along +z, field of view (radians) of the shorter
 * side of the image. */
constexpr double kCloseupCameraDistance = 12.0, kCloseupCameraFov = 0.9;

/* The pixel filter of every scene: a box one pixel wide, the standalone Cycles' default, written into the
 * scene (Film) so that Blender (addon/scene_bpy.py; Blender's own default is Blackman-Harris 1.5 px)
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

/* The layered scene's ply spacing by default, in ply radii: touching but for a small gap. */
constexpr double kLayerPitch = 2.05;

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
  double layer_pitch_y = kLayerPitch; /* with layers: ply axes this far apart within a sheet, in ply radii (>= 2: */
  double layer_pitch_z = kLayerPitch; /* plies do not overlap), and between sheets */
  std::string plies;             /* instead of the straight ply: these ply centrelines (scenes/ply_curves.h, e.g. a
                                  * garment); explicit: each ply's fibers swept along it (geometry/sweep.h) */
  std::string level = "plies";   /* aggregated version of `plies`: "plies" (each ply a curve, a ply-level model) or
                                  * "yarns" (each of the file's yarns one curve of its radius, a yarn-level model
                                  * of the file's plying: D27) or "surface" (the file's cloth surface with the
                                  * stock closures of `surface`: D44) */
  std::string surface;           /* level "surface": the surface BSDF file (model/surface_fit.h) */
  double light_scale = 1.0;      /* point lights' positions and sizes times this, their power times its square
                                  * (a scene larger than the close-up keeps the rig's look) */
  int seed = 0;                  /* Cycles' integrator seed: independent noise per value */
  std::string model;             /* aggregated version: the model file (written relative to the scene) */
  bool embed_model = false;      /* write the model's JSON into the scene (model_json), not its path */
  std::string baseline;          /* instead of --model: the aggregated geometry with a stock closure (baselines()) */
  double baseline_colour[3] = {0.5, 0.5, 0.5}; /* its colour, each in [0, 1] (the harness fits it, D23) */
  bool diffuse = false;          /* instead of --model: the aggregated geometry in a grey Lambertian (the check that
                                  * two renderers build the same scene: scripts/bench_fallback.sh) */
  bool empty = false;            /* camera, film, integrator and a black background only: the renderer's own
                                  * memory (the harness's baseline_rss_mb) */
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

/* The scene the options describe; throws std::runtime_error naming what is wrong (a bad option, an unreadable or
 * refused plies file or model) before any work. */
Scene ply_scene(const FiberPreset &preset, const PlySceneOptions &options);

/* The surface level's material of a surface BSDF (`neuralyarn surface`, D44): its closures, each with its weight
 * sampled as the renderers read it (256 RGB samples over x = front |N.I| + back_start Backfacing). */
Material cloth_surface_material(const model::SurfaceBsdf &bsdf);

/* ply_scene() written to `path` (write_scene(): .xml or .json). */
void write_ply_scene(const FiberPreset &preset, const PlySceneOptions &options, const std::string &path);

}  // namespace neuralyarn::scenes
