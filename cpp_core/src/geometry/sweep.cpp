// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/geometry/sweep.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include "neuralyarn/presets.h"

namespace neuralyarn::geometry {

int64_t sweep_segments(const PlyParams &params, double length, size_t points, int segments_per_turn)
{
  /* Helix pitch 2R / alpha (ply.h); an untwisted ply is sampled once per ply radius. */
  const double turns = params.alpha > 0.0 ? length / (2.0 * params.R / params.alpha) : 0.0;
  return std::max({int64_t(std::ceil(turns * segments_per_turn)), int64_t(std::ceil(length / params.R)),
                   int64_t(points) - 1});
}

std::vector<Eigen::Vector3d> catmull_rom_polyline(const std::vector<Eigen::Vector3d> &keys, int per_span)
{
  const size_t n = keys.size();
  if (n < 3 || per_span < 2) {
    return keys;
  }
  std::vector<Eigen::Vector3d> out;
  out.reserve((n - 1) * size_t(per_span) + 1);
  for (size_t k = 0; k + 1 < n; k++) {
    const Eigen::Vector3d &p0 = keys[k ? k - 1 : 0], &p1 = keys[k], &p2 = keys[k + 1];
    const Eigen::Vector3d &p3 = keys[std::min(k + 2, n - 1)];
    /* Uniform Catmull-Rom: 0.5 (2 p1 + (p2 - p0) t + (2 p0 - 5 p1 + 4 p2 - p3) t^2 + (3 p1 - p0 - 3 p2 + p3) t^3). */
    const Eigen::Vector3d c1 = 0.5 * (p2 - p0), c2 = 0.5 * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3),
                          c3 = 0.5 * (3.0 * p1 - p0 - 3.0 * p2 + p3);
    for (int j = 0; j < per_span; j++) {
      const double t = double(j) / per_span;
      out.push_back(p1 + t * (c1 + t * (c2 + t * c3)));
    }
  }
  out.push_back(keys.back());
  return out;
}

namespace {
std::vector<double> arc_lengths(const std::vector<Eigen::Vector3d> &p)
{
  std::vector<double> s(p.size(), 0.0);
  for (size_t k = 1; k < p.size(); k++) {
    s[k] = s[k - 1] + (p[k] - p[k - 1]).norm();
  }
  return s;
}
}  // namespace

double centreline_length(const std::vector<Eigen::Vector3d> &keys)
{
  return keys.empty() ? 0.0 : arc_lengths(catmull_rom_polyline(keys)).back();
}

CurveSet sweep_fibers(const Ply &ply, const std::vector<Eigen::Vector3d> &keys, int segments_per_turn)
{
  if (keys.size() < 2) {
    throw ParameterError("centreline", "a ply centreline needs at least two points, got " + std::to_string(keys.size()));
  }
  if (segments_per_turn < 3) {
    throw ParameterError("segments_per_turn", "segments_per_turn must be >= 3, got " + std::to_string(segments_per_turn));
  }
  for (size_t k = 0; k < keys.size(); k++) {
    if (!keys[k].allFinite()) {
      throw ParameterError("centreline", "ply centreline point " + std::to_string(k) + " is not finite");
    }
  }
  const std::vector<Eigen::Vector3d> centreline = catmull_rom_polyline(keys);
  const std::vector<double> s = arc_lengths(centreline);
  const double length = s.back(), R = ply.params().R;
  if (!(length > 1e-9 * R)) {
    throw ParameterError("centreline", "the ply centreline has no length");
  }
  const int segments = int(sweep_segments(ply.params(), length, keys.size(), segments_per_turn));
  /* Even arc-length samples of the curve. */
  std::vector<Eigen::Vector3d> C(size_t(segments) + 1);
  size_t k = 0;
  for (int j = 0; j <= segments; j++) {
    const double sj = length * j / segments;
    while (k + 2 < s.size() && s[k + 1] < sj) {
      k++;
    }
    const double span = s[k + 1] - s[k];
    const double t = span > 0.0 ? std::clamp((sj - s[k]) / span, 0.0, 1.0) : 0.0;
    C[size_t(j)] = (1.0 - t) * centreline[k] + t * centreline[k + 1];
  }
  std::vector<Eigen::Vector3d> T(C.size());
  for (size_t j = 0; j < C.size(); j++) {
    const Eigen::Vector3d d = C[std::min(j + 1, C.size() - 1)] - C[j ? j - 1 : 0];
    T[j] = d.normalized();
  }
  /* Rotation-minimising frame by double reflection. */
  std::vector<Eigen::Vector3d> N(C.size());
  const Eigen::Vector3d e = std::abs(T[0].y()) < 0.9 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
  N[0] = (e - e.dot(T[0]) * T[0]).normalized();
  for (size_t j = 0; j + 1 < C.size(); j++) {
    const Eigen::Vector3d v1 = C[j + 1] - C[j];
    const double c1 = v1.squaredNorm();
    const Eigen::Vector3d rL = c1 > 0.0 ? Eigen::Vector3d(N[j] - (2.0 / c1) * v1.dot(N[j]) * v1) : N[j];
    const Eigen::Vector3d tL = c1 > 0.0 ? Eigen::Vector3d(T[j] - (2.0 / c1) * v1.dot(T[j]) * v1) : T[j];
    const Eigen::Vector3d v2 = T[j + 1] - tL;
    const double c2 = v2.squaredNorm();
    const Eigen::Vector3d n = c2 > 0.0 ? Eigen::Vector3d(rL - (2.0 / c2) * v2.dot(rL) * v2) : rL;
    /* Re-orthogonalise against rounding over long plies. */
    N[j + 1] = (n - n.dot(T[j + 1]) * T[j + 1]).normalized();
  }
  const double w = ply.twist_rate();
  const std::vector<Eigen::Vector2d> &centres = ply.cross_section().centers;
  CurveSet out;
  out.points.reserve(centres.size() * C.size());
  for (const Eigen::Vector2d &c : centres) {
    out.offsets.push_back(int(out.points.size()));
    for (size_t j = 0; j < C.size(); j++) {
      const double a = w * length * double(j) / segments, ca = std::cos(a), sa = std::sin(a);
      const Eigen::Vector3d B = T[j].cross(N[j]);
      out.points.push_back(
          (C[j] + (c.x() * ca - c.y() * sa) * N[j] + (c.x() * sa + c.y() * ca) * B).cast<float>());
    }
    out.radii.push_back(float(ply.fiber_radius()));
  }
  out.offsets.push_back(int(out.points.size()));
  return out;
}

}  // namespace neuralyarn::geometry
