// SPDX-License-Identifier: Apache-2.0
//
// The von Mises distribution for the random walk's TT azimuth: Best & Fisher's sampler (kernel/sampling.h, its
// proposal and acceptance written once there), with the proposal's tan(pi U / 2) taken without a tan. The
// tangent of an angle uniform in [0, pi/2) is y / x of a point uniform in the quarter disc, which two uniforms
// give by rejection from the unit square (accepted with probability pi / 4). Exact, like the kernel's; the
// renderer keeps tanf, since a closure gets a fixed number of random numbers (decisions D57).
#pragma once

#include "neuralyarn/kernel/sampling.h"

namespace neuralyarn::rdm {

/* t = tan(theta / 2) of theta ~ von Mises(0, p.kappa) on (-pi, pi]; `uniform()` returns numbers in [0, 1). */
template<class Uniform> float sample_von_mises_half_tan(const ny::VonMisesProposal &p, Uniform &&uniform)
{
  const bool negative = uniform() < 0.5f;
  float t = 0.0f;
  /* As the kernel's loop: 64 rounds fail with probability < 0.35^64, the last proposal is then returned. */
  for (int round = 0; round < 64; round++) {
    float x, y;
    do {
      x = uniform();
      y = uniform();
    } while (!(x * x + y * y < 1.0f && x > 0.0f));
    t = y / x;
    if (p.kappa < ny::kVonMisesUniformKappa) {
      break;
    }
    t *= p.c;
    if (ny::von_mises_accepts(p, t, uniform())) {
      break;
    }
  }
  return negative ? -t : t;
}

}  // namespace neuralyarn::rdm
