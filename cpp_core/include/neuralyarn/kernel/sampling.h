// SPDX-License-Identifier: Apache-2.0
//
// Paired samplers and densities. Every sample_X draws exactly from the density pdf_X next to it; the
// pair is tested by chi^2 goodness-of-fit in tests/cpp/test_sampling.cpp.
//
//   truncated normal  — inverse CDF (exact up to float rounding), with both tails handled in the
//                       complementary form so that neither Phi nor Phi^-1 cancels;
//   von Mises         — Best & Fisher (1979) rejection sampler in a half-angle form that stays accurate in
//                       float for concentrations from 1e-4 to 1e7;
//   uniform sphere    — the textbook map.
#pragma once

#include "platform.h"
#include "special.h"

namespace ny {

/* ------------------------------------------------------------------------------------------------ */
/* Counter-based random numbers for rejection loops.                                                  */
/* ------------------------------------------------------------------------------------------------ */

/* A kernel receives a fixed number of random numbers per sample (Cycles gives three). A rejection
 * sampler that needs more continues with a hash chain seeded from the bits of the numbers it was given:
 * deterministic, stateless, and independent enough for a loop that runs 1.5 times on average. */
/* PCG-style integer hash (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020). */
NY_KERNEL_FN uint32_t hash_pcg(uint32_t v)
{
  const uint32_t state = v * 747796405u + 2891336453u;
  const uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

/* Next uniform float in [0, 1) from the chain state (24 random bits, exactly representable). */
NY_KERNEL_FN float hash_next_uniform(NY_PRIVATE uint32_t *state)
{
  *state = hash_pcg(*state);
  return (float)(*state >> 8) * (1.0f / 16777216.0f);
}

/* ------------------------------------------------------------------------------------------------ */
/* Truncated normal on [a, b].                                                                        */
/* ------------------------------------------------------------------------------------------------ */

struct TruncatedNormal {
  float mu, sigma;
  float za, zb;   /* standardised bounds (a - mu) / sigma, (b - mu) / sigma */
  float lower;    /* Phi(za): mass below a          */
  float upper;    /* 1 - Phi(zb): mass above b      */
  float mass;     /* Phi(zb) - Phi(za): mass inside */
};

/* A tail beyond kNormalTailCut sigma (mass < 1.2e-19) is below float resolution next to the smallest mass the
 * inverse CDF ever asks for (u >= 2^-32 times the mass): it is exactly 0 then, and erfc is skipped. */
constexpr float kNormalTailCut = 9.0f;

/* Whether both tails of an interval with standardised bounds za < 0 < zb are cut (mass exactly 1, lower and upper
 * exactly 0, in make_truncated_normal and truncated_normal_lanes alike). */
NY_KERNEL_FN bool truncated_normal_tails_cut(float za, float zb) { return za < -kNormalTailCut && zb > kNormalTailCut; }

/* Requires sigma > 0 and a < b. The mass is computed in whichever form avoids cancellation: both bounds
 * in one tail use that tail's CDF, a straddling interval uses 1 - lower - upper. */
NY_KERNEL_FN TruncatedNormal make_truncated_normal(float mu, float sigma, float a, float b)
{
  TruncatedNormal tn;
  tn.mu = mu;
  tn.sigma = sigma;
  tn.za = (a - mu) / sigma;
  tn.zb = (b - mu) / sigma;
  /* An interval on one side of the mean takes its mass as a difference of two tail probabilities, and the
   * CDF level on the mean's side as 1 - its own tail (>= 1/2, where that loses nothing and the sampler
   * reads the other one): two erfc calls instead of three (the TT azimuth's interval lies beyond its mean). */
  if (tn.za >= 0.0f) {
    const float tail_a = normal_ccdf(tn.za);
    tn.lower = 1.0f - tail_a;
    tn.upper = tn.zb > kNormalTailCut ? 0.0f : normal_ccdf(tn.zb);
    tn.mass = tail_a - tn.upper;
  }
  else if (tn.zb <= 0.0f) {
    const float tail_b = normal_cdf(tn.zb);
    tn.upper = 1.0f - tail_b;
    tn.lower = tn.za < -kNormalTailCut ? 0.0f : normal_cdf(tn.za);
    tn.mass = tail_b - tn.lower;
  }
  else {
    tn.lower = tn.za < -kNormalTailCut ? 0.0f : normal_cdf(tn.za);
    tn.upper = tn.zb > kNormalTailCut ? 0.0f : normal_ccdf(tn.zb);
    tn.mass = 1.0f - tn.lower - tn.upper;
  }
  return tn;
}

/* make_truncated_normal() for loops that run lanes side by side (the R nodes, yarn_lobes): the same three cases
 * and the same two tail probabilities, each case's erfc argument selected before one call per bound and its
 * results after, erfc by erfc_lanes (the kernel's exp: within a few ulps of make_truncated_normal's values).
 * Fields by reference: a structure returned inside such a loop keeps GCC 12 from vectorising it. */
NY_KERNEL_FN void truncated_normal_lanes(float mu, float sigma, float a, float b, NY_PRIVATE float &za,
                                         NY_PRIVATE float &zb, NY_PRIVATE float &lower, NY_PRIVATE float &upper,
                                         NY_PRIVATE float &mass)
{
  za = (a - mu) / sigma;
  zb = (b - mu) / sigma;
  const bool above = za >= 0.0f, below = !above && zb <= 0.0f;
  /* Phi(za) = erfc(-za / sqrt 2) / 2 but in the upper case its tail 1 - Phi(za) = erfc(za / sqrt 2) / 2; 1 - Phi(zb)
   * = erfc(zb / sqrt 2) / 2 but in the lower case Phi(zb) = erfc(-zb / sqrt 2) / 2 (make_truncated_normal's
   * normal_cdf and normal_ccdf, multiplied by 1 / sqrt 2 as there). */
  const float e_a = 0.5f * erfc_lanes((above ? za : -za) * kInvSqrt2);
  const float e_b = 0.5f * erfc_lanes((below ? -zb : zb) * kInvSqrt2);
  const float lower_mid = za < -kNormalTailCut ? 0.0f : e_a, upper_mid = zb > kNormalTailCut ? 0.0f : e_b;
  lower = above ? 1.0f - e_a : lower_mid;
  upper = below ? 1.0f - e_b : upper_mid;
  mass = above ? e_a - upper_mid : below ? e_b - lower_mid : 1.0f - lower_mid - upper_mid;
}

/* The density at standard score z given normal_pdf(z) = g: one g serves every lobe of that mean and width. */
NY_KERNEL_FN float truncated_normal_pdf_of(NY_PRIVATE const TruncatedNormal &tn, float z, float g)
{
  if (!(z >= tn.za && z <= tn.zb) || !(tn.mass > 0.0f)) {
    return 0.0f;
  }
  return g / (tn.sigma * tn.mass);
}

/* Density with respect to x. */
NY_KERNEL_FN float truncated_normal_pdf(NY_PRIVATE const TruncatedNormal &tn, float x)
{
  const float z = (x - tn.mu) / tn.sigma;
  return truncated_normal_pdf_of(tn, z, normal_pdf(z));
}

/* Smallest u used by the inverse CDF. u = 0 would ask for the truncated distribution's 0-quantile, its
 * boundary, where the float density can be 0 or denormal (a 1-degree lobe 20 degrees from the bound:
 * the boundary is 20 sigma out) and the sample weight infinite. Treating u = 0 as u = 2^-32 puts that
 * sample at the distribution's 2^-32 quantile instead: a point inside the support whose density is a
 * normal float. Any 24- or 32-bit uniform generator's smallest non-zero output is >= 2^-32, so no other
 * u moves and the distribution is unchanged at the resolution of the random numbers. */
constexpr float kMinUniform = 2.3283064e-10f; /* 2^-32 */

/* Inverse-CDF sample for u in [0, 1). The target CDF level P = Phi(za) + u * mass is formed in the lower
 * tail when P <= 1/2 and as its complement Q = (1 - Phi(zb)) + (1 - u) * mass otherwise, so every
 * quantile is taken where it is well conditioned. Requires mass > 0 (the interval must reach within
 * ~13 sigma of the mean for its mass to be a float); otherwise the result is a bound. */
NY_KERNEL_FN float sample_truncated_normal(NY_PRIVATE const TruncatedNormal &tn, float u)
{
  u = maxf(u, kMinUniform);
  float z;
  const float p = tn.lower + u * tn.mass;
  if (p <= 0.5f) {
    z = normal_quantile(p);
  }
  else {
    z = normal_quantile_upper(tn.upper + (1.0f - u) * tn.mass);
  }
  /* Rounding can step a hair outside the support; the density there is the boundary value. */
  z = clampf(z, tn.za, tn.zb);
  return tn.mu + tn.sigma * z;
}

/* ------------------------------------------------------------------------------------------------ */
/* Von Mises distribution on the circle, mean 0, concentration kappa.                                 */
/* ------------------------------------------------------------------------------------------------ */

/* Below this concentration the distribution is uniform to float precision (|pdf - 1/2pi| < 1e-4 rel). */
constexpr float kVonMisesUniformKappa = 1e-4f;

/* f(delta) = exp(kappa cos delta) / (2 pi I0(kappa)), written with the scaled Bessel function and
 * cos(delta) - 1 = -2 sin^2(delta / 2) so that it neither overflows nor cancels for large kappa. */
NY_KERNEL_FN float von_mises_pdf(float delta, float kappa)
{
  if (kappa < kVonMisesUniformKappa) {
    return kInvTwoPi;
  }
  const float s = sinf(0.5f * delta);
  return expf(-2.0f * kappa * s * s) * kInvTwoPi / bessel_i0e(kappa);
}

/* Best & Fisher (1979), "Efficient simulation of the von Mises distribution", Appl. Stat. 28(2).
 *
 * The textbook form proposes z = cos(pi U), w = (1 + r z) / (r + z) and returns acos(w); in float that
 * cancels badly for large kappa (r -> 1, w -> 1). Using 1 - w = (r-1)(1-z)/(r+z) and
 * 1 + w = (r+1)(1+z)/(r+z), the proposal is exactly
 *     tan(theta / 2) = c tan(pi U / 2),   c = (1 - b) / (1 + b),
 * and the acceptance variable is Y = kappa (r - w) = kappa ((r - 1) + 2 sin^2(theta / 2)), where
 * r - 1 = (1 - b)^2 / (2 b). 1 - b itself is formed without cancellation (see below). */

/* The proposal's c and r - 1 for one concentration. They depend on kappa alone, so a caller of one kappa (the
 * random walk's TT lobe) makes them once.
 *   tau = 1 + sqrt(1 + 4 kappa^2), b = (tau - sqrt(2 tau)) / (2 kappa). With
 *   2 kappa - tau = -1 - 1 / (sqrt(1 + 4 kappa^2) + 2 kappa):
 *   1 - b = (sqrt(2 tau) - 1 - 1 / (sqrt(1 + 4 kappa^2) + 2 kappa)) / (2 kappa). */
struct VonMisesProposal {
  float kappa, c, r_minus_1;
};

NY_KERNEL_FN VonMisesProposal make_von_mises_proposal(float kappa)
{
  const float root = sqrtf(1.0f + 4.0f * kappa * kappa);
  const float tau = 1.0f + root;
  const float one_minus_b = (sqrtf(2.0f * tau) - 1.0f - 1.0f / (root + 2.0f * kappa)) / (2.0f * kappa);
  const float b = 1.0f - one_minus_b;
  VonMisesProposal p;
  p.kappa = kappa;
  p.c = one_minus_b / (1.0f + b);
  p.r_minus_1 = one_minus_b * one_minus_b / (2.0f * b);
  return p;
}

/* Best & Fisher's acceptance of the proposal t = tan(theta / 2) (t = c tan(pi U / 2)) with variate v in [0, 1):
 * Y = kappa ((r - 1) + 2 sin^2(theta / 2)), accepted when Y (2 - Y) > v (the squeeze) or ln(Y / v) + 1 >= Y. */
NY_KERNEL_FN bool von_mises_accepts(NY_PRIVATE const VonMisesProposal &p, float t, float v)
{
  const float sh2 = t * t / (1.0f + t * t); /* sin^2(theta / 2) */
  const float y = p.kappa * (p.r_minus_1 + 2.0f * sh2);
  return y * (2.0f - y) - v > 0.0f || logf(y / v) + 1.0f - y >= 0.0f;
}

/* The sampler's core: returns t = tan(theta / 2) of the sampled angle theta in (-pi, pi], from which
 * callers form theta = 2 atan(t) or, without any inverse trigonometry, sin(theta) = 2t / (1 + t^2) and
 * cos(theta) = (1 - t^2) / (1 + t^2). (For kappa below kVonMisesUniformKappa the angle is uniform and t
 * = tan(pi u / 2) as well.) u_angle in [0, 1) supplies the sign (its first half) and U (rescaled); u_accept
 * in [0, 1) is the first acceptance variate. Further variates, needed after a rejection (probability < 0.35
 * per round), come from the hash chain. */
NY_KERNEL_FN float sample_von_mises_half_tan(float kappa, float u_angle, float u_accept)
{
  const bool negative = u_angle < 0.5f;
  float u = negative ? 2.0f * u_angle : 2.0f * u_angle - 1.0f;
  if (kappa < kVonMisesUniformKappa) {
    const float t = tanf(0.5f * kPi * u);
    return negative ? -t : t;
  }
  const VonMisesProposal p = make_von_mises_proposal(kappa);
  uint32_t chain = hash_pcg(float_bits(u_angle) ^ hash_pcg(float_bits(u_accept) + 0x9e3779b9u));
  float v = u_accept;
  float t = 0.0f;
  /* 64 rounds fail with probability < 0.35^64 ~ 1e-29; the last proposal is then returned. */
  for (int round = 0; round < 64; round++) {
    t = p.c * tanf(0.5f * kPi * u);
    if (von_mises_accepts(p, t, v)) {
      break;
    }
    u = hash_next_uniform(&chain);
    v = hash_next_uniform(&chain);
  }
  return negative ? -t : t;
}

NY_KERNEL_FN float sample_von_mises(float kappa, float u_angle, float u_accept)
{
  return 2.0f * atanf(sample_von_mises_half_tan(kappa, u_angle, u_accept));
}

/* ------------------------------------------------------------------------------------------------ */
/* Uniform sphere.                                                                                    */
/* ------------------------------------------------------------------------------------------------ */

NY_KERNEL_FN Vec3 sample_uniform_sphere(float u1, float u2)
{
  const float z = 1.0f - 2.0f * u1;
  const float r = safe_sqrtf(1.0f - z * z);
  const float phi = kTwoPi * u2;
  return make_vec3(r * cosf(phi), r * sinf(phi), z);
}

NY_KERNEL_FN float uniform_sphere_pdf() { return kInvFourPi; }

}  // namespace ny
