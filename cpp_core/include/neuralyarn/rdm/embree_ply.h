// SPDX-License-Identifier: Apache-2.0
//
// An explicit, finite ply as Embree 3 round linear curves: the independent intersector the tests check
// PlyTracer against (P(T) from straight rays) and the benchmark races it against; YarnTracer's fibers. Each fiber is its helix
// tessellated into `segments_per_turn` chords per turn (at least one per ply radius of length), radius r.
#pragma once

#include <memory>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/kernel/platform.h"

struct RTCIntersectContext; /* Embree's; the header stays free of Embree */

namespace neuralyarn::rdm {

struct EmbreeHit {
  float t = 0.0f;
  int fiber = -1;
  ny::Vec3 normal;  /* geometric normal, unit, facing against the ray */
  ny::Vec3 tangent; /* unit direction of the hit segment (the fiber tangent, +x-ward) */
  bool entering = true; /* the ray enters the tube here (false: it leaves it, its origin was inside) */

  /* The tube's radial normal at the hit: Embree's normal at a joint of two segments is the joint sphere's,
   * so only its part normal to the tangent (the normal itself where that part vanishes). */
  ny::Vec3 radial_normal() const
  {
    const ny::Vec3 n = normal - tangent * ny::dot(normal, tangent);
    const float len = ny::length(n);
    return len > 1e-6f ? n * (1.0f / len) : normal;
  }
};

class EmbreePly {
 public:
  /* The fibers of `ply` over x in [x0, x1]. */
  EmbreePly(const geometry::Ply &ply, double x0, double x1, int segments_per_turn);
  /* Any fibers (every curve with the same number of points: the fiber of a segment is its curve).
   * `device_config` is Embree's: "threads=1" (the default, for timing one thread) limits every TBB arena
   * of the process while the device lives, so walks on several threads pass "". */
  explicit EmbreePly(const geometry::CurveSet &curves, const char *device_config = "threads=1");
  ~EmbreePly();
  EmbreePly(const EmbreePly &) = delete;
  EmbreePly &operator=(const EmbreePly &) = delete;

  /* Nearest fiber hit with t in (tnear, tfar); false if none. Hits on fiber `exclude` closer than
   * `exclude_distance` are skipped (the fiber a walk just left, as PlyTracer::trace does); with
   * `cull_exits`, so are hits where the ray leaves a tube (a renderer's backface culling: PlyTracer reports
   * entries only). */
  bool intersect(ny::Vec3 o, ny::Vec3 d, float tnear, float tfar, EmbreeHit *hit, int exclude = -1,
                 float exclude_distance = 0.0f, bool cull_exits = false) const;
  size_t num_segments() const { return segments_; }

 private:
  /* One Embree query with `ctx` (its filter, if any, decides which hits count). */
  bool nearest_hit(ny::Vec3 o, ny::Vec3 d, float tnear, float tfar, ::RTCIntersectContext *ctx, EmbreeHit *hit) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  size_t segments_ = 0;
  int segments_per_fiber_ = 0;
};

}  // namespace neuralyarn::rdm
