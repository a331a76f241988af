// SPDX-License-Identifier: Apache-2.0
//
// A K-ply yarn: K plies of radius R_ply twisted around the yarn axis (+x), each ply filled with the
// fibers of a packed cross-section (ply.h) and twisted about its own centerline.
//
// Handedness (textile convention, docs/conventions.md): fibers are Z-twisted inside each ply
// (right-handed about the ply tangent, as in ply.h), and the plies are S-twisted around the yarn axis
// (left-handed), which is what keeps a real plied yarn balanced. Ply k's centerline is
//     c_k(x) = (x, d cos(phi_k - w x), d sin(phi_k - w x)),  phi_k = 2 pi k / K,  w = pi alpha_yarn / R_yarn,
// with R_yarn = d + R_ply. The centre distance d is the smallest for which neighbouring ply tubes do not
// intersect in 3D (found numerically: tilted plies touching in the axis-normal plane would overlap).
//
// A fiber with cross-section polar offset (rho_i, psi_i) sits at
//     c_k(x) + rho_i (cos(psi) e_r + sin(psi) e_b),   psi = psi_i + (pi alpha_ply / R_ply + tau) s(x),
// where e_r is the radial direction from the yarn axis to c_k(x) (exactly normal to the helix), e_b =
// t_k × e_r, s(x) the arc length of the centerline and tau = w / (1 + d^2 w^2) the helix's torsion. The
// radial frame turns against a parallel-transported (rotation-minimising) frame at exactly +tau per unit
// arc length, so adding tau makes alpha_ply the fiber twist *relative to the ply itself*. Without it the
// plying would change the fibers' twist by tau, which is not small against the presets' fiber twist rates
// (tests/cpp/test_ply_geometry.cpp checks the transport).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/geometry/yarn_structure.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/units.h"

namespace neuralyarn::geometry {

struct YarnParams {
  int K = 3;                /* plies (1 = a single ply on the axis)         */
  PlyParams ply;            /* N, rho, alpha (fiber twist), R (ply radius)  */
  double alpha_yarn = 0.0;  /* ply twist factor 2 R_yarn dn / dl, >= 0 (S); no effect when K = 1 */
};

class Yarn {
 public:
  /* Packs one cross-section per ply (seeds seed, seed + 1, ...). Throws ParameterError naming the
   * parameter for bad input. */
  Yarn(const YarnParams &params, uint64_t seed);

  const YarnParams &params() const { return params_; }
  int num_plies() const { return params_.K; }
  const PlyCrossSection &cross_section(int ply) const { return sections_[ply]; }
  /* Distance of the ply centerlines from the yarn axis. */
  double ply_distance() const { return d_; }
  double yarn_radius() const { return d_ + params_.ply.R; }
  /* The length over which the yarn's structure is sampled (surface_twist, the yarn level's entry region): one
   * pitch of the plies about the axis, 2 R_yarn / alpha_yarn, or two yarn radii where they do not turn. */
  double sampling_length() const { return w_ > 0.0 ? 2.0 * kPi / w_ : 2.0 * yarn_radius(); }

  Eigen::Vector3d ply_center(int ply, double x) const;
  Eigen::Vector3d ply_tangent(int ply, double x) const;
  Eigen::Vector3d fiber_point(int ply, int fiber, double x) const;
  /* The point at polar offset (rho, psi0) of ply `ply`'s cross-section at x, turned with the fibers as
   * fiber_point() turns a fiber there: rho = R_ply is the ply's surface, which its outermost fibers follow. */
  Eigen::Vector3d ply_point(int ply, double rho, double psi0, double x) const;

 private:
  YarnParams params_;
  std::vector<PlyCrossSection> sections_;
  double d_ = 0.0, w_ = 0.0, arc_per_x_ = 1.0;
  double fiber_rate_ = 0.0; /* d psi / ds = pi alpha_ply / R_ply + tau */
};

/* A preset's fibers in the plies of `structure`, in ply radii (R_ply = 1): what the yarn level walks through. */
YarnParams yarn_params(const FiberPreset &preset, const YarnStructure &structure);

/* The surface fibers' twist of a yarn as a twist factor: the mean over the outermost fibers (centres
 * within three fiber radii of the yarn's envelope, sampled along one pitch) of tan(tilt) / pi, tilt the
 * angle of the fiber tangent from the yarn axis about the outward radial direction, positive for a
 * Z twist. For K = 1 it is the ply's alpha (times the outer fibers' rho / R_ply). */
double surface_twist(const Yarn &yarn);

/* Where single scattering meets a K-ply yarn (docs/decisions.md D51): a point of a ply's surface that a ray along
 * the yarn's outward radial leaves without entering another ply, with the direction a fiber takes there (T) and
 * the ply surface's normal (N), both in the yarn frame of the envelope point above it (x = yarn axis, z =
 * outward radial, y = z x x: kernel/frames.h). `turn` is N's angle about x from z, `weight` its projected area
 * N.z at normal incidence. */
struct SurfaceFrame {
  Eigen::Vector3d T, N;
  double turn = 0.0, weight = 0.0;
};

/* `nodes` frames of the visible ply surface (samples of one ply's circumference, which by the screw symmetry
 * stand for every ply and every x), at the midpoints of `nodes` equal quantiles of the central `spread` share
 * of the weighted distribution of turns. One ply (K = 1): every point is visible, the frames turn about x
 * alone. Throws ParameterError for nodes < 1 or spread outside (0, 1]. */
std::vector<SurfaceFrame> visible_surface_frames(const Yarn &yarn, int nodes, double spread);

/* Smallest 3D distance between the centerlines of neighbouring plies at centre distance d (by the screw
 * symmetry of the yarn, a 1-D minimisation). Exposed for tests. */
double neighbour_ply_distance(int K, double d, double R_ply, double alpha_yarn);

/* d: the smallest ply centre distance at which neighbouring ply tubes of radius R_ply do not intersect in
 * 3D (0 for K = 1). The neighbour distance grows with d, so it is bisected from the bound of plies touching
 * in the axis-normal plane, R_ply / sin(pi / K), upwards. The add-on's geometry/ply.py repeats it in Python
 * (its tests compare the two through `neuralyarn yarn-geometry`). Throws ParameterError for bad input. */
double ply_center_distance(int K, double R_ply, double alpha_yarn);

/* All fibers of all plies as polylines from x0 to x1. */
CurveSet export_fibers(const Yarn &yarn, double x0, double x1, int segments_per_turn = 32);

}  // namespace neuralyarn::geometry
