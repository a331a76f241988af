// SPDX-License-Identifier: Apache-2.0
//
// The level a set of maps or a model describes (docs/decisions.md D27), and its one JSON form, which the
// map file's header and the model file share.
#pragma once

#include <nlohmann/json_fwd.hpp>

namespace neuralyarn::geometry {

/* plies = 1 is one ply of the preset (the ply level), plies > 1 a yarn of that many plies at ply twist
 * alpha_yarn = ply_twist, rendered as one thick curve of the yarn's radius. surface_alpha is the twist the
 * aggregated BSDF's R lobe turns its surface-fiber frame by (kernel/frames.h atan(pi alpha)) for a yarn: its
 * surface_twist() (geometry/yarn.h), negative where the S-twisted plies more than undo the fibers' Z twist;
 * for a ply it is unused (the preset's alpha is: RdmMaps / YarnModel::surface_alpha()). */
struct YarnStructure {
  int plies = 1;
  double ply_twist = 0.0;
  double surface_alpha = 0.0;
  bool is_yarn() const { return plies > 1; }
};

/* A yarn's structure is valid with plies in [2, 16], a finite ply twist in [0, 8] and a finite surface twist
 * within +-100; otherwise ParameterError naming the value. */
void validate(const YarnStructure &structure);

/* {"level": "yarn", "plies", "ply_twist", "surface_alpha"} of a yarn, and back (validated; ParameterError
 * naming the key otherwise). */
nlohmann::json structure_to_json(const YarnStructure &structure);
YarnStructure structure_from_json(const nlohmann::json &object);

}  // namespace neuralyarn::geometry
