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
// How G is computed (docs/conventions.md, "cos^2 normaliser"; docs/decisions.md D39):
//   * Over the whole line G_inf = (1 - exp(-2 beta^2)) / 2 + sin^2(d) exp(-2 beta^2), d = pi/2 - |mu| (the
//     textbook (1 + cos(2 mu) exp(-2 beta^2)) / 2, written so that float keeps its digits near the bound, where
//     both terms are ~ beta^2). If both bounds are at least 6 beta away from mu, the truncation changes G by
//     less than 1e-11 relative and G = G_inf.
//   * Nearer, G = G_inf r(beta, d / beta): the ratio r is tabulated (cos2_table.h, scripts/make_cos2_table.py)
//     for beta up to 30 degrees and interpolated by Catmull-Rom splines; relative error below 4e-6. The table
//     replaced a 32-node quadrature per lobe that was a third of the yarn closure's cost per shading point.
//   * Wider lobes: Gauss-Legendre quadrature over the window [max(-pi/2, mu - 9 beta), min(pi/2, mu + 9 beta)],
//     split at mu into two panels of 16 nodes each (1e-8 relative in double against 30-digit quadrature).
// The authors' code instead integrates an 8th-order polynomial fit of cos^2, whose absolute error of 1e-4
// is as large as G itself at grazing incidence (G ~ beta^2 / 2 when mu = -+pi/2 and beta = 1 degree).
#pragma once

#include "cos2_table.h"
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

/* (1 - exp(-x)) for x >= 0 without the cancellation of 1 - expf(-x) at small x (no expm1 on every device):
 * five terms of the series below 0.05 (truncation < 3e-11 relative). */
NY_KERNEL_FN float one_minus_exp_neg(float x)
{
  if (x < 0.05f) {
    return x * (1.0f - x * 0.5f * (1.0f - x * (1.0f / 3.0f) * (1.0f - x * 0.25f * (1.0f - x * 0.2f))));
  }
  return 1.0f - expf(-x);
}

/* What G_inf takes from the width alone, exp(-2 beta^2) and (1 - exp(-2 beta^2)) / 2: made once for every lobe of
 * that width (the yarn closure's R nodes share beta_R and beta_TT, docs/decisions.md D59). */
struct Cos2Width {
  float beta;
  float e;    /* exp(-2 beta^2)           */
  float half; /* (1 - exp(-2 beta^2)) / 2 */
};

NY_KERNEL_FN Cos2Width make_cos2_width(float beta)
{
  Cos2Width w;
  w.beta = beta;
  w.e = expf(-2.0f * beta * beta);
  w.half = 0.5f * one_minus_exp_neg(2.0f * beta * beta);
  return w;
}

/* G over the whole line (see the file comment); d = pi/2 - |mu|. */
/* G over the whole line given s = sin d (the lanes take their own sin). */
NY_KERNEL_FN float cos2_gaussian_untruncated_of_sin(float s, float half, float e) { return half + s * s * e; }

NY_KERNEL_FN float cos2_gaussian_untruncated(float d, NY_PRIVATE const Cos2Width &w)
{
  return cos2_gaussian_untruncated_of_sin(sinf(d), w.half, w.e);
}

/* Catmull-Rom spline through p0..p3 at x in [0, 1] between p1 and p2. */
NY_KERNEL_FN float catmull_rom(float p0, float p1, float p2, float p3, float x)
{
  return p1 + 0.5f * x * (p2 - p0 + x * (2.0f * p0 - 5.0f * p1 + 4.0f * p2 - p3 + x * (3.0f * (p1 - p2) + p3 - p0)));
}

