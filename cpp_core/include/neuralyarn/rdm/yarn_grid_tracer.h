// SPDX-License-Identifier: Apache-2.0
//
// Ray queries against an explicit K-ply yarn (geometry/yarn.h) for the yarn level's random walks, by slabs
// of chord tubes (docs/decisions.md D66). A plied yarn is not invariant under any screw motion (the fibers turn
// about their ply at another rate than the plies about the yarn), so PlyTracer's one canonical slab does not
// apply; instead the yarn over |x| <= half_length is cut into slabs short enough that each fiber is its chord
// within `sagitta` fiber radii, each slab with its own TubeGrid (rdm/tube_grid.h). The chords of a fiber meet
// on the slab faces (their ends are the fiber's points on the planes x = const), so the tubes are continuous.
// Paths enter over `entry_length` about x = 0; a path that leaves through an end rather than the envelope is
// counted by the gather (GatherStats::paths_past_ends).
//
// It answers the queries YarnTracer (Embree's round curves over the same fibers) answers, faster (by how much:
// docs/benchmarks.md); YarnTracer stays as the independent intersector the tests compare it with.
#pragma once

#include <memory>
#include <vector>

#include "neuralyarn/geometry/yarn.h"
#include "neuralyarn/rdm/fiber_medium.h"
#include "neuralyarn/rdm/tube_grid.h"

namespace neuralyarn::rdm {

/* The yarn's grid cells are twice PlyTracer's: its slabs, hundreds of them, do not stay in the cache as the
 * ply's one slab does, and larger cells (fewer, fuller blocks) cost fewer misses than the tube tests they add
 * (docs/benchmarks.md, D66). */
inline TracerOptions yarn_tracer_options()
{
  TracerOptions o;
  o.cell_size = 4.0;
  return o;
}

/* Whether the yarn's fibers advance along its axis everywhere (x grows with each fiber's parameter, sampled over
 * a period of the plies), as slabs need: each fiber crosses each face once. Plies twisted so steeply that the
 * fibers on their outer side turn back along the axis (ply twist ~8 for 2 plies) do not; gather_yarn walks those
 * through Embree's curves. */
bool fibers_advance_along_axis(const geometry::Yarn &yarn);

/* The slabs of one yarn (shared by the tracer and its mirror image). */
class YarnSlabs {
 public:
  /* The yarn's fibers over |x| <= half_length; fiber k N + i is fiber i of ply k. Throws ParameterError for a
   * half length that is not positive and finite, std::runtime_error for fibers that do not advance along the
   * axis (fibers_advance_along_axis). */
  YarnSlabs(const geometry::Yarn &yarn, double half_length, const TracerOptions &options = yarn_tracer_options());

  float bound_radius() const { return bound_; }
  float envelope_radius() const { return R_; }
  float fiber_radius() const { return r_; }
  double half_length() const { return half_; }
  int num_slabs() const { return int(grids_.size()); }

  /* Entry distance of the ray into fiber `fiber`'s tube of slab `slab`, ignoring the slab's x range; +inf if
   * it misses or starts inside. (Brute-force reference for tests.) */
  float intersect_chord(int slab, int fiber, ny::Vec3 o, ny::Vec3 d) const;
  /* Distance of point p from the line of fiber `fiber`'s chord in slab `slab`. (For tests.) */
  float distance_from_chord(int slab, int fiber, ny::Vec3 p) const;
  float slab_face(int j) const { return planes_[size_t(j)]; }

  /* As PlyTracer::trace, in the yarn's coordinates. */
  bool trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const;

 private:
  float R_ = 1.0f, bound_ = 1.0f, r_ = 0.0f, L_ = 1.0f;
  double half_ = 0.0;
  std::vector<float> planes_;         /* x of the slab faces: slab j is [planes_[j], planes_[j + 1]] */
  std::vector<TubeGrid> grids_;       /* per slab */
  int fibers_ = 0;
  std::vector<ny::Vec3> chord_a_, chord_axis_; /* [slab][fiber]: a hit's normal and axis */
};

class YarnGridTracer final : public FiberMedium {
 public:
  /* The slabs' yarn, or its mirror image (turned by pi about the y axis: the gather's mirror, D9). */
  YarnGridTracer(std::shared_ptr<const YarnSlabs> slabs, double entry_length, bool mirrored)
      : slabs_(std::move(slabs)), entry_(entry_length), mirrored_(mirrored)
  {
  }

  float bound_radius() const override { return slabs_->bound_radius(); }
  float envelope_radius() const override { return slabs_->envelope_radius(); }
  float fiber_radius() const override { return slabs_->fiber_radius(); }
  double entry_length() const override { return entry_; }
  double half_length() const override { return slabs_->half_length(); }
  bool trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const override;
  void leave_fiber(const TubeHit &hit, ny::Vec3 d, SlabRay *ray) const override;

 private:
  std::shared_ptr<const YarnSlabs> slabs_;
  double entry_ = 0.0;
  bool mirrored_ = false;
};

}  // namespace neuralyarn::rdm
