// SPDX-License-Identifier: Apache-2.0
//
// A scene as one description for every renderer (docs/decisions.md D37): camera, pixel filter, integrator
// settings, background, lights, and curve objects each with its material. Builders fill it (the close-up and
// its variants: scenes/ply_scene.h); two writers render it into a renderer's input, with nothing read back:
//   - Cycles XML for the patched standalone Cycles (scenes/cycles_xml.h),
//   - a JSON file, "neuralyarn-scene 1" (scenes/scene_json.h, docs/file_formats.md), that the add-on's Blender
//     builder (addon/scene_bpy.py) turns into a Blender scene for the fallbacks and the baselines.
// Coordinates are Cycles' standalone ones: the camera looks along +z with +y up (left-handed, x to the right).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "neuralyarn/geometry/ply.h"

namespace neuralyarn::scenes {

/* A colour in double precision. */
struct Rgb3 {
  double r = 0, g = 0, b = 0;
};

/* A perspective camera at `position` looking along +z, +y up; `fov` (radians) spans the image's shorter side. */
struct Camera {
  int width = 0, height = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double fov = 0;
};

/* The pixel filter (Cycles' film): a box one pixel wide is the standalone's default (D36). */
struct Film {
  std::string filter_type = "box";
  double filter_width = 1;
};

/* Cycles' bounce limits (integrator max_bounce, max_diffuse_bounce, ...), each in [0, 65535] (total >= 1). */
struct BounceLimits {
  int total = 1024, diffuse = 1024, glossy = 1024, transmission = 1024, transparent = 1024;
  /* Blender's defaults (12, 4, 4, 12) with the add-on's transparent limit (addon/scene_setup.py): what an
   * artist's scene renders with. */
  static BounceLimits blender_addon();
};

/* Every integrator setting the scenes depend on, stated even where it is the standalone's default, because
 * Blender's defaults differ (D36): a description leaves nothing to a renderer's defaults. */
struct Integrator {
  BounceLimits bounces;
  int min_bounce = 0; /* Russian roulette starts after this many bounces */
  double sample_clamp_direct = 0, sample_clamp_indirect = 0; /* 0: no clamping */
  double filter_glossy = 0, light_sampling_threshold = 0;
  bool use_adaptive_sampling = false;
  int seed = 0;
};

/* A uniform background. */
struct Background {
  double strength = 0;
  Rgb3 colour{1, 1, 1};
};

struct Light {
  enum class Kind { point, distant };
  Kind kind = Kind::point;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  /* point */
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ(); /* distant: the unit vector toward the light */
  double strength = 0; /* point: power, W; distant: irradiance on a plane facing the light, W/m^2 */
  double radius = 0;   /* point: the sphere's radius */
  double angle = 0;    /* distant: the disc's full angular diameter, radians */
  bool use_mis = false;          /* BSDF and camera rays hit the light (Cycles' Light default: no) */
  bool visible_to_camera = true; /* (with use_mis) camera rays see it */
};

/* What shades an object's curves. */
struct Material {
  enum class Kind {
    neural_yarn,    /* the aggregated model (model_path, or model_json embedded) */
    khungurn_fiber, /* explicit fibers (C_R, C_TT, beta_R, beta_TT, gamma_TT of a preset) */
    principled_hair_chiang, principled_hair_huang, /* baselines: direct colouring, colour */
    sheen,   /* baseline: Principled BSDF with sheen weight 1, colour */
    diffuse, /* a grey Lambertian, colour: the check that two renderers build the same scene */
    cloth_surface, /* the surface level (D44): stock closures weighted by the view angle (surface) */
  };
  Kind kind = Kind::diffuse;
  std::string model_path; /* neural_yarn: absolute; each writer makes it relative to its own file */
  std::string model_json; /* neural_yarn, optional: the model file's text, embedded */
  double C_R[3] = {0, 0, 0}, C_TT[3] = {0, 0, 0}, beta_R = 0, beta_TT = 0, gamma_TT = 0; /* radians */
  Rgb3 colour{0.5, 0.5, 0.5};
  /* cloth_surface: its closures, each weighted by a curve over x = kSurfaceFront cos theta_v on the front face
   * and kSurfaceBackStart + kSurfaceFront cos theta_v on the back one (model/surface_fit.h). */
  struct SurfaceClosure {
    std::string closure; /* "transparent", "diffuse", "translucent" or "ggx" */
    double alpha = 0;    /* ggx: Cycles' alpha (the Glossy node's roughness squared) */
    std::vector<std::array<double, 3>> weight; /* RGB samples evenly spaced over x in [0, 1] */
  };
  std::vector<SurfaceClosure> surface;
};

/* Curves with one material. */
struct CurveObject {
  std::string name, shader; /* shader: the material's name in the scene ("fiber", "yarn") */
  Material material;
  geometry::CurveSet curves;
};

/* A triangle mesh with one material (the surface level's cloth: its normal, by the winding, toward the face). */
struct MeshObject {
  std::string name, shader;
  Material material;
  std::vector<Eigen::Vector3f> vertices;
  std::vector<int> triangles; /* three vertex indices each */
};

struct Scene {
  std::string title;                          /* what the scene is, one line */
  std::string lighting, lighting_description; /* the light rig's name and description */
  Camera camera;
  Film film;
  Integrator integrator;
  Background background;
  std::vector<Light> lights;
  std::vector<CurveObject> objects;
  std::vector<MeshObject> meshes;
  size_t num_curve_keys() const;
  size_t num_curves() const;
};

/* Writes the scene in the format its path's extension names: ".xml" Cycles XML, ".json" the description.
 * Through a temporary file and a rename (a reader never sees half a scene); throws std::runtime_error naming
 * the path when it cannot be written or the extension is neither. */
void write_scene(const Scene &scene, const std::string &path);
/* Throws write_scene()'s message unless the path's extension names a format. */
void check_scene_extension(const std::string &path);

/* A model path as a scene file at `scene_path` refers to it: relative to the scene's directory (Cycles' XML
 * reader and the Blender builder resolve it so: scene and models move together). */
std::string model_path_for(const std::string &model_path, const std::string &scene_path);

}  // namespace neuralyarn::scenes