/* G / G_inf at (beta, t) from the table; beta in [0, kCos2TableBetaMax], t clamped to [0, kCos2TableTMax]. */
NY_KERNEL_FN float cos2_gaussian_ratio(float beta, float t)
{
  const float fb = beta * ((float)kCos2TableBetaSteps / kCos2TableBetaMax);
  const float ft = clampf(t, 0.0f, kCos2TableTMax) * ((float)kCos2TableTSteps / kCos2TableTMax);
  const int ib = (int)fb < kCos2TableBetaSteps - 1 ? (int)fb : kCos2TableBetaSteps - 1;
  const int it = (int)ft < kCos2TableTSteps - 1 ? (int)ft : kCos2TableTSteps - 1;
  const float xb = fb - (float)ib, xt = ft - (float)it;
  /* Row k starts at node (ib - 1 + k, it - 1) after the padding. The four rows written out, not a loop: a loop
   * here keeps the R nodes' lanes (yarn_lobes) from vectorising. */
  const int b0 = ib * kCos2TableStride + it, b1 = b0 + kCos2TableStride, b2 = b1 + kCos2TableStride,
            b3 = b2 + kCos2TableStride;
  const float r0 = catmull_rom(kCos2Table[b0], kCos2Table[b0 + 1], kCos2Table[b0 + 2], kCos2Table[b0 + 3], xt);
  const float r1 = catmull_rom(kCos2Table[b1], kCos2Table[b1 + 1], kCos2Table[b1 + 2], kCos2Table[b1 + 3], xt);
  const float r2 = catmull_rom(kCos2Table[b2], kCos2Table[b2 + 1], kCos2Table[b2 + 2], kCos2Table[b2 + 3], xt);
  const float r3 = catmull_rom(kCos2Table[b3], kCos2Table[b3 + 1], kCos2Table[b3 + 2], kCos2Table[b3 + 3], xt);
  return catmull_rom(r0, r1, r2, r3, xb);
}

/* Whether G is the closed form over the whole line: the mean 6 beta or more from both bounds. */
NY_KERNEL_FN bool cos2_gaussian_closed_form_holds(float dist_to_bound, float beta) { return dist_to_bound >= 6.0f * beta; }

/* G(mu, beta), see the file comment. Requires beta > 0. */
NY_KERNEL_FN float cos2_gaussian_normalizer(float mu, NY_PRIVATE const Cos2Width &w)
{
  const float beta = w.beta;
  const float dist_to_bound = kHalfPi - fabsf(mu);
  if (cos2_gaussian_closed_form_holds(dist_to_bound, beta)) {
    return cos2_gaussian_untruncated(dist_to_bound, w);
  }
  if (beta <= kCos2TableBetaMax) {
    const float d = maxf(dist_to_bound, 0.0f);
    return cos2_gaussian_untruncated(d, w) * cos2_gaussian_ratio(beta, d / beta);
  }
  const float lo = maxf(mu - 9.0f * beta, -kHalfPi);
  const float hi = minf(mu + 9.0f * beta, kHalfPi);
  if (mu > lo && mu < hi) {
    return cos2_gaussian_panel(mu, beta, lo, mu) + cos2_gaussian_panel(mu, beta, mu, hi);
  }
  return cos2_gaussian_panel(mu, beta, lo, hi);
}

/* cos2_gaussian_normalizer() for beta <= kCos2TableBetaMax without branches or library calls, for loops that run
 * lanes side by side (the R nodes, yarn_lobes): both the closed form and the table's ratio computed, one selected;
 * sin by sincos_lanes (within 2 ulps of sinf), so within a few ulps of cos2_gaussian_normalizer's value. kTable
 * false leaves the table out, for a caller that knows every lane at least 6 beta from the bounds (the same value). */
template<bool kTable = true>
NY_KERNEL_FN float cos2_gaussian_normalizer_lanes(float mu, float beta, float half, float e)
{
  const float dist_to_bound = kHalfPi - fabsf(mu);
  const float d = maxf(dist_to_bound, 0.0f);
  float s, c;
  sincos_lanes(d, s, c);
  const float G_inf = cos2_gaussian_untruncated_of_sin(s, half, e);
  if (!kTable) {
    return G_inf;
  }
  /* The table read on every lane (its indices are clamped into it), not under the condition: loads there become
   * masked gathers, which GCC 12 does not vectorise here. */
  const float ratio = cos2_gaussian_ratio(beta, d / beta);
  return cos2_gaussian_closed_form_holds(dist_to_bound, beta) ? G_inf : G_inf * ratio;
}

