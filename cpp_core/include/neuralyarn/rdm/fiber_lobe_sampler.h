// SPDX-License-Identifier: Apache-2.0
//
// The fiber BSDF sampled the way a random walk wants it: the one-sample lobe estimator.
//
// Pick lobe k in {R, TT} with probability p_k proportional to its energy weighted by the path's throughput, draw w_o from that lobe's sampling
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
// Where the acceptance rate E_TN[cos^2 theta] = G_k / Z_k is at least kRejectionMinAcceptance (every
// event except those with w_i within a few beta of the fiber axis), theta_o is instead drawn exactly from
// gbar_k cos^2 by rejection (propose from TN_k, accept with probability cos^2 theta_o), and the weight is
// the constant e_k / p_k: the cos^2 factor would otherwise multiply into the throughput at every event
// and, over the tens of events of a high-albedo walk (cotton), dominate the variance of the maps. Both
// branches are unbiased, and which one runs depends on w_i only. TN_k itself is drawn as normal variates
// (rdm/normal_ziggurat.h) until one falls in [-pi/2, pi/2]: exact, without the erfc of the bounds and the
// quantile of an inverse CDF at every event.
//
// Z_k / G_k = 1 / E_TN[cos^2 theta] depends on mu and beta_k only. Computing G_k per event costs up to 32
// exp + 32 cos (the Gauss-Legendre branch, taken whenever mu is within 6 beta of a pole: most events), so
// the sampler tabulates Z/G over |mu| in [0, pi/2] once per preset, in double precision, and interpolates
// it with a cubic (Catmull-Rom) spline on 8192 intervals: relative error below 2e-5 (tests/cpp/test_rdm.cpp), far below
// the Monte Carlo noise of any map. docs/benchmarks.md has the speed-up.
#pragma once

#include <cmath>
#include <vector>

#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/rdm/normal_ziggurat.h"
#include "neuralyarn/rdm/von_mises_stream.h"

namespace neuralyarn::rdm {

/* Z(mu) / G(mu) for one longitudinal width beta (radians), tabulated over |mu| in [0, pi/2]. */
class CosSquaredRatioTable {
 public:
  explicit CosSquaredRatioTable(double beta, int intervals = 8192);
  float operator()(float mu) const;
  /* The exact value in double precision (what the table stores at its nodes). */
  static double exact(double mu, double beta);

 private:
  std::vector<float> values_; /* nodes 0 .. intervals, plus one guard on each side */
  float inv_step_ = 0.0f;
  int intervals_ = 0;
};

constexpr float kRejectionMinAcceptance = 0.2f;
constexpr int kRejectionMaxRounds = 64;

class FiberLobeSampler {
 public:
  /* `plain`: the textbook estimator instead, for benchmarks only (docs/benchmarks.md): lobe probability
   * from the channel mean (as the kernel) and theta_o always from the truncated normal with weight
   * cos^2 Z / G. Also unbiased, but noisier. */
  explicit FiberLobeSampler(const ny::FiberBsdfParams &params, bool plain = false);

  /* Samples w_o for w_i (both in the fiber frame, pointing away from the fiber); `uniform()` returns
   * numbers in [0, 1). Returns false (zero weight) when the fiber scatters nothing; *albedo receives
   * F + (1 - F) C_TT. */
  template<class Uniform>
  bool sample(ny::Vec3 wi, ny::Rgb throughput, Uniform &&uniform, ny::Vec3 *wo, ny::Rgb *weight,
              ny::Rgb *albedo) const;

  const ny::FiberBsdfParams &params() const { return p_; }
  /* Z / G of lobe R or TT at mu = -theta_i. */
  float ratio(bool lobe_R, float mu) const { return lobe_R ? ratio_R_(mu) : ratio_TT_(mu); }

 private:
  /* theta ~ TN(mu, beta) on [-pi/2, pi/2], |mu| <= pi/2: normal draws until one falls inside (the interval
   * holds at least half the normal's mass), or after kRejectionMaxRounds misses (p < 2^-64) the inverse CDF. */
  template<class Uniform> float sample_theta(float mu, float beta, Uniform &uniform) const;

