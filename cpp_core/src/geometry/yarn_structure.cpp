// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/geometry/yarn_structure.h"

#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "neuralyarn/presets.h" /* ParameterError */

namespace neuralyarn::geometry {

void validate(const YarnStructure &s)
{
  if (s.plies < 2 || s.plies > 16) {
    throw ParameterError("plies", "plies per yarn must be an integer in [2, 16], got " + std::to_string(s.plies));
  }
  if (!(std::isfinite(s.ply_twist) && s.ply_twist >= 0.0 && s.ply_twist <= 8.0)) {
    throw ParameterError("ply_twist", "the ply twist must be a finite number in [0, 8]");
  }
  if (!(std::isfinite(s.surface_alpha) && std::abs(s.surface_alpha) <= 100.0)) {
    throw ParameterError("surface_alpha", "the surface twist must be a finite number within +-100");
  }
}

nlohmann::json structure_to_json(const YarnStructure &s)
{
  return {{"level", "yarn"}, {"plies", s.plies}, {"ply_twist", s.ply_twist}, {"surface_alpha", s.surface_alpha}};
}

YarnStructure structure_from_json(const nlohmann::json &j)
{
  if (!j.is_object() || j.value("level", "") != "yarn") {
    throw ParameterError("structure", "'structure' must be an object with \"level\": \"yarn\"");
  }
  auto number = [&](const char *key) {
    if (!j.contains(key) || !j[key].is_number() || !std::isfinite(j[key].get<double>())) {
      throw ParameterError(key, std::string("'structure' needs a finite '") + key + "'");
    }
    return j[key].get<double>();
  };
  YarnStructure s;
  const double plies = number("plies");
  if (plies != std::floor(plies) || std::abs(plies) > 1e6) {
    throw ParameterError("plies", "'structure' 'plies' must be an integer");
  }
  s.plies = int(plies);
  s.ply_twist = number("ply_twist");
  s.surface_alpha = number("surface_alpha");
  validate(s);
  return s;
}

}  // namespace neuralyarn::geometry
