// SPDX-License-Identifier: Apache-2.0
//
// Explicit geometry of one ply: N fibers of radius r = R sqrt(rho / N) inside a ply of radius R, placed
// without overlap in the cross-section and twisted into helices (paper Sec. 2, Eq. 1).
//
// Frame (docs/conventions.md): the ply axis is +x; the cross-section is the (y, z) plane. A fiber whose
// centre sits at polar position (d, psi0) in the cross-section at x = 0 follows
//     p(x) = (x, d cos(psi0 + w x), d sin(psi0 + w x)),   w = pi alpha / R,
// a helix turning right-handed about +x (Z twist), pitch 2R / alpha. At the ply surface (d -> R) its
// tangent in the local yarn frame is (1, -pi alpha, 0) / sqrt(1 + pi^2 alpha^2): the surface-fiber frame
// of kernel/frames.h (tests/cpp/test_ply_geometry.cpp checks it on the generated fibers).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

namespace neuralyarn::geometry {

struct PlyParams {
  int N = 0;          /* fibers                       */
  double rho = 0.0;   /* fiber density N r^2 / R^2    */
  double alpha = 0.0; /* twist factor 2 R dn / dl     */
  double R = 1.0;     /* ply radius (scene units)     */
};

struct PackingStats {
  int iterations = 0;        /* relaxation sweeps until no pair overlapped */
  double min_distance = 0.0; /* smallest fiber-perpendicular centre distance of neighbours (>= 2 r; +inf if none) */
};

struct PlyCrossSection {
  double R = 1.0;                       /* ply radius   */
  double r = 0.0;                       /* fiber radius */
  std::vector<Eigen::Vector2d> centers; /* (y, z) at x = 0, |c| <= R - r, pairwise >= 2 r */
  PackingStats stats;
};

/* Places N non-overlapping fibers in the cross-section, reproducibly from `seed`: uniform random start
 * in the disk of radius R - r, then relaxation (overlapping pairs pushed apart, centres projected back
 * into the disk) until no two fibers overlap. Throws ParameterError naming the parameter when the
 * parameters are invalid or the density cannot be packed (tens of percent beyond what random packings
 * reach; rho = 0.5 with the presets' N is easy). */
PlyCrossSection pack_cross_section(const PlyParams &params, uint64_t seed);

/* The cross-section mirrored y -> -y. A ply built from it, with the same Z twist, is the original ply
 * rotated by pi about the z axis: its mirror image in the sense of the RDM's half-turn symmetry. */
PlyCrossSection mirrored(const PlyCrossSection &cross_section);

/* A ply's fibers as helices. */
class Ply {
 public:
  Ply(const PlyParams &params, PlyCrossSection cross_section);

  const PlyParams &params() const { return params_; }
  const PlyCrossSection &cross_section() const { return cs_; }
  int num_fibers() const { return int(cs_.centers.size()); }
  double fiber_radius() const { return cs_.r; }
  /* Twist rate w = pi alpha / R (radians per unit length). */
  double twist_rate() const { return twist_rate_; }
  /* Axial period 2R / alpha; +inf for alpha = 0 (then the ply is translation invariant). */
  double pitch() const;

  /* Centre of fiber i at axial position x, and its unit tangent there. */
  Eigen::Vector3d fiber_point(int i, double x) const;
  Eigen::Vector3d fiber_tangent(int i, double x) const;

 private:
  PlyParams params_;
  PlyCrossSection cs_;
  double twist_rate_ = 0.0;
};

/* Curves for renderers and the add-on: polylines with a constant radius each. */
struct CurveSet {
  std::vector<Eigen::Vector3f> points; /* all curves' points, concatenated                   */
  std::vector<int> offsets;            /* curve c has points [offsets[c], offsets[c + 1])     */
  std::vector<float> radii;            /* one radius per curve                                */
  int num_curves() const { return int(radii.size()); }
};

/* Samples curves point(c, x), c < num_curves, at segments + 1 evenly spaced x in [x0, x1], with radius(c).
 * The one tessellation routine behind every export_fibers. Throws ParameterError for an empty or
 * non-finite range. `turns` is the number of helix turns over [x0, x1] (the fastest twist involved);
 * the segment count is max(turns * segments_per_turn, (x1 - x0) / min_segment_length, 1). */
CurveSet tessellate_curves(int num_curves, const std::function<Eigen::Vector3d(int, double)> &point,
                           const std::function<float(int)> &radius, double x0, double x1, double turns,
                           int segments_per_turn, double min_segment_length);

/* The ply's fibers from x0 to x1 as polylines with `segments_per_turn` segments per helix turn (at least
 * one segment per ply radius of length, so that untwisted plies are also sampled). */
CurveSet export_fibers(const Ply &ply, double x0, double x1, int segments_per_turn = 32);

}  // namespace neuralyarn::geometry