  ny::FiberBsdfParams p_;
  bool plain_ = false;
  ny::VonMisesProposal von_mises_TT_; /* kappa = 1 / gamma_TT^2 */
  const NormalZiggurat *normal_ = &NormalZiggurat::get(); /* a pointer: the sampler stays assignable */
  CosSquaredRatioTable ratio_R_, ratio_TT_;
};

template<class Uniform> float FiberLobeSampler::sample_theta(float mu, float beta, Uniform &uniform) const
{
  for (int round = 0; round < kRejectionMaxRounds; round++) {
    const float theta = float(double(mu) + double(beta) * sample_standard_normal(*normal_, uniform));
    if (theta >= -ny::kHalfPi && theta <= ny::kHalfPi) {
      return theta;
    }
  }
  return ny::sample_truncated_normal(ny::make_truncated_normal(mu, beta, -ny::kHalfPi, ny::kHalfPi), uniform());
}

template<class Uniform>
bool FiberLobeSampler::sample(ny::Vec3 wi, ny::Rgb throughput, Uniform &&uniform, ny::Vec3 *wo, ny::Rgb *weight,
                              ny::Rgb *albedo) const
{
  const float theta_i = ny::theta_of(wi);
  const float cos_i = ny::cos_theta(wi);
  ny::Rgb F, e_TT;
  ny::fiber_energies(p_, wi, &F, &e_TT);
  *albedo = F + e_TT;
  /* Lobe energies weighted by the path's throughput: then the channel sum of the throughput can never grow
   * (sum_c beta_c e_kc / p_k = <beta, albedo>), however differently the lobes are coloured (kernel/fiber_bsdf.h). */
  *weight = ny::make_rgb(0.0f);
  if (!(ny::average(F) + ny::average(e_TT) > 0.0f)) {
    return false;
  }
  const float p_R = plain_ ? ny::fiber_probability_R(F, e_TT) : ny::fiber_probability_R(F, e_TT, throughput);
  const bool choose_R = uniform() < p_R;
  const float beta = choose_R ? p_.beta_R : p_.beta_TT;
  const float mu = -theta_i;
  const float zg = ratio(choose_R, mu); /* Z / G = 1 / acceptance */
  const ny::Rgb lobe_weight = choose_R ? F * (1.0f / p_R) : e_TT * (1.0f / (1.0f - p_R));

  float theta_o = 0.0f, sin_t = 0.0f, cos_t = 1.0f;
  bool exact = false;
  if (!plain_ && zg * kRejectionMinAcceptance <= 1.0f) {
    for (int round = 0; round < kRejectionMaxRounds && !exact; round++) {
      theta_o = sample_theta(mu, beta, uniform);
      const float u = uniform();
      /* cos^2 t <= 1 - t^2 + t^4 / 3 (from sin t >= t - t^3 / 6): most rejections need no sincos. */
      const double t2 = double(theta_o) * double(theta_o);
      if (double(u) >= 1.0 - t2 + t2 * t2 * (1.0 / 3.0)) {
        continue;
      }
      sincosf(theta_o, &sin_t, &cos_t);
      exact = u < cos_t * cos_t;
    }
  }
  float factor = 1.0f;
  if (!exact) {
    /* Weighted branch (or, with probability < 0.8^64, a rejection loop that ran out): a fresh TN sample. */
    theta_o = sample_theta(mu, beta, uniform);
    sincosf(theta_o, &sin_t, &cos_t);
    factor = cos_t * cos_t * zg;
  }

  /* The azimuth as its sine and cosine: for TT, phi_o = phi_i + pi + delta is expanded with the angle-sum
   * formulas from phi_i's sine and cosine (w_i's normal-plane components), saving an atan2 and a sincos. */
  float sin_phi, cos_phi;
  if (choose_R) {
    sincosf(ny::kTwoPi * uniform() - ny::kPi, &sin_phi, &cos_phi);
  }
  else {
    const float t = sample_von_mises_half_tan(von_mises_TT_, uniform);
    const float inv = 1.0f / (1.0f + t * t);
    const float sd = 2.0f * t * inv, cd = (1.0f - t * t) * inv; /* sin, cos of the deviation delta */
    const float si_phi = cos_i > 0.0f ? wi.y / cos_i : 0.0f, ci_phi = cos_i > 0.0f ? wi.z / cos_i : 1.0f;
    sin_phi = -(si_phi * cd + ci_phi * sd);
    cos_phi = -(ci_phi * cd - si_phi * sd);
  }
  *wo = ny::make_vec3(sin_t, cos_t * sin_phi, cos_t * cos_phi);
  *weight = lobe_weight * factor;
  return true;
}

}  // namespace neuralyarn::rdm
