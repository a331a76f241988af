// SPDX-License-Identifier: Apache-2.0
//
// The fibers of one slab x0 <= x <= x1 of a fiber bundle as straight round tubes about chords, found by a
// uniform 2D grid over the slab's (y, z) cross-section (docs/decisions.md D7, D66). PlyTracer keeps one such
// slab of its screw-symmetric ply; YarnGridTracer a row of them along an explicit K-ply yarn.
//
// Each chord is entered in every cell its projected tube (a capsule around the projected chord, of radius
// r / cos(tilt)) overlaps. A query walks the cells under the ray's (y, z) projection in order (2D DDA) and
// stops once the nearest hit lies before the current cell's exit. A cell's tubes are stored structure-of-arrays
// in blocks of kTubeLanes, so that one block's tube tests run as vector instructions without a branch per tube;
// every lane does what one scalar test does, in the same float operations, so a block and a single tube give
// the same distance to the bit.
//
// Hits are tube *entries* (a ray whose origin lies inside a tube passes through it), within the slab's x range
// (beyond it the fiber is the neighbouring slab's chord). The fiber a path just scattered on is ignored for
// `exclude_distance` after it leaves, so that the kink between two chords never produces a spurious event.
#pragma once

#include <cstdint>
#include <vector>

#include "neuralyarn/kernel/platform.h"

namespace neuralyarn::rdm {

/* Tubes a query tests at once (one SSE vector; eight lanes of AVX measured no faster, docs/benchmarks.md).
 * Each lane computes what one scalar tube test would, in the same float operations. */
inline constexpr int kTubeLanes = 4;

/* One fiber's straight piece in a slab: the tube about the line a + s axis, a on the slab's anchor plane (a.x = x0,
 * the near face, unless the grid says otherwise; exactly: the grid's blocks do not store it). */
struct Chord {
  ny::Vec3 a;    /* chord start (x = x0 of its slab, in float)          */
  ny::Vec3 axis; /* unit chord direction, +x-ward                        */
  int fiber = -1;
  /* The projected chord from (y0, z0) to (y1, z1) and its capsule's radius, in double: which cells it
   * touches. */
  double y0 = 0.0, z0 = 0.0, y1 = 0.0, z1 = 0.0, capsule_radius = 0.0;
};

/* A chord from p0 (on x = x0) to p1 (on x = x1) of a fiber of radius r, its capsule slightly inflated so that
 * float rounding in the DDA can never lose a candidate. `scale` is the bundle's size (R), for that margin. */
Chord make_chord(int fiber, const double p0[3], const double p1[3], double r, double scale);

/* The largest distance from the x axis that the chord's tube of radius r reaches within x0 <= x <= x1 (its
 * x-slices are ellipses stretched along the projected chord, which can poke a hair beyond the fibers' envelope),
 * sampled on circles about the axis at `steps` + 1 positions from x0 - 2r to x1 + 2r, 64 points each: within
 * r (1 - cos(pi / 64)) ~ 1.2e-3 r of the true maximum for steps of at most a few r. */
double clipped_tube_reach(const Chord &c, double r, double x0, double x1, int steps);

/* p's offset from the line a + s axis (axis unit), normal to it: a hit's outward normal once normalised. */
inline ny::Vec3 chord_radial(ny::Vec3 a, ny::Vec3 axis, ny::Vec3 p)
{
  const ny::Vec3 w = p - a;
  return w - axis * ny::dot(w, axis);
}

/* Entry distance of the ray o + t d (d unit) into the round tube of radius sqrt(r2) about the chord's line;
 * +inf if it misses, moves away from the axis or starts inside. */
float tube_entry(const Chord &c, ny::Vec3 o, ny::Vec3 d, float r2);

class TubeGrid {
 public:
  TubeGrid() = default;
  /* The chords of the slab [x0, x1] over the cross-section [-bound, bound]^2, cells of side about `cell`. Every chord
   * starts on the plane x = anchor (x0 unless given: a slab's near face); hits count within [x0, x1]. */
  TubeGrid(const std::vector<Chord> &chords, float r, float bound, float x0, float x1, double cell);
  TubeGrid(const std::vector<Chord> &chords, float r, float bound, float x0, float x1, double cell, float anchor);

  /* The nearest tube entry at t in [0, t_end] along (o, d); fiber `exclude` is skipped where the trace,
   * `travelled` before this query, is closer than `exclude_distance`. Returns t_end (or +inf) and *fiber = -1
   * if none. */
  float nearest(ny::Vec3 o, ny::Vec3 d, float t_end, int exclude, float travelled, float exclude_distance,
                int *fiber) const;

  int resolution() const { return n_; }
  /* Number of (chord, cell) entries: the grid's size and the mean candidate count. */
  size_t entries() const { return entries_; }

 private:
  float r_ = 0.0f, bound_ = 1.0f, x0_ = 0.0f, x1_ = 1.0f, anchor_ = 0.0f;
  /* Grid over [-bound, bound]^2 in (y, z): cell (iy, iz) holds blocks_[start_[c] .. start_[c + 1]). */
  int n_ = 1;
  float cell_ = 1.0f, inv_cell_ = 1.0f;
  std::vector<uint32_t> start_;
  size_t entries_ = 0;
  /* Lanes past a cell's last tube have fiber -1. A chord starts on the slab's near face, so its start's x is x0
   * for every lane and not stored: 96 bytes, two cache lines at this alignment. */
  struct alignas(8 * kTubeLanes) TubeBlock {
    float ay[kTubeLanes], az[kTubeLanes]; /* chord start (x = x0) */
    float ux[kTubeLanes], uy[kTubeLanes], uz[kTubeLanes]; /* unit chord direction */
    int32_t fiber[kTubeLanes];
  };
  std::vector<TubeBlock> blocks_;
};

}  // namespace neuralyarn::rdm
