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
  const auto plies = j.find("plies");
  if (plies == j.end() || !plies->is_array() || plies->empty()) {
    throw fail("'plies' must be a non-empty list of coordinate lists");
  }
  PlyCurves out;
  size_t total = 0;
  for (size_t k = 0; k < plies->size(); k++) {
    const nlohmann::json &p = (*plies)[k];
    if (!p.is_array() || p.size() < 6 || p.size() % 3) {
      throw fail("ply " + std::to_string(k) + " needs x y z triples of at least two points, got " +
                 std::to_string(p.is_array() ? p.size() : 0) + " numbers");
    }
    total += p.size() / 3;
    if (total > kMaxPlyPoints) {
      throw fail("more than " + std::to_string(kMaxPlyPoints) + " points");
    }
    std::vector<Eigen::Vector3d> pts(p.size() / 3);
    for (size_t i = 0; i < p.size(); i++) {
      if (!p[i].is_number() || !std::isfinite(p[i].get<double>())) {
        throw fail("ply " + std::to_string(k) + " point " + std::to_string(i / 3) + " is not a finite number");
      }
      pts[i / 3][int(i % 3)] = scale * p[i].get<double>();
    }
    out.plies.push_back(std::move(pts));
  }
  return out;
}

}  // namespace neuralyarn::scenes
