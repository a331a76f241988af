// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/scenes/ply_curves.h"

#include <cmath>
#include <fstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace neuralyarn::scenes {

size_t PlyCurves::num_points() const
{
  size_t n = 0;
  for (const auto &p : plies) {
    n += p.size();
  }
  return n;
}

PlyCurves read_ply_curves(const std::string &path)
{
  const auto fail = [&](const std::string &why) { return std::runtime_error("ply curves '" + path + "': " + why); };
  std::ifstream in(path);
  if (!in) {
    throw fail("cannot be read");
  }
  nlohmann::json j;
  try {
    in >> j;
  }
  catch (const nlohmann::json::exception &e) {
    throw fail(std::string("not JSON (") + e.what() + ")");
  }
  if (!j.is_object() || j.value("format", std::string()) != "neuralyarn-plies 1") {
    throw fail("not a \"neuralyarn-plies 1\" file");
  }
  const auto radius = j.find("ply_radius");
  if (radius == j.end() || !radius->is_number() || !(radius->get<double>() > 0.0) ||
      !std::isfinite(radius->get<double>()))
  {
    throw fail("'ply_radius' must be a positive number");
  }
  const double scale = 1.0 / radius->get<double>();
  size_t total = 0;
  /* The curves under `key` ("plies" or "yarns"), each named `what` in messages. */
  auto read_curves = [&](const char *key, const char *what) {
    const auto list = j.find(key);
    if (list == j.end() || !list->is_array() || list->empty()) {
      throw fail(std::string("'") + key + "' must be a non-empty list of coordinate lists");
    }
    std::vector<std::vector<Eigen::Vector3d>> curves;
    for (size_t k = 0; k < list->size(); k++) {
      const nlohmann::json &p = (*list)[k];
      if (!p.is_array() || p.size() < 6 || p.size() % 3) {
        throw fail(std::string(what) + " " + std::to_string(k) + " needs x y z triples of at least two points, got " +
                   std::to_string(p.is_array() ? p.size() : 0) + " numbers");
      }
      total += p.size() / 3;
      if (total > kMaxPlyPoints) {
        throw fail("more than " + std::to_string(kMaxPlyPoints) + " points");
      }
      std::vector<Eigen::Vector3d> pts(p.size() / 3);
      for (size_t i = 0; i < p.size(); i++) {
        if (!p[i].is_number() || !std::isfinite(p[i].get<double>())) {
          throw fail(std::string(what) + " " + std::to_string(k) + " point " + std::to_string(i / 3) +
                     " is not a finite number");
        }
        pts[i / 3][int(i % 3)] = scale * p[i].get<double>();
      }
      curves.push_back(std::move(pts));
    }
    return curves;
  };
  PlyCurves out;
  out.plies = read_curves("plies", "ply");
  if (j.contains("yarns")) {
    out.yarns = read_curves("yarns", "yarn");
    const nlohmann::json yr = j.value("yarn_radius", nlohmann::json()), k = j.value("plies_per_yarn", nlohmann::json()),
                         tw = j.value("ply_twist", nlohmann::json());
    if (!yr.is_number() || !std::isfinite(yr.get<double>()) || !(yr.get<double>() * scale > 1.0)) {
      throw fail("'yarn_radius' must be a number larger than the ply radius");
    }
    if (!k.is_number_integer() || k.get<int>() < 2 || k.get<int>() > 16) {
      throw fail("'plies_per_yarn' must be an integer in [2, 16]");
    }
    if (!tw.is_number() || !std::isfinite(tw.get<double>()) || tw.get<double>() < 0.0) {
      throw fail("'ply_twist' must be a finite number >= 0");
    }
    out.yarn_radius = yr.get<double>() * scale;
    out.plies_per_yarn = k.get<int>();
    out.ply_twist = tw.get<double>();
  }
  if (j.contains("period")) {
    const nlohmann::json &p = j["period"];
    if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number() ||
        !(p[0].get<double>() > 0.0) || !(p[1].get<double>() > 0.0) || !std::isfinite(p[0].get<double>()) ||
        !std::isfinite(p[1].get<double>()))
    {
      throw fail("'period' must be two positive numbers (the pattern's period along x and y)");
    }
    out.period[0] = scale * p[0].get<double>(), out.period[1] = scale * p[1].get<double>();
  }
  if (j.contains("surface")) {
    const nlohmann::json &s = j["surface"];
    const auto v = s.is_object() ? s.find("vertices") : s.end(), t = s.is_object() ? s.find("triangles") : s.end();
    if (v == s.end() || t == s.end() || !v->is_array() || !t->is_array() || v->empty() || v->size() % 3 ||
        t->empty() || t->size() % 3)
    {
      throw fail("'surface' must hold 'vertices' (x y z triples) and 'triangles' (index triples)");
    }
    for (const nlohmann::json &x : *v) {
      if (!x.is_number() || !std::isfinite(x.get<double>())) {
        throw fail("a surface vertex is not a finite number");
      }
    }
    for (size_t i = 0; i < v->size(); i += 3) {
      out.surface_vertices.emplace_back(scale * (*v)[i].get<double>(), scale * (*v)[i + 1].get<double>(),
                                        scale * (*v)[i + 2].get<double>());
    }
    for (const nlohmann::json &x : *t) {
      if (!x.is_number_integer() || x.get<int64_t>() < 0 || x.get<int64_t>() >= int64_t(out.surface_vertices.size())) {
        throw fail("a surface triangle's index is not an integer in [0, " +
                   std::to_string(out.surface_vertices.size()) + ")");
      }
      out.surface_triangles.push_back(x.get<int>());
    }
  }
  return out;
}

geometry::CurveSet curve_set(const std::vector<std::vector<Eigen::Vector3d>> &lines, double radius, double scale)
{
  geometry::CurveSet c;
  c.offsets = {0};
  for (const auto &line : lines) {
    for (const Eigen::Vector3d &p : line) {
      c.points.push_back((scale * p).cast<float>());
    }
    c.offsets.push_back(int(c.points.size()));
    c.radii.push_back(float(radius));
  }
  return c;
}

}  // namespace neuralyarn::scenes
