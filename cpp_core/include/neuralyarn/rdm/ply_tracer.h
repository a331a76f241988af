// SPDX-License-Identifier: Apache-2.0
//
// Ray queries against one infinitely long ply, exploiting its structure (docs/decisions.md, D7).
//
// A ply of helical fibers p_i(x) = (x, Rot(w x) c_i), w = pi alpha / R, is invariant under the screw
// motion S_X: (x, q) -> (x + X, Rot(w X) q) for every X. The tracer therefore stores only one short slab
// 0 <= x < L of it and keeps every ray in "canonical" slab coordinates: when a ray leaves the slab through
// x = L it re-enters at x = 0 with its (y, z) components rotated by Rot(-w L) (and symmetrically through
// x = 0), and the slab counter k records that the canonical frame sits at S_{k L} in the world. The ply is
// thereby exactly infinite: no energy is lost through ends, and a ray can wander any number of pitches.
//
// Inside the slab each fiber is the straight round tube of radius r around the chord from p_i(0) to
// p_i(L). L is chosen so that the chord deviates from the helix by at most `sagitta * r` (default 1 %):
// L = sqrt(8 sagitta r / kappa_max), kappa_max = w^2 R / (1 + w^2 R^2) the largest helix curvature. For
// alpha = 0 the chords are the exact fibers and L is arbitrary.
//
// Candidate fibers come from a uniform 2D grid over the slab's (y, z) cross-section (rdm/tube_grid.h).
//
// Rays enter and leave through the bounding cylinder of radius bound_radius() (R plus a hair: no tube
// reaches it). Hits are tube *entries*: a ray whose origin lies inside a tube (neighbouring helical tubes of a packed
// cross-section interpenetrate slightly in the outer layers, because the packing is done in the x = const
// slice) passes through that tube, and so does a path that scatters into the fiber it is on. The fiber a
// path just scattered on is ignored for `exclude_distance` after it leaves, so that the kink between two
// chords never produces a spurious second event.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/kernel/platform.h"
#include "neuralyarn/rdm/tube_grid.h"

namespace neuralyarn::rdm {

struct TracerOptions {
  double sagitta = 0.01;   /* largest chord deviation from the helix, in fiber radii      */
  double cell_size = 2.0;  /* grid cell side in fiber radii                               */
};

/* A ray in canonical slab coordinates plus the slab it is in. */
struct SlabRay {
  ny::Vec3 o;      /* origin, 0 <= o.x <= L */
  ny::Vec3 d;      /* unit direction        */
  int64_t slab = 0;
};

struct TubeHit {
  float t = 0.0f;   /* distance from the query origin (summed over slabs) */
  int fiber = -1;
  ny::Vec3 point;   /* canonical coordinates of the slab the ray ends in  */
  ny::Vec3 normal;  /* outward tube normal at the hit                     */
  ny::Vec3 axis;    /* unit chord direction (the fiber tangent, +x-ward)  */
};

/* Distance from o (inside the cylinder y^2 + z^2 = radius^2 about the x axis, or on it) along unit d to where
 * the ray leaves it: the far root, in a cancellation-free form; infinity for a ray along the axis. */
inline float cylinder_exit(ny::Vec3 o, ny::Vec3 d, float radius)
{
  const float a2 = d.y * d.y + d.z * d.z;
  if (!(a2 > 0.0f)) {
    return std::numeric_limits<float>::infinity();
  }
  const float b = o.y * d.y + o.z * d.z;
  const float c = o.y * o.y + o.z * o.z - radius * radius;
  const float disc = std::max(b * b - a2 * c, 0.0f);
  const float q = -b + std::copysign(std::sqrt(disc), -b);
  /* roots q / a2 and c / q; the far one is the larger. */
  const float t1 = q / a2;
  const float t2 = (q != 0.0f) ? c / q : 0.0f;
  return std::max(std::max(t1, t2), 0.0f);
}

class PlyTracer {
 public:
  PlyTracer(const geometry::Ply &ply, const TracerOptions &options = {});

  float ply_radius() const { return R_; }
  /* Radius of the bounding cylinder rays enter and leave through: R plus a hair (see the constructor). */
  float bound_radius() const { return bound_; }
  float fiber_radius() const { return r_; }
  float slab_length() const { return L_; }
  double twist_rate() const { return w_; }
  int num_fibers() const { return int(fibers_.size()); }
  /* Number of (fiber, cell) entries of the grid: its memory and the mean candidate count. */
  size_t grid_entries() const { return grid_.entries(); }
  int grid_resolution() const { return grid_.resolution(); }

  /* Traces `ray` (updated in place: on return it is at the hit or exit point, in the slab it ended in)
   * until it enters a tube or leaves the bounding cylinder of radius R. `exclude` is a fiber ignored for
   * the first `exclude_distance` of travel. Returns true on a hit (filled into *hit). */
  bool trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const;

  /* The ray a path continues with after scattering at `hit` into direction d: from the hit point, in
   * canonical coordinates of the slab it starts in. A direction into the fiber crosses it, as a renderer's
   * ray does (Cycles, Mitsuba: a ray leaving a curve's surface inward does not hit that curve): the tracer
   * reports tube entries only (docs/decisions.md D32). */
  void leave_fiber(const TubeHit &hit, ny::Vec3 d, SlabRay *ray) const;

  /* Entry distance of the ray (canonical coordinates) into tube `fiber` of the slab, ignoring the slab's
   * x range; +inf if it misses or starts inside. (Brute-force reference for tests.) */
  float intersect_fiber(int fiber, ny::Vec3 o, ny::Vec3 d) const { return tube_entry(fibers_[size_t(fiber)], o, d, r_ * r_); }

  /* Moves a ray whose origin has left [0, L] back into the slab (several slabs at once if needed). */
  void canonicalize(SlabRay *ray) const;

  /* World coordinates of a canonical point or direction in slab k. */
  ny::Vec3 to_world_point(ny::Vec3 p, int64_t slab) const;
  ny::Vec3 to_world_dir(ny::Vec3 d, int64_t slab) const;

 private:
  void rotate_yz(ny::Vec3 *v, float c, float s) const;
  /* The ray from its point at t_slab on a slab face into the neighbouring slab, re-entering the canonical
   * slab through the opposite face. */
  void cross_slab(SlabRay *ray, float t_slab) const;

  float R_ = 1.0f, bound_ = 1.0f, r_ = 0.0f, L_ = 1.0f;
  double w_ = 0.0;
  float rot_c_ = 1.0f, rot_s_ = 0.0f; /* Rot(w L) */
  std::vector<Chord> fibers_;         /* fiber i's chord over the slab */
  TubeGrid grid_;
};

}  // namespace neuralyarn::rdm