NY_KERNEL_FN float cos2_gaussian_normalizer(float mu, float beta)
{
  const Cos2Width w = make_cos2_width(beta);
  return cos2_gaussian_normalizer(mu, w);
}

/* G(mu, beta) for a lobe wider than the table (a fiber's TT past 30 degrees) near a bound: one 16-node panel
 * over [mu - 6 beta, mu + 6 beta] clipped to [-pi/2, pi/2] (the tails beyond 6 beta hold 2e-9). Against dense
 * quadrature the worst relative error over beta in [5, 40] degrees and mu in [-pi/2, pi/2] is 1e-5, at half
 * the cost of the two-panel rule; lobes the table holds go to cos2_gaussian_normalizer. */
NY_KERNEL_FN float cos2_gaussian_normalizer_wide(float mu, NY_PRIVATE const Cos2Width &w)
{
  const float beta = w.beta;
  if (beta <= kCos2TableBetaMax || cos2_gaussian_closed_form_holds(kHalfPi - fabsf(mu), beta)) {
    return cos2_gaussian_normalizer(mu, w); /* the table, or the closed form holds */
  }
  return cos2_gaussian_panel(mu, beta, maxf(mu - 6.0f * beta, -kHalfPi), minf(mu + 6.0f * beta, kHalfPi));
}

NY_KERNEL_FN float cos2_gaussian_normalizer_wide(float mu, float beta)
{
  const Cos2Width w = make_cos2_width(beta);
  return cos2_gaussian_normalizer_wide(mu, w);
}

/* A longitudinal lobe gbar(.; mu, beta) with its normaliser computed once. */
struct LongitudinalLobe {
  float mu, beta;
  float inv_beta_G; /* 1 / (beta G): gbar(theta) = normal_pdf((theta - mu) / beta) * inv_beta_G */
};

/* 1 / (beta G), 0 where G is not positive. */
NY_KERNEL_FN float longitudinal_inv_beta_G(float beta, float G) { return (G > 0.0f) ? 1.0f / (beta * G) : 0.0f; }

/* `wide`: G by cos2_gaussian_normalizer_wide (a fiber's TT, beta >= 5 degrees). */
NY_KERNEL_FN LongitudinalLobe make_longitudinal_lobe(float mu, NY_PRIVATE const Cos2Width &w, bool wide = false)
{
  LongitudinalLobe lobe;
  lobe.mu = mu;
  lobe.beta = w.beta;
  const float G = wide ? cos2_gaussian_normalizer_wide(mu, w) : cos2_gaussian_normalizer(mu, w);
  lobe.inv_beta_G = longitudinal_inv_beta_G(w.beta, G);
  return lobe;
}

NY_KERNEL_FN LongitudinalLobe make_longitudinal_lobe(float mu, float beta, bool wide = false)
{
  const Cos2Width w = make_cos2_width(beta);
  return make_longitudinal_lobe(mu, w, wide);
}

/* gbar(theta) given g = normal_pdf((theta - mu) / beta): one g serves every lobe of that mean and width. */
NY_KERNEL_FN float longitudinal_eval_of(NY_PRIVATE const LongitudinalLobe &lobe, float theta, float g)
{
  if (!(theta >= -kHalfPi && theta <= kHalfPi)) {
    return 0.0f;
  }
  return g * lobe.inv_beta_G;
}

NY_KERNEL_FN float longitudinal_eval(NY_PRIVATE const LongitudinalLobe &lobe, float theta)
{
  return longitudinal_eval_of(lobe, theta, normal_pdf((theta - lobe.mu) / lobe.beta));
}

}  // namespace ny
