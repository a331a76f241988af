// SPDX-License-Identifier: Apache-2.0
//
// A ply bent on a circle, for the random walks (decisions D75): the far field of a bent ply, which a straight ply's
// does not give. The straight ply's helices are laid around a circle of radius Rc (in ply radii) in its
// rotation-minimising frame, as geometry/sweep.h lays a ply along a knit or a yarn's helix: a fiber at (x, y, z) of
// the straight ply sits at x / Rc along the circle, y outward from it, -z across its plane (so the ply keeps its
// twist's handedness). Paths enter uniformly over the bent tube's area on the half of the circle away from the seam
// where its ends meet, and each exit is binned in the frame at its entry (x along the circle, z the tube's normal):
// what a far-field renderer evaluates at the point it hits. A ray leaving the tube stops there — it does not reach
// the circle's other side.
//
// Where around the tube a path enters matters (the bend's inner side is compressed, its outer side stretched): psi,
// the entry normal's angle about the tube from the circle's outward direction toward the circle's normal (outward x
// tangent), and a gather can be held to one sector of psi. Several cross-sections are several circles side by side.
//
// Two intersectors (decisions D76): wedges of the circle, each fiber the chord between its points on the wedge's two
// faces (planes through the circle's axis), within `sagitta` fiber radii of the fiber, each wedge a TubeGrid in the
// frame of its middle (as D66's slabs along a yarn) — the default; or Embree's round curves, the reference the wedges
// are checked against. With Rc = 0 the same cross-sections are walked straight through Embree's curves, so bent
// against straight isolates the bend.
#pragma once

#include <limits>
#include <memory>
#include <vector>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/embree_ply.h"
#include "neuralyarn/rdm/fiber_medium.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/rdm/tube_grid.h"

namespace neuralyarn::rdm {

/* The bend: the circle's radius in ply radii (0: straight; else at least kMinBendRadius) and the sector of psi the
 * paths enter in: sector k of `sectors` spans psi within pi / sectors of 2 pi k / sectors (k = 0: the outer side). */
struct Bend {
  double radius = 3.0;
  int sector = 0, sectors = 1;
};

/* What walks a bent ply (a straight one, radius 0, is always Embree's). */
enum class BentIntersector { kWedges, kEmbree };

/* The wedges' chords within 1 % of a fiber radius of their fibers, and grid cells of 4 fiber radii, as the yarn's
 * slabs' (hundreds of grids do not stay in the cache as PlyTracer's one does: D66). */
inline TracerOptions bent_tracer_options()
{
  TracerOptions o;
  o.cell_size = 4.0;
  return o;
}

/* Tighter circles fold the tube onto itself near the centre. */
constexpr double kMinBendRadius = 1.5;

/* Throws ParameterError for a radius in (0, kMinBendRadius) or not finite, or a sector outside [0, sectors). */
void validate(const Bend &bend);

class BentPlies final : public FiberMedium {
 public:
  /* One circle (or straight ply) per ply, all of radius 1 and the same fibers per ply. */
  BentPlies(const std::vector<geometry::Ply> &plies, const Bend &bend,
            BentIntersector intersector = BentIntersector::kWedges,
            const TracerOptions &options = bent_tracer_options());

  float bound_radius() const override { return bound_; }
  float envelope_radius() const override { return 1.0f; }
  float fiber_radius() const override { return r_; }
  double entry_length() const override { return entry_; }
  double half_length() const override { return 0.5 * length_ + bend_.radius + 2.0; }
  EntryFrame entry_frame(double u_around, double u_along) const override;
  bool trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const override;
  void leave_fiber(const TubeHit &hit, ny::Vec3 d, SlabRay *ray) const override;

  /* Where the point p of the straight ply (x along it from its start, y and z across) lies on ply k. */
  Eigen::Vector3d place(const Eigen::Vector3d &p, int k) const;
  /* Bound minus the distance from ply k's centreline: positive inside its tube (for the tests). */
  double inside(const Eigen::Vector3d &p, int k) const;
  /* Where the ray from o (in a tube, or on it going in) leaves that tube; +inf once it is found
   * still in past t_max (a walk asks only as far as the fiber it hits). */
  float exit_distance(ny::Vec3 o, ny::Vec3 d, float t_max = std::numeric_limits<float>::infinity()) const;
  /* psi of a point on or in ply k's tube (for the tests). */
  double psi(const Eigen::Vector3d &p, int k) const;
  /* Which ply's tube a point belongs to. */
  int ply_of(ny::Vec3 p) const;
  /* The wedges of each circle (0 for Embree's curves), and the largest distance of a fiber's midpoint in a wedge from
   * its chord, in fiber radii (for the tests). */
  int num_wedges() const { return int(mid_c_.size()); }
  double wedge_sagitta() const { return wedge_sagitta_; }
  /* The chords' largest distance from their fibers that the wedges were built for (0 for Embree's curves). */
  double chord_sagitta() const { return wedges_.empty() ? 0.0 : sagitta_; }
  const char *intersector_name() const { return wedges_.empty() ? "embree" : "wedges"; }

 private:
  Bend bend_;
  double spacing_ = 0.0, length_ = 0.0, entry_ = 0.0;
  float r_ = 0.0f, bound_ = 1.0f;
  int plies_ = 1;
  std::unique_ptr<EmbreePly> curves_;
  /* Wedge j spans angles [j, j + 1] delta about every circle's axis; its grid and chords live in the frame of its
   * middle (x along the circle, y outward from it, z = -z: right-handed). */
  double delta_ = 0.0, sagitta_ = 0.0, wedge_sagitta_ = 0.0;
  std::vector<float> face_c_, face_s_; /* cos, sin of face j's angle, j = 0 ... S (face S is face 0) */
  std::vector<float> mid_c_, mid_s_;   /* of wedge j's middle */
  struct Wedges {
    std::vector<TubeGrid> grids;
    std::vector<ny::Vec3> a, axis; /* [wedge][fiber], the wedge's frame */
  };
  std::vector<Wedges> wedges_; /* per circle; empty: Embree's curves */
  int fibers_ = 0;
  void build_wedges(const std::vector<geometry::Ply> &plies, const TracerOptions &options);
  /* The nearest fiber the ray enters within t_end (its hit point, normal and axis in *hit), by either intersector;
   * false if none. */
  bool nearest_fiber(ny::Vec3 o, ny::Vec3 d, float t_end, int exclude, float exclude_distance, TubeHit *hit,
                     int64_t *crossings) const;
  bool nearest_in_wedges(ny::Vec3 o, ny::Vec3 d, float t_end, int exclude, float exclude_distance, TubeHit *hit,
                         int64_t *crossings) const;
};

/* The maps of the preset's ply bent as `bend` says, over options.layouts cross-sections (packing seeds
 * options.packing_seed, +1, ...; the maps record them). A sector other than the outer or the inner side (2 k !=
 * sectors, 2 k != 0) is not its own image under the half turn about the normal that symmetrisation averages with
 * (the half turn takes psi to -psi): it needs options.symmetrize off, else ParameterError. */
RdmMaps gather_bent(const FiberPreset &preset, const Bend &bend, const GatherOptions &options,
                    BentIntersector intersector = BentIntersector::kWedges);

}  // namespace neuralyarn::rdm
