// SPDX-License-Identifier: Apache-2.0
//
// What a random walk needs of the fibers it walks through (rdm/gather.h): ray queries that stop at tube
// entries (a path crosses the fiber it scattered into), and the cylinder paths enter and leave through.
// PlyTracer (one infinite ply, exact, D7) is the gather's own; for the yarn level (docs/decisions.md D27) a
// finite explicit K-ply yarn implements this interface, as slabs of chord tubes (rdm/yarn_grid_tracer.h, D66)
// or in Embree (rdm/yarn_tracer.h, the reference).
#pragma once

#include <cstdint>

#include "neuralyarn/rdm/ply_tracer.h"
#include "neuralyarn/units.h"

namespace neuralyarn::rdm {

/* Where a path enters: the point on the bounding surface and the entry frame there (ex along the medium's axis,
 * n the surface's outward normal, ey = n x ex). */
struct EntryFrame {
  ny::Vec3 point, ex, ey, n;
};

/* The entry on the cylinder of radius `bound` about the x axis at azimuth 2 pi u_around and x = L (u_along - 1/2). */
inline EntryFrame cylinder_entry(float bound, double entry_length, double u_around, double u_along)
{
  double sin_a, cos_a;
  sincos(2.0 * kPi * u_around, &sin_a, &cos_a);
  const float x = entry_length > 0.0 ? float(entry_length * (u_along - 0.5)) : 0.0f;
  EntryFrame e;
  e.n = ny::make_vec3(0.0f, float(cos_a), float(sin_a));
  e.ey = ny::make_vec3(0.0f, float(sin_a), float(-cos_a));
  e.ex = ny::make_vec3(1.0f, 0.0f, 0.0f);
  e.point = e.n * bound + e.ex * x;
  return e;
}

class FiberMedium {
 public:
  virtual ~FiberMedium() = default;
  /* Radius of the cylinder about the x axis that paths enter through; nothing lies outside it. */
  virtual float bound_radius() const = 0;
  /* The envelope's radius (the unit of the displacement statistics). */
  virtual float envelope_radius() const = 0;
  virtual float fiber_radius() const = 0;
  /* Paths enter at x uniform in [-entry_length / 2, entry_length / 2] (the structure's period along the
   * axis); 0: on the ring x = 0, for a medium that is invariant along its axis. */
  virtual double entry_length() const = 0;
  /* |x| beyond which the medium has no fibers (infinity for an infinite one). */
  virtual double half_length() const = 0;
  /* Where a path enters, from two uniform numbers (u_along is drawn only for a positive entry_length): on the
   * bounding cylinder unless the medium is bent (a ply on a curved centreline, decisions D75). */
  virtual EntryFrame entry_frame(double u_around, double u_along) const
  {
    return cylinder_entry(bound_radius(), entry_length(), u_around, u_along);
  }
  /* As PlyTracer::trace and PlyTracer::leave_fiber. For a finite medium the ray stays in the medium's
   * coordinates; SlabRay::slab, if it changes, only counts slab crossings for the gather's statistics. */
  virtual bool trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const = 0;
  virtual void leave_fiber(const TubeHit &hit, ny::Vec3 d, SlabRay *ray) const = 0;
};

}  // namespace neuralyarn::rdm
