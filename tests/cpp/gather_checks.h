// SPDX-License-Identifier: Apache-2.0
// What the tests of other fiber media than PlyTracer's share (test_yarn_level.cpp, test_bent_ply.cpp): a small
// gather, and two gathers' energies agreeing within their noise.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::testing {

/* Coarse bins (6 x 12 x 12 x 12), 2 threads. */
inline rdm::GatherOptions small_gather(uint64_t paths)
{
  rdm::GatherOptions o;
  o.paths = paths;
  o.bins = rdm::parse_resolution("6x12x12x12");
  o.threads = 2;
  return o;
}

/* The energies of T, R and M of two gathers of as many paths agree within their noise: per-path exit weights stay
 * below ~1.5 (roulette keeps them near 1), so Var <= 1.5 E; 4 sigma of a difference of two independent means, plus
 * `slack` of the larger (what the media may differ by: chords against helices, a bend). */
inline void expect_same_energies(const rdm::GatherStats &a, const rdm::GatherStats &b, double slack)
{
  const double n = double(a.paths);
  auto tol = [&](double x, double y) { return 4.0 * std::sqrt(1.5 * (x + y) / n) + slack * std::max(x, y); };
  for (int c = 0; c < 3; c++) {
    EXPECT_NEAR(a.energy_T[c], b.energy_T[c], tol(a.energy_T[c], b.energy_T[c])) << c;
    EXPECT_NEAR(a.energy_R[c], b.energy_R[c], tol(a.energy_R[c], b.energy_R[c])) << c;
    EXPECT_NEAR(a.energy_M[c], b.energy_M[c], tol(a.energy_M[c], b.energy_M[c])) << c;
  }
}

}  // namespace neuralyarn::testing
