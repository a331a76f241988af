// SPDX-License-Identifier: Apache-2.0
//
// The fiber BSDF sampled the way a random walk wants it: the one-sample lobe estimator.
//
// Pick lobe k in {R, TT} with probability p_k (the kernel's p_R), draw w_o from that lobe's sampling
// density alone (truncated normal TN_k in theta_o, uniform or von Mises in phi_o) and return the weight
//
//     weight = e_k / p_k * cos^2(theta_o) * Z_k(mu) / G_k(mu),       mu = -theta_i,
//
// with e_k the lobe's albedo (F or (1 - F) C_TT), Z_k the truncated normal's mass on [-pi/2, pi/2] and G_k
// the cos^2 normaliser of kernel/longitudinal.h. Because TN_k cos^2 Z_k / G_k = gbar_k cos^2 exactly,
// E[weight h(w_o)] equals the integral of the kernel's eval times h for every h: the estimator is unbiased
// without evaluating the other lobe. (Its weight is not eval / pdf, so a renderer that combines BSDF and
// light sampling by MIS must keep using ny::fiber_sample.)
//
// Z_k / G_k = 1 / E_TN[cos^2 theta] depends on mu and beta_k only. Computing G_k per event costs up to 32
// exp + 32 cos (the Gauss-Legendre branch, taken whenever mu is within 6 beta of a pole: most events), so
// the sampler tabulates Z/G over |mu| in [0, pi/2] once per preset, in double precision, and interpolates
// it with a cubic (Catmull-Rom) spline: relative error below 1e-6 (tests/cpp/test_rdm.cpp), far below
// the Monte Carlo noise of any map. docs/benchmarks.md has the speed-up.
#pragma once

#include <vector>

#include "neuralyarn/kernel/fiber_bsdf.h"

namespace neuralyarn::rdm {

/* Z(mu) / G(mu) for one longitudinal width beta (radians), tabulated over |mu| in [0, pi/2]. */
class CosSquaredRatioTable {
 public:
  explicit CosSquaredRatioTable(double beta, int intervals = 2048);
  float operator()(float mu) const;
  /* The exact value in double precision (what the table stores at its nodes). */
  static double exact(double mu, double beta);

 private:
  std::vector<float> values_; /* nodes 0 .. intervals, plus one guard on each side */
  float inv_step_ = 0.0f;
  int intervals_ = 0;
};

class FiberLobeSampler {
 public:
  explicit FiberLobeSampler(const ny::FiberBsdfParams &params);

  /* Samples w_o for w_i (both in the fiber frame, pointing away from the fiber) from four uniform numbers.
   * Returns false (zero weight) when the fiber scatters nothing; *albedo receives F + (1 - F) C_TT. */
  bool sample(ny::Vec3 wi, float u_lobe, float u_theta, float u_phi, float u_extra, ny::Vec3 *wo,
              ny::Rgb *weight, ny::Rgb *albedo) const;

  const ny::FiberBsdfParams &params() const { return p_; }

 private:
  ny::FiberBsdfParams p_;
  float kappa_TT_;
  CosSquaredRatioTable ratio_R_, ratio_TT_;
};

}  // namespace neuralyarn::rdm
