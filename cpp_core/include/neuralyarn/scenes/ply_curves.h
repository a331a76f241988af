// SPDX-License-Identifier: Apache-2.0
//
// Ply centrelines as a scene's geometry (a knitted garment, a woven patch): the file that the Python
// generators (scripts/garment.py) write and `neuralyarn cycles-scene --plies` reads, so that the explicit
// fibers and the aggregated plies of one scene come from the same curves (docs/file_formats.md):
//     {"format": "neuralyarn-plies 1", "ply_radius": R, "plies": [[x0, y0, z0, x1, y1, z1, ...], ...]}
// in any unit; read scaled to ply radius 1 (cycles-scene's unit). Optionally the yarns the plies were
// twisted from, for the yarn level (docs/decisions.md D27): "yarns" (their centrelines, same unit),
// "yarn_radius", "plies_per_yarn" and "ply_twist". Optionally, for the surface level (D44): "period" [px, py],
// the pattern's period along x and y of a flat patch in the plane z = 0 (what `neuralyarn surface` walks
// through), and "surface" {"vertices": [x, y, z, ...], "triangles": [i, j, k, ...]}, the cloth's mid-surface
// (what the surface level draws; its normal, by the triangles' winding, toward the cloth's face).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "neuralyarn/geometry/ply.h"

namespace neuralyarn::scenes {

struct PlyCurves {
  std::vector<std::vector<Eigen::Vector3d>> plies; /* centrelines, ply radius 1 */
  std::vector<std::vector<Eigen::Vector3d>> yarns; /* optional: the yarns' centrelines, same unit */
  double yarn_radius = 0.0;                        /* with yarns: in ply radii */
  int plies_per_yarn = 0;
  double ply_twist = 0.0;
  double period[2] = {0.0, 0.0};              /* optional: a flat patch's period, ply radii */
  std::vector<Eigen::Vector3d> surface_vertices; /* optional: the mid-surface, ply radii */
  std::vector<int> surface_triangles;            /* three vertex indices each */
  size_t num_points() const;
};

/* Throws std::runtime_error naming the file and what is wrong: not JSON, another format, a ply radius that
 * is not positive and finite, no plies, a ply with fewer than two points or a count not a multiple of three,
 * a non-finite coordinate, more than kMaxPlyPoints points in all; yarns without a yarn radius larger than the
 * ply's, an integer plies_per_yarn in [2, 16] and a finite ply twist >= 0, or with bad curves. */
constexpr size_t kMaxPlyPoints = 50'000'000;
PlyCurves read_ply_curves(const std::string &path);

/* Centrelines (the file's plies or yarns) as curves of one radius, every point times `scale`. */
geometry::CurveSet curve_set(const std::vector<std::vector<Eigen::Vector3d>> &lines, double radius, double scale = 1.0);

}  // namespace neuralyarn::scenes
