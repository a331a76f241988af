// SPDX-License-Identifier: Apache-2.0
//
// Ply centrelines as a scene's geometry (a knitted garment, a woven patch): the file that the Python
// generators (scripts/garment.py) write and `neuralyarn cycles-scene --plies` reads, so that the explicit
// fibers and the aggregated plies of one scene come from the same curves (docs/file_formats.md):
//     {"format": "neuralyarn-plies 1", "ply_radius": R, "plies": [[x0, y0, z0, x1, y1, z1, ...], ...]}
// in any unit; read scaled to ply radius 1 (cycles-scene's unit).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace neuralyarn::scenes {

struct PlyCurves {
  std::vector<std::vector<Eigen::Vector3d>> plies; /* centrelines, ply radius 1 */
  size_t num_points() const;
};

/* Throws std::runtime_error naming the file and what is wrong: not JSON, another format, a ply radius that
 * is not positive and finite, no plies, a ply with fewer than two points or a count not a multiple of three,
 * a non-finite coordinate, more than kMaxPlyPoints points in all. */
constexpr size_t kMaxPlyPoints = 50'000'000;
PlyCurves read_ply_curves(const std::string &path);

}  // namespace neuralyarn::scenes
