// SPDX-License-Identifier: Apache-2.0
//
// Ray queries against an explicit K-ply yarn (geometry/yarn.h) for the yarn level's random walks
// (docs/decisions.md D27). A plied yarn is not invariant under any screw motion (the fibers turn about
// their ply at another rate than the plies about the yarn), so PlyTracer's one-slab trick does not apply:
// the yarn is built explicitly over |x| <= half_length as Embree round linear curves, and paths enter over
// one pitch in its middle. A path that leaves through an end rather than the envelope is counted
// (GatherStats::paths_past_ends); the half length is chosen so that they are negligible.
#pragma once

#include <memory>

#include "neuralyarn/geometry/yarn.h"
#include "neuralyarn/rdm/embree_ply.h"
#include "neuralyarn/rdm/fiber_medium.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::rdm {

/* Margin of the explicit yarn beyond the entry region, in yarn radii. */
constexpr double kYarnEndMargin = 16.0;

class YarnTracer final : public FiberMedium {
 public:
  /* The yarn's fibers over |x| <= half_length; `mirrored`: the yarn turned by pi about the y axis (the
   * gather's mirror image, D9). Paths enter over `entry_length` about x = 0. */
  YarnTracer(const geometry::Yarn &yarn, double entry_length, double half_length, bool mirrored,
             int segments_per_turn = 128);

  float bound_radius() const override { return bound_; }
  float envelope_radius() const override { return R_; }
  float fiber_radius() const override { return r_; }
  double entry_length() const override { return entry_; }
  double half_length() const override { return half_; }
  bool trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const override;
  void leave_fiber(const TubeHit &hit, ny::Vec3 d, SlabRay *ray) const override;
  size_t num_segments() const { return curves_->num_segments(); }

 private:
  std::unique_ptr<EmbreePly> curves_;
  float R_ = 1.0f, bound_ = 1.0f, r_ = 0.0f;
  double entry_ = 0.0, half_ = 0.0;
};

/* Which intersector a yarn-level gather walks through: the slabs of chord tubes (YarnGridTracer, the default)
 * or Embree's round curves (YarnTracer: the reference it is checked and timed against). A yarn whose fibers turn
 * back along its axis (rdm::fibers_advance_along_axis) is walked through Embree's whichever is asked for; the maps'
 * `intersector` says which. */
enum class YarnIntersector { kGrid, kEmbree };

/* Gathers the maps of a yarn of `structure.plies` plies of the preset's fibers at ply twist
 * `structure.ply_twist` (the yarn level). The maps' structure records the yarn and its surface twist.
 * Throws ParameterError for a one-ply yarn (plies and yarns coincide: gather the ply) or bad parameters. */
RdmMaps gather_yarn(const FiberPreset &preset, const geometry::YarnStructure &structure, const GatherOptions &options,
                    YarnIntersector intersector = YarnIntersector::kGrid);

}  // namespace neuralyarn::rdm
