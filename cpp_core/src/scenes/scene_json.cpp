// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/scenes/scene_json.h"

#include <charconv>
#include <cstdlib>

#include "neuralyarn/model/surface_fit.h" /* kSurfaceFront, kSurfaceBackStart */

namespace neuralyarn::scenes {

namespace {

using nlohmann::json;

json vec(const Eigen::Vector3d &v)
{
  return json::array({v.x(), v.y(), v.z()});
}

json rgb(const Rgb3 &c)
{
  return json::array({c.r, c.g, c.b});
}

/* A float as the double of its shortest decimal form: the file says 0.1, not 0.10000000149011612. */
double shortest(float f)
{
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf) - 1, f);
  *r.ptr = '\0';
  return std::strtod(buf, nullptr);
}

const char *material_type(Material::Kind k)
{
  switch (k) {
    case Material::Kind::neural_yarn: return "neural_yarn";
    case Material::Kind::khungurn_fiber: return "khungurn_fiber";
    case Material::Kind::principled_hair_chiang: return "principled_hair_chiang";
    case Material::Kind::principled_hair_huang: return "principled_hair_huang";
    case Material::Kind::sheen: return "sheen";
    case Material::Kind::diffuse: return "diffuse";
    case Material::Kind::cloth_surface: return "cloth_surface";
  }
  return "";
}

}  // namespace

json material_json(const Material &m, const std::string &scene_path)
{
  json j = {{"type", material_type(m.kind)}};
  switch (m.kind) {
    case Material::Kind::neural_yarn:
      j["model"] = model_path_for(m.model_path, scene_path);
      if (!m.model_json.empty()) {
        j["model_json"] = m.model_json;
      }
      break;
    case Material::Kind::khungurn_fiber:
      j["C_R"] = {m.C_R[0], m.C_R[1], m.C_R[2]};
      j["C_TT"] = {m.C_TT[0], m.C_TT[1], m.C_TT[2]};
      j["beta_R"] = m.beta_R, j["beta_TT"] = m.beta_TT, j["gamma_TT"] = m.gamma_TT;
      break;
    case Material::Kind::cloth_surface: {
      /* The closures' weight curves as the XML's rgb_curves hold them, read at x = front |N.I| + back_start
       * Backfacing. */
      j["front"] = model::kSurfaceFront, j["back_start"] = model::kSurfaceBackStart;
      json closures = json::array();
      for (const Material::SurfaceClosure &c : m.surface) {
        json w = json::array();
        for (const auto &v : c.weight) {
          w.push_back({v[0], v[1], v[2]});
        }
        closures.push_back({{"closure", c.closure}, {"alpha", c.alpha}, {"weight", std::move(w)}});
      }
      j["closures"] = std::move(closures);
      break;
    }
    default:
      j["colour"] = rgb(m.colour);
  }
  return j;
}

namespace {

json mesh(const MeshObject &o)
{
  json v = json::array(), t = json::array();
  for (const Eigen::Vector3f &q : o.vertices) {
    v.push_back(shortest(q.x())), v.push_back(shortest(q.y())), v.push_back(shortest(q.z()));
  }
  for (int i : o.triangles) {
    t.push_back(i);
  }
  return {{"vertices", std::move(v)}, {"triangles", std::move(t)}};
}

json curves(const geometry::CurveSet &c)
{
  json keys = json::array(), radii = json::array(), points = json::array();
  for (int k = 0; k < c.num_curves(); k++) {
    keys.push_back(c.offsets[size_t(k) + 1] - c.offsets[size_t(k)]);
    radii.push_back(shortest(c.radii[size_t(k)]));
  }
  auto &p = points.get_ref<json::array_t &>();
  p.reserve(3 * c.points.size());
  for (const Eigen::Vector3f &q : c.points) {
    p.emplace_back(shortest(q.x())), p.emplace_back(shortest(q.y())), p.emplace_back(shortest(q.z()));
  }
  return {{"keys", std::move(keys)}, {"radius", std::move(radii)}, {"points", std::move(points)}};
}

}  // namespace

json scene_json(const Scene &scene, const std::string &scene_path)
{
  const Integrator &in = scene.integrator;
  json lights = json::array();
  for (const Light &l : scene.lights) {
    json j;
    if (l.kind == Light::Kind::point) {
      j = {{"type", "point"}, {"position", vec(l.position)}, {"strength", l.strength}, {"radius", l.radius}};
    }
    else {
      j = {{"type", "distant"}, {"direction", vec(l.direction)}, {"strength", l.strength}, {"angle", l.angle}};
    }
    j["use_mis"] = l.use_mis;
    j["visible_to_camera"] = l.visible_to_camera;
    lights.push_back(std::move(j));
  }
  json objects = json::array();
  for (const CurveObject &o : scene.objects) {
    objects.push_back({{"name", o.name}, {"material", material_json(o.material, scene_path)}, {"curves", curves(o.curves)}});
  }
  json meshes = json::array();
  for (const MeshObject &o : scene.meshes) {
    meshes.push_back({{"name", o.name}, {"material", material_json(o.material, scene_path)}, {"mesh", mesh(o)}});
  }
  json j = {
      {"format", scene.meshes.empty() ? kSceneFormat : kSceneFormatMeshes},
      {"title", scene.title},
      {"lighting", {{"name", scene.lighting}, {"description", scene.lighting_description}}},
      {"camera",
       {{"width", scene.camera.width}, {"height", scene.camera.height}, {"position", vec(scene.camera.position)},
        {"fov", scene.camera.fov}}},
      {"film", {{"filter_type", scene.film.filter_type}, {"filter_width", scene.film.filter_width}}},
      {"integrator",
       {{"max_bounce", in.bounces.total}, {"max_diffuse_bounce", in.bounces.diffuse},
        {"max_glossy_bounce", in.bounces.glossy}, {"max_transmission_bounce", in.bounces.transmission},
        {"transparent_max_bounce", in.bounces.transparent}, {"min_bounce", in.min_bounce},
        {"sample_clamp_direct", in.sample_clamp_direct}, {"sample_clamp_indirect", in.sample_clamp_indirect},
        {"filter_glossy", in.filter_glossy}, {"light_sampling_threshold", in.light_sampling_threshold},
        {"use_adaptive_sampling", in.use_adaptive_sampling}, {"seed", in.seed}}},
      {"background", {{"strength", scene.background.strength}, {"colour", rgb(scene.background.colour)}}},
      {"lights", std::move(lights)},
      {"objects", std::move(objects)},
  };
  if (!scene.meshes.empty()) { /* a reader of version 1 would drop them silently: version 2 says they are there */
    j["meshes"] = std::move(meshes);
  }
  return j;
}

}  // namespace neuralyarn::scenes
