// SPDX-License-Identifier: Apache-2.0
//
// Khungurn et al.'s normalised longitudinal Gaussian
//
//     gbar(theta; mu, beta) = g(theta; mu, beta) / G(mu, beta),
//     G(mu, beta)           = integral_{-pi/2}^{pi/2} g(theta; mu, beta) cos^2(theta) d(theta),
//
// where g is the normal density with mean mu and standard deviation beta (radians). With this
// normalisation a lobe M(theta_o) = gbar(theta_o; -theta_i, beta) integrates to one against the two cosines
// of a fiber's projected solid angle, int M cos^2(theta_o) d(theta_o) = 1, so the fiber BSDF's energy is
// exactly F + (1 - F) C_TT.
//
// How G is computed (docs/conventions.md, "cos^2 normaliser"):
//   * If both bounds are at least 6 beta away from mu, the truncation changes G by less than 1e-11
//     relative, and the untruncated closed form holds:  G = (1 + cos(2 mu) exp(-2 beta^2)) / 2.
//   * Otherwise the integral is taken by Gauss-Legendre quadrature over the window
//     [max(-pi/2, mu - 9 beta), min(pi/2, mu + 9 beta)], split at mu into two panels of 16 nodes each.
//     Against 30-digit adaptive quadrature the worst relative error over beta in [0.5, 300] degrees and
//     mu in [-pi/2, pi/2] is 1e-8 (in double; the float result is therefore float-exact).
// The authors' code instead integrates an 8th-order polynomial fit of cos^2, whose absolute error of 1e-4
// is as large as G itself at grazing incidence (G ~ beta^2 / 2 when mu = -+pi/2 and beta = 1 degree).
#pragma once

#include "platform.h"
#include "special.h"

namespace ny {

/* 16-point Gauss-Legendre rule on [-1, 1]: the 8 positive nodes and their weights (the rule is
 * symmetric). */
struct GaussLegendreNode {
  float x, w;
};

NY_KERNEL_FN GaussLegendreNode gauss_legendre16(int i)
{
  /* Roots of P_16 and their weights, rounded to float. */
  const float xs[8] = {0.09501250983763744f, 0.28160355077925892f, 0.45801677765722737f, 0.61787624440264377f,
                       0.75540440835500300f, 0.86563120238783176f, 0.94457502307323260f, 0.98940093499164994f};
  const float ws[8] = {0.18945061045506864f, 0.18260341504492364f, 0.16915651939500265f, 0.14959598881657671f,
                       0.12462897125553407f, 0.09515851168249261f, 0.06225352393864746f, 0.02715245941175418f};
  GaussLegendreNode n;
  n.x = xs[i];
  n.w = ws[i];
  return n;
}

/* integral_lo^hi g(theta; mu, beta) cos^2(theta) d(theta) by one 16-node panel. */
NY_KERNEL_FN float cos2_gaussian_panel(float mu, float beta, float lo, float hi)
{
  const float half = 0.5f * (hi - lo);
  const float mid = 0.5f * (hi + lo);
  const float inv_beta = 1.0f / beta;
  float sum = 0.0f;
  for (int i = 0; i < 8; i++) {
    const GaussLegendreNode n = gauss_legendre16(i);
    for (int side = 0; side < 2; side++) {
      const float t = mid + (side ? half : -half) * n.x;
      const float c = cosf(t);
      sum += n.w * normal_pdf((t - mu) * inv_beta) * c * c;
    }
  }
  return sum * half * inv_beta;
}

/* G(mu, beta), see the file comment. Requires beta > 0. */
NY_KERNEL_FN float cos2_gaussian_normalizer(float mu, float beta)
{
  const float dist_to_bound = kHalfPi - fabsf(mu);
  if (dist_to_bound >= 6.0f * beta) {
    return 0.5f * (1.0f + cosf(2.0f * mu) * expf(-2.0f * beta * beta));
  }
  const float lo = fmaxf(-kHalfPi, mu - 9.0f * beta);
  const float hi = fminf(kHalfPi, mu + 9.0f * beta);
  if (mu > lo && mu < hi) {
    return cos2_gaussian_panel(mu, beta, lo, mu) + cos2_gaussian_panel(mu, beta, mu, hi);
  }
  return cos2_gaussian_panel(mu, beta, lo, hi);
}

/* G(mu, beta) for a wide lobe (beta >= 5 degrees, e.g. a fiber's TT) near a bound: one 16-node panel over
 * [mu - 6 beta, mu + 6 beta] clipped to [-pi/2, pi/2] (the tails beyond 6 beta hold 2e-9). Against dense
 * quadrature the worst relative error over beta in [5, 40] degrees and mu in [-pi/2, pi/2] is 1e-5, at half
 * the cost of cos2_gaussian_normalizer; narrower lobes go to that. */
NY_KERNEL_FN float cos2_gaussian_normalizer_wide(float mu, float beta)
{
  if (!(beta >= 5.0f * kPi / 180.0f) || kHalfPi - fabsf(mu) >= 6.0f * beta) {
    return cos2_gaussian_normalizer(mu, beta); /* narrow, or the closed form holds */
  }
  return cos2_gaussian_panel(mu, beta, fmaxf(-kHalfPi, mu - 6.0f * beta), fminf(kHalfPi, mu + 6.0f * beta));
}

/* A longitudinal lobe gbar(.; mu, beta) with its normaliser computed once. */
struct LongitudinalLobe {
  float mu, beta;
  float inv_beta_G; /* 1 / (beta G): gbar(theta) = normal_pdf((theta - mu) / beta) * inv_beta_G */
};

/* `wide`: G by cos2_gaussian_normalizer_wide (a fiber's TT, beta >= 5 degrees). */
NY_KERNEL_FN LongitudinalLobe make_longitudinal_lobe(float mu, float beta, bool wide = false)
{
  LongitudinalLobe lobe;
  lobe.mu = mu;
  lobe.beta = beta;
  const float G = wide ? cos2_gaussian_normalizer_wide(mu, beta) : cos2_gaussian_normalizer(mu, beta);
  lobe.inv_beta_G = (G > 0.0f) ? 1.0f / (beta * G) : 0.0f;
  return lobe;
}

NY_KERNEL_FN float longitudinal_eval(NY_PRIVATE const LongitudinalLobe &lobe, float theta)
{
  if (!(theta >= -kHalfPi && theta <= kHalfPi)) {
    return 0.0f;
  }
  return normal_pdf((theta - lobe.mu) / lobe.beta) * lobe.inv_beta_G;
}

}  // namespace ny
