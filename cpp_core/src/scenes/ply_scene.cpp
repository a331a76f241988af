// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/scenes/ply_scene.h"

#include <cmath>
#include <stdexcept>

#include <filesystem>

#include <Eigen/Geometry>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/geometry/sweep.h"
#include "neuralyarn/io.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/model/surface_fit.h"
#include "neuralyarn/scenes/ply_curves.h"
#include "neuralyarn/units.h"

namespace neuralyarn::scenes {

namespace {
/* Distant lights: the sun's angular diameter (small, yet not a delta: BSDF samples can hit it and MIS
 * works, which matters for the 1-degree R lobes of silk and cotton), and its strength: irradiance pi on a
 * plane facing it, so a white Lambertian surface facing the light renders 1 (the key-rim key light gives
 * 2000 W / (4 pi 9.4^2) = 1.8). */
constexpr double kSunAngleDeg = 2.0, kSunStrength = kPi;

/* The distant light `deg` degrees from the view direction (from the ply toward the camera, -z), tilted
 * toward the unit axis (ax, ay, 0) perpendicular to it. */
RigLight sun(double deg, double ax, double ay)
{
  const double t = deg * kDeg;
  RigLight l;
  l.kind = RigLight::Kind::distant;
  l.x = std::sin(t) * ax, l.y = std::sin(t) * ay, l.z = -std::cos(t);
  l.strength = kSunStrength;
  l.size = kSunAngleDeg;
  return l;
}

RigLight sphere(double x, double y, double z)
{
  RigLight l;
  l.kind = RigLight::Kind::point;
  l.x = x, l.y = y, l.z = z;
  l.strength = 2000.0;
  l.size = 1.0;
  return l;
}

}

const std::vector<LightRig> &light_rigs()
{
  static const std::vector<LightRig> rigs = {
      {"key-rim", "two sphere lights (2000 W, radius 1): in front above left (reflection) and behind (transmission)",
       false, {sphere(-3.0, 4.0, -8.0), sphere(2.0, -1.0, 9.0)}},
      {"environment", "no lights, a uniform white background of strength 1", true, {}},
      {"front", "distant light 10 deg from the view direction, toward +y", false, {sun(10.0, 0.0, 1.0)}},
      {"grazing", "distant light 80 deg from the view, in the plane normal to the ply (toward +y)", false,
       {sun(80.0, 0.0, 1.0)}},
      {"back", "distant light 170 deg from the view, in the plane normal to the ply (behind it, toward +y)", false,
       {sun(170.0, 0.0, 1.0)}},
      {"axis", "distant light 80 deg from the view, along the ply axis (toward +x)", false, {sun(80.0, 1.0, 0.0)}},
  };
  return rigs;
}

std::string light_rig_names()
{
  std::string names;
  for (const LightRig &r : light_rigs()) {
    names += (names.empty() ? "" : ", ") + r.name;
  }
  return names;
}

LightRig find_light_rig(const std::string &name)
{
  for (const LightRig &r : light_rigs()) {
    if (r.name == name) {
      return r;
    }
  }
  /* sun-DEG-normal, sun-DEG-axis */
  const size_t a = name.find('-'), b = name.rfind('-');
  if (name.compare(0, 4, "sun-") == 0 && b > a + 1) {
    const std::string deg_text = name.substr(a + 1, b - a - 1), plane = name.substr(b + 1);
    size_t used = 0;
    double deg = -1.0;
    try {
      deg = std::stod(deg_text, &used);
    }
    catch (const std::exception &) {
      used = 0;
    }
    if (used == deg_text.size() && deg >= 0.0 && deg <= 180.0 && (plane == "normal" || plane == "axis")) {
      const bool normal = plane == "normal";
      return {name,
              "distant light " + deg_text + " deg from the view, " +
                  (normal ? "in the plane normal to the ply (toward +y)" : "along the ply axis (toward +x)"),
              false,
              {sun(deg, normal ? 0.0 : 1.0, normal ? 1.0 : 0.0)}};
    }
  }
  throw std::runtime_error("unknown light rig '" + name + "' (known: " + light_rig_names() +
                           ", sun-DEG-normal, sun-DEG-axis with DEG in [0, 180])");
}

const std::vector<Baseline> &baselines()
{
  static const std::vector<Baseline> all = {
      {"chiang", "Principled Hair, Chiang (2016), direct colouring"},
      {"huang", "Principled Hair, Huang (2022), direct colouring, round cross-section"},
      {"sheen", "Principled BSDF, sheen weight 1"},
  };
  return all;
}

namespace {

/* What the scene's options allow alone (before any file is read): the light rig they name. */
LightRig check_options(const FiberPreset &preset, const PlySceneOptions &o)
{
  validate(preset);
  if (o.white_furnace && o.lights != "key-rim" && o.lights != "environment") {
    throw std::runtime_error("the white furnace is the 'environment' light rig; it cannot use lights '" + o.lights +
                             "'");
  }
  LightRig rig = find_light_rig(o.white_furnace ? std::string("environment") : o.lights);
  if (o.max_bounce < 1 || o.max_bounce > 65535) {
    /* Cycles keeps bounce counters in 16 bits. */
    throw std::runtime_error("max_bounce must be in [1, 65535], got " + std::to_string(o.max_bounce));
  }
  if (!(o.camera_distance > 1.0 && o.camera_distance <= 1e4)) {
    throw std::runtime_error("camera_distance must be in (1, 1e4] ply radii (outside the ply), got " +
                             std::to_string(o.camera_distance));
  }
  if (!(o.unit_scale >= 1e-6 && o.unit_scale <= 1e6)) {
    throw std::runtime_error("unit_scale must be in [1e-6, 1e6], got " + std::to_string(o.unit_scale));
  }
  if (o.layers < 1 || o.layers > 256) {
    throw std::runtime_error("layers must be in [1, 256], got " + std::to_string(o.layers));
  }
  for (const double pitch : {o.layer_pitch_y, o.layer_pitch_z}) {
    if (!(pitch >= 2.0 && pitch <= 100.0)) {
      throw std::runtime_error("a layer pitch must be in [2, 100] ply radii (below 2 the plies overlap), got " +
                               std::to_string(pitch));
    }
  }
  if (o.layers == 1 && (o.layer_pitch_y != kLayerPitch || o.layer_pitch_z != kLayerPitch)) {
    throw std::runtime_error("a layer pitch needs layers (2 or more): one layer is the single ply");
  }
  if (!(o.light_scale > 0.0 && o.light_scale <= 1e6)) {
    throw std::runtime_error("light_scale must be in (0, 1e6], got " + std::to_string(o.light_scale));
  }
  if (!o.plies.empty() && o.layers != 1) {
    throw std::runtime_error("a scene of ply curves has its own geometry: no layers");
  }
  return rig;
}

/* What the level and the baseline allow, given the plies file (if any). */
void check_level_and_baseline(const PlySceneOptions &o, const PlyCurves &curves_in, bool yarn_level)
{
  if (o.level == "surface") {
    if (o.surface.empty() || curves_in.surface_triangles.empty() || !o.model.empty() || !o.baseline.empty() || o.diffuse) {
      throw std::runtime_error("the surface level draws the cloth surface of a plies file (--plies with \"surface\") "
                               "with a surface BSDF (--surface), nothing else");
    }
    return;
  }
  if (!o.surface.empty()) {
    throw std::runtime_error("--surface is the surface level's BSDF: give it with --level surface");
  }
  if (!yarn_level && o.level != "plies") {
    throw std::runtime_error("level must be plies, yarns or surface, got '" + o.level + "'");
  }
  if (yarn_level && (curves_in.yarns.empty() || (o.model.empty() && o.baseline.empty() && !o.diffuse))) {
    throw std::runtime_error("the yarn level draws the yarns of a plies file (--plies with \"yarns\") with a model "
                             "or a baseline");
  }
  if (o.diffuse && (!o.model.empty() || !o.baseline.empty())) {
    throw std::runtime_error("the diffuse check replaces the model: give --model, --baseline or --diffuse, not two");
  }
  if (o.white_furnace && o.artist_bounces) {
    throw std::runtime_error("the white furnace runs every path to its end; it cannot use the artist's bounce limits");
  }
  if (!o.baseline.empty()) {
    bool known = false;
    std::string names;
    for (const Baseline &b : baselines()) {
      known |= b.name == o.baseline;
      names += (names.empty() ? "" : ", ") + b.name;
    }
    if (!known) {
      throw std::runtime_error("unknown baseline '" + o.baseline + "' (known: " + names + ")");
    }
    if (!o.model.empty()) {
      throw std::runtime_error("a baseline replaces the model: give --model or --baseline, not both");
    }
    for (double c : o.baseline_colour) {
      if (!(c >= 0.0 && c <= 1.0)) {
        throw std::runtime_error("baseline colour components must be in [0, 1], got " + std::to_string(c));
      }
    }
  }
}

/* The model, refused here with the loader's message if it is broken or describes another fiber or level; its
 * absolute path. */
std::string checked_model_path(const FiberPreset &preset, const PlySceneOptions &o, const PlyCurves &curves_in,
                               bool yarn_level)
{
  const model::YarnModel m = model::load_model(o.model);
  if (preset_to_json(m.preset) != preset_to_json(preset)) {
    throw std::runtime_error("model '" + o.model + "' was trained for preset '" + m.preset.name +
                             "' with other parameters than '" + preset.name + "'");
  }
  if (m.calibration.empty()) {
    throw std::runtime_error("model '" + o.model + "' is a version 1 file without a kernel array; re-bake it");
  }
  /* A model describes one level: a ply's on yarn curves (or the reverse) would render silently wrong. */
  if (m.structure.is_yarn() != yarn_level) {
    throw std::runtime_error("model '" + o.model + "' is a " + (m.structure.is_yarn() ? "yarn" : "ply") +
                             "-level model; the scene draws " + (yarn_level ? "yarns" : "plies"));
  }
  if (yarn_level && (m.structure.plies != curves_in.plies_per_yarn ||
                     std::abs(m.structure.ply_twist - curves_in.ply_twist) > 1e-6)) {
    throw std::runtime_error("model '" + o.model + "' was baked for " + std::to_string(m.structure.plies) +
                             " plies at ply twist " + std::to_string(m.structure.ply_twist) + "; the yarns have " +
                             std::to_string(curves_in.plies_per_yarn) + " at " + std::to_string(curves_in.ply_twist));
  }
  return std::filesystem::absolute(o.model).lexically_normal().string();
}

/* Where a straight ply lies in the close-up or in the sheets of a layered scene. */
struct Placement {
  double y, z, turn_deg;
};

/* The plies: one on the x axis, or `layers` sheets of plies side by side (along y, enough to fill the
 * frame's height at the camera's distance) stacked away from the camera (along +z), by default touching but
 * for a small gap (the pitches). */
std::vector<Placement> ply_placements(const PlySceneOptions &o)
{
  std::vector<Placement> plies;
  if (o.layers == 1) {
    plies.push_back({0.0, 0.0, o.ply_rotation_deg});
  }
  else {
    const int half = int(std::ceil(o.camera_distance * std::tan(0.5 * kCloseupCameraFov) / o.layer_pitch_y)) + 1;
    for (int k = 0; k < o.layers; k++) {
      for (int j = -half; j <= half; j++) {
        /* Each explicit ply another orientation of the cross-section (the golden angle apart). */
        plies.push_back({o.layer_pitch_y * j, o.layer_pitch_z * k, o.ply_rotation_deg + 137.5 * double(plies.size())});
      }
    }
  }
  return plies;
}

/* The explicit version's fibers: swept along the plies file's centrelines, or the straight plies'. */
geometry::CurveSet explicit_fibers(const FiberPreset &preset, const PlySceneOptions &o, const PlyCurves &curves_in,
                                   const std::vector<Placement> &plies)
{
  const double s = o.unit_scale;
  geometry::CurveSet curves;
  if (!curves_in.plies.empty()) {
    /* Each ply's fibers swept along its centreline, each ply another orientation of the cross-section. */
    const geometry::PlyParams pp{preset.N, preset.rho, preset.alpha, 1.0};
    /* Refuse before any work a scene that cannot be rendered here. */
    int64_t keys = 0;
    for (const auto &ply : curves_in.plies) {
      keys += int64_t(preset.N) *
              (geometry::sweep_segments(pp, geometry::centreline_length(ply), ply.size(), o.segments_per_turn) + 1);
    }
    if (keys > kMaxExplicitKeys) {
      throw std::runtime_error("explicit fibers of these plies would be " + std::to_string(keys) +
                               " curve keys, more than " + std::to_string(kMaxExplicitKeys) +
                               " (tens of GB in Cycles): fewer plies, or fewer --segments-per-turn");
    }
    const geometry::PlyCrossSection cs = geometry::pack_cross_section(pp, o.packing_seed);
    curves.offsets = {0};
    for (size_t k = 0; k < curves_in.plies.size(); k++) {
      geometry::PlyCrossSection turned = cs;
      const Eigen::Rotation2Dd turn((o.ply_rotation_deg + 137.5 * double(k)) * kDeg);
      for (Eigen::Vector2d &c : turned.centers) {
        c = turn * c;
      }
      const geometry::CurveSet one =
          geometry::sweep_fibers(geometry::Ply(pp, turned), curves_in.plies[k], o.segments_per_turn);
      for (int c = 0; c < one.num_curves(); c++) {
        curves.radii.push_back(one.radii[size_t(c)] * float(s));
        curves.offsets.push_back(curves.offsets.back() + (one.offsets[size_t(c) + 1] - one.offsets[size_t(c)]));
      }
      for (const Eigen::Vector3f &p : one.points) {
        curves.points.push_back(float(s) * p);
      }
    }
  }
  else {
    const geometry::PlyParams pp{preset.N, preset.rho, preset.alpha, 1.0};
    const geometry::Ply ply(pp, geometry::pack_cross_section(pp, o.packing_seed));
    const geometry::CurveSet one =
        geometry::export_fibers(ply, -0.5 * o.ply_length, 0.5 * o.ply_length, o.segments_per_turn);
    curves.offsets = {0};
    for (const Placement &pl : plies) {
      /* The fibers turned about the ply axis: another orientation of the same random cross-section. */
      const Eigen::Matrix3f turn =
          Eigen::AngleAxisf(float(pl.turn_deg * kDeg), Eigen::Vector3f::UnitX()).toRotationMatrix();
      const Eigen::Vector3f at(0.0f, float(pl.y), float(pl.z));
      for (const Eigen::Vector3f &p : one.points) {
        curves.points.push_back(float(s) * (turn * p + at));
      }
      for (int c = 0; c < one.num_curves(); c++) {
        curves.radii.push_back(one.radii[size_t(c)] * float(s));
        curves.offsets.push_back(curves.offsets.back() + (one.offsets[size_t(c) + 1] - one.offsets[size_t(c)]));
      }
    }
  }
  return curves;
}

/* Camera, film and integrator. */
void set_up(Scene &scene, const PlySceneOptions &o, const BounceLimits &limits)
{
  const double s = o.unit_scale;
  /* The camera camera_distance radii in front of the ply (-z), looking at the origin along +z. */
  scene.camera.width = o.width, scene.camera.height = o.height;
  scene.camera.position = Eigen::Vector3d(0.0, 0.0, -o.camera_distance * s);
  scene.camera.fov = kCloseupCameraFov;
  scene.film.filter_type = "box", scene.film.filter_width = kPixelFilterWidth;
  /* Bounce limits: a limit cuts the long random walks inside bright plies and biases the explicit-fiber
   * references dark (cotton most; docs/benchmarks.md), so the limit is high and Cycles' Russian roulette
   * (from the first bounce) ends paths without bias. The white furnace must not lose energy at all: no
   * roulette there (min_bounce = max_bounce), every path runs until it leaves (an albedo-1 ply lets light out
   * after tens of events). Transparent bounces (the aggregated model's T lobe) and diffuse ones get the same
   * limit. */
  Integrator &in = scene.integrator;
  in.bounces = limits;
  in.min_bounce = o.white_furnace ? limits.total : 0;
  /* No sample clamping: Cycles clamps indirect light at 10 by default, which biases the explicit-fiber
   * references low, the more the more lights there are (the clamp acts on each light sample divided by its
   * selection probability), and makes the image depend on the number of lights. */
  in.sample_clamp_direct = in.sample_clamp_indirect = 0.0;
  in.filter_glossy = in.light_sampling_threshold = 0.0;
  /* No adaptive sampling (Cycles' default stops converged pixels after 64 samples): N samples are N samples
   * in every pixel, so renders at equal samples compare and references converge everywhere. */
  in.use_adaptive_sampling = false;
  in.seed = o.seed;
}

/* The rig's background and lights. */
void light(Scene &scene, const PlySceneOptions &o, const LightRig &rig)
{
  const double s = o.unit_scale;
  scene.lighting = rig.name, scene.lighting_description = rig.description;
  scene.background.strength = rig.environment ? 1.0 : 0.0;
  scene.background.colour = {1.0, 1.0, 1.0};
  for (const RigLight &l : rig.lights) {
    Light light;
    if (l.kind == RigLight::Kind::point) {
      /* Scaled scenes scale the power with the area. */
      const double ls = s * o.light_scale;
      light.kind = Light::Kind::point;
      light.position = Eigen::Vector3d(l.x, l.y, l.z) * ls;
      light.strength = l.strength * ls * ls;
      light.radius = l.size * ls;
      /* Light sampling only, as the standalone's scenes always rendered them: no MIS, so neither BSDF nor
       * camera rays hit the sphere (Blender's lights have MIS on and show the sphere to the camera). */
      light.use_mis = false;
      light.visible_to_camera = false;
    }
    else {
      /* Camera rays do not see a distant light: the back rig's disc (radiance ~3300) is in the frame, above
       * the ply, and would swamp every whole-frame measurement. */
      light.kind = Light::Kind::distant;
      light.direction = Eigen::Vector3d(l.x, l.y, l.z);
      light.strength = l.strength;
      light.angle = l.size * kDeg;
      /* MIS: BSDF samples may hit the 2-degree disc (silk's and cotton's 1-degree R lobes need it). */
      light.use_mis = true;
      light.visible_to_camera = false;
    }
    scene.lights.push_back(light);
  }
}

/* One thick curve per ply (or yarn), shaded by the neural model, a baseline or the grey diffuse check. */
CurveObject aggregated(const PlySceneOptions &o, const std::string &model_path, const PlyCurves &curves_in,
                       bool yarn_level, const std::vector<Placement> &plies)
{
  CurveObject obj;
  obj.name = yarn_level ? "yarns" : "plies";
  obj.shader = "yarn";
  Material &m = obj.material;
  if (o.diffuse) {
    m.kind = Material::Kind::diffuse;
    m.colour = {0.5, 0.5, 0.5};
  }
  else if (!o.baseline.empty()) {
    m.kind = o.baseline == "chiang"  ? Material::Kind::principled_hair_chiang
             : o.baseline == "huang" ? Material::Kind::principled_hair_huang
                                     : Material::Kind::sheen;
    m.colour = {o.baseline_colour[0], o.baseline_colour[1], o.baseline_colour[2]};
  }
  else {
    m.kind = Material::Kind::neural_yarn;
    m.model_path = model_path;
    if (o.embed_model) {
      try {
        m.model_json = read_file(o.model);
      }
      catch (const std::runtime_error &e) {
        throw std::runtime_error("model '" + o.model + "': " + e.what());
      }
    }
  }
  /* The ply curves as given, or each straight ply as 17 keys along x: the bounding cylinder the maps were
   * gathered on. */
  std::vector<std::vector<Eigen::Vector3d>> axes = yarn_level ? curves_in.yarns : curves_in.plies;
  const double s = o.unit_scale, radius = s * (yarn_level ? curves_in.yarn_radius : 1.0);
  if (axes.empty()) {
    const int keys = 17;
    for (const Placement &pl : plies) {
      std::vector<Eigen::Vector3d> axis;
      for (int k = 0; k < keys; k++) {
        axis.emplace_back(-0.5 * o.ply_length + o.ply_length * k / (keys - 1), pl.y, pl.z);
      }
      axes.push_back(std::move(axis));
    }
  }
  obj.curves = curve_set(axes, radius, s);
  return obj;
}

/* The plies file's cloth surface with the surface level's stock closures (D44). */
MeshObject cloth_surface(const PlySceneOptions &o, const PlyCurves &curves_in)
{
  MeshObject obj;
  obj.name = "cloth";
  obj.shader = "surface";
  obj.material = cloth_surface_material(model::load_surface(o.surface));
  for (const Eigen::Vector3d &v : curves_in.surface_vertices) {
    obj.vertices.push_back((o.unit_scale * v).cast<float>());
  }
  obj.triangles = curves_in.surface_triangles;
  return obj;
}

/* The fibers with the Khungurn fiber closure. */
CurveObject fibers(const FiberPreset &preset, geometry::CurveSet curves)
{
  CurveObject obj;
  obj.name = "fibers";
  obj.shader = "fiber";
  Material &m = obj.material;
  m.kind = Material::Kind::khungurn_fiber;
  for (int c = 0; c < 3; c++) {
    m.C_R[c] = preset.C_R[c], m.C_TT[c] = preset.C_TT[c];
  }
  m.beta_R = preset.beta_R_deg * kDeg, m.beta_TT = preset.beta_TT_deg * kDeg, m.gamma_TT = preset.gamma_TT_deg * kDeg;
  obj.curves = std::move(curves);
  return obj;
}

}  // namespace

Material cloth_surface_material(const model::SurfaceBsdf &bsdf)
{
  Material m;
  m.kind = Material::Kind::cloth_surface;
  /* 256 samples over both faces: 125 per face between cos theta_v = 0 and 1, finer than the view bins. */
  constexpr int kSamples = 256;
  m.surface.push_back({"transparent", 0.0, model::surface_curve(bsdf, -1, kSamples)});
  for (size_t k = 0; k < bsdf.lobes.size(); k++) {
    m.surface.push_back({bsdf.lobes[k].closure, bsdf.lobes[k].alpha, model::surface_curve(bsdf, int(k), kSamples)});
  }
  return m;
}

Scene ply_scene(const FiberPreset &preset, const PlySceneOptions &o)
{
  const LightRig rig = check_options(preset, o);
  /* Read (and refuse a bad file) before anything else. */
  const PlyCurves curves_in = o.plies.empty() ? PlyCurves{} : read_ply_curves(o.plies);
  const bool yarn_level = o.level == "yarns";
  check_level_and_baseline(o, curves_in, yarn_level);
  const BounceLimits limits = o.artist_bounces ? BounceLimits::blender_addon()
                                               : BounceLimits{o.max_bounce, o.max_bounce, o.max_bounce,
                                                              o.max_bounce, o.max_bounce};
  /* Aggregated geometry: one thick curve per ply, shaded by the neural model, a baseline or the diffuse check. */
  const bool aggregated_version = !o.model.empty() || !o.baseline.empty() || o.diffuse;
  const std::string model_path = o.model.empty() ? std::string() : checked_model_path(preset, o, curves_in, yarn_level);
  Scene scene;
  scene.title = preset.name + (o.empty                ? std::string(" ply scene without objects (the renderer's own memory)")
                               : o.diffuse            ? std::string(" ply, aggregated (one thick curve, grey diffuse)")
                               : !o.baseline.empty()  ? " ply, aggregated (one thick curve, baseline " + o.baseline + ")"
                               : o.level == "surface" ? std::string(" cloth, surface level (a mesh, stock closures)")
                               : aggregated_version   ? std::string(" ply, aggregated (one thick curve, neural_yarn_bsdf)")
                                                      : std::string(" ply, explicit fibers (khungurn_fiber_bsdf)"));
  set_up(scene, o, limits);
  if (o.empty) { /* a black background (Background's default), nothing else */
    return scene;
  }
  light(scene, o, rig);
  const std::vector<Placement> plies = ply_placements(o);
  if (o.level == "surface") {
    scene.meshes.push_back(cloth_surface(o, curves_in));
  }
  else if (aggregated_version) {
    scene.objects.push_back(aggregated(o, model_path, curves_in, yarn_level, plies));
  }
  else {
    /* Only the explicit version packs fibers. */
    scene.objects.push_back(fibers(preset, explicit_fibers(preset, o, curves_in, plies)));
  }
  return scene;
}

void write_ply_scene(const FiberPreset &preset, const PlySceneOptions &o, const std::string &path)
{
  write_scene(ply_scene(preset, o), path);
}

}  // namespace neuralyarn::scenes
