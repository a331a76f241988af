// SPDX-License-Identifier: Apache-2.0
//
// Where along the ply the light scattered inside an aggregated ply leaves it (decisions D68).
//
// The aggregated BSDF is a far-field function: a renderer evaluates it at the hit point and continues the path
// from there. Inside real fibers, light also travels along the ply (cotton: half of what goes through more than a
// ply radius, a tenth more than six), so a part of a ply in another ply's shadow still glows with light that
// entered where the ply is lit; a far-field BSDF leaves that part dark. The gather measures, energy-weighted at
// the levels below, how far along the axis the exits lie from where a renderer's ray from the entry point would
// leave (rdm::GatherStats::axial_exit_through, axial_exit_reflected: through the far side, on the entry side); a
// model carries those quantiles (model::NearField), and a renderer moves the origin of a path that leaves a neural
// yarn closure's ply by an offset drawn from those of its side, in ply radii along the curve.
//
// The quantiles become knots of |offset| at the levels 0, the gather's six and 1 (the last extrapolated by
// the step before it); between knots the inverse distribution is linear.
#pragma once

#include "platform.h"

namespace ny {

/* The gather's quantile levels (rdm::GatherStats), and the knots': 0, those six, 1. */
constexpr int kExitQuantiles = 6;
constexpr int kExitKnots = kExitQuantiles + 2;
/* Knot k's level (a function, not a table: device code reads no namespace-scope arrays). */
NY_KERNEL_FN float exit_knot_level(int k)
{
  return k <= 0 ? 0.0f : k == 1 ? 0.25f : k == 2 ? 0.5f : k == 3 ? 0.75f : k == 4 ? 0.9f : k == 5 ? 0.95f :
                                                                                                  k == 6 ? 0.99f :
                                                                                                           1.0f;
}
/* Largest quantile a model may carry (ply radii). */
constexpr float kExitMaxOffset = 1000.0f;

#ifndef NY_KERNEL_DEVICE
/* Checks a model's quantiles (kExitQuantiles of them, ply radii): finite, in [0, kExitMaxOffset], non-decreasing.
 * Returns null if they are fine, else what is wrong. */
inline const char *exit_quantiles_check(const float *q, int n)
{
  if (n != kExitQuantiles) {
    return "must hold six quantiles (at 25, 50, 75, 90, 95 and 99 %)";
  }
  for (int k = 0; k < n; k++) {
    if (!(q[k] >= 0.0f && q[k] <= kExitMaxOffset)) {
      return "holds a value that is not a finite number in [0, 1000] ply radii";
    }
    if (k > 0 && !(q[k] >= q[k - 1])) {
      return "decreases: quantiles at higher levels must not be smaller";
    }
  }
  return nullptr;
}

/* The knots (kExitKnots floats) of checked quantiles: 0, the quantiles, and the last one stepped on by the
 * difference before it (the 99 % to 100 % share spread as the 95 % to 99 % one is, so no offset is unbounded). */
inline void exit_knots(const float *q, float *knots)
{
  knots[0] = 0.0f;
  for (int k = 0; k < kExitQuantiles; k++) {
    knots[k + 1] = q[k];
  }
  knots[kExitKnots - 1] = q[kExitQuantiles - 1] + (q[kExitQuantiles - 1] - q[kExitQuantiles - 2]);
}
#endif

/* A signed offset (ply radii) for u in [0, 1): its sign from u < 1/2 (the walk is symmetric along the axis), its
 * magnitude from the inverse distribution through `knots` at the remapped u. */
NY_KERNEL_FN float exit_sample_offset(NY_GLOBAL const float *knots, float u)
{
  const float sign = u < 0.5f ? -1.0f : 1.0f;
  float v = u < 0.5f ? 2.0f * u : 2.0f * u - 1.0f;
  v = v < 0.0f ? 0.0f : (v > 1.0f ? 1.0f : v);
  float magnitude = knots[kExitKnots - 1];
  for (int k = 1; k < kExitKnots; k++) {
    const float l0 = exit_knot_level(k - 1), l1 = exit_knot_level(k);
    if (v < l1) {
      magnitude = knots[k - 1] + (knots[k] - knots[k - 1]) * ((v - l0) / (l1 - l0));
      break;
    }
  }
  return sign * magnitude;
}

}  // namespace ny
