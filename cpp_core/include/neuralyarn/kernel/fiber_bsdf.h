// SPDX-License-Identifier: Apache-2.0
//
// Khungurn et al. (2015) fiber scattering, exactly as the paper's Sec. 2.1 defines it:
//
//   S_f(w_i, w_o) = sum_{k in {R, TT}} M_k(theta_i, theta_o) N_k(phi_i, phi_o)
//   M_R  = F_R(theta_i) gbar(theta_o; -theta_i, beta_R)
//   M_TT = C_TT (1 - F_R(theta_i)) gbar(theta_o; -theta_i, beta_TT)
//   N_R  = 1 / (2 pi)
//   N_TT = vonMises(phi_o; phi_i + pi, kappa = gamma_TT^-2)
//   F_R  = C_R + (1 - C_R) (1 - cos theta_i)^5                       (Schlick, per channel)
//
// in the local fiber frame of frames.h (x = fiber tangent). Both directions point away from the fiber.
//
// Conventions of this file (the same as Cycles' bsdf_*.h):
//   * eval returns S_f(w_i, w_o) |cos theta_o|, the "projected" BSDF that a path tracer multiplies by the
//     incident radiance; its integral over the sphere is the albedo F + (1 - F) C_TT per channel;
//   * pdf is a density with respect to solid angle;
//   * sample returns a direction, its pdf and weight = eval / pdf.
//
// Sampling matches pdf exactly. The lobe is chosen with probability
//   p_R = mean(F) / (mean(F) + mean((1 - F) C_TT)),
// or, where the caller knows the path's throughput t (it then sets FiberLobes::p_R itself), with the lobes'
// energies weighted by it: p_R = <t, F> / <t, F + (1 - F) C_TT>. Any p_R in (0, 1) is unbiased; the weighted
// one keeps the lobe choice from growing a channel: with the channel mean, every TT event of a cotton path
// multiplies its blue weight by 2.1 and its red by 0.19 (TT is blue-heavy, R red-heavy); weighted, the
// channel sum of t e_k / p_k is <t, albedo>.
// theta_o is drawn exactly from lobe k's density gbar_k(theta) cos^2(theta) by rejection: proposals from the
// truncated normal N(-theta_i, beta_k) on [-pi/2, pi/2] (inverse CDF), accepted with probability
// cos^2 theta_o, more uniform numbers from the caller's generator. The acceptance rate is G_k / Z_k (Z_k the
// truncated normal's mass); where it is below kFiberExactMinAcceptance (w_i within a few beta of the fiber
// axis) one proposal is kept instead, with density TN_k. The azimuth is uniform (R) or von Mises (TT).
// pdf is the density of that mixture,
//   pdf = [p_R D_R(theta_o) / (2 pi) + (1 - p_R) D_TT(theta_o) vM(phi_o - phi_i - pi)] / cos theta_o,
// D_k = gbar_k cos^2 or TN_k, the 1 / cos theta_o converting from (theta, phi) to solid angle. Where both
// lobes are exact, eval = sum_k e_k pdf_k and the weight eval / pdf is a mix of the lobes' colours: with the
// weighted p_R the path's channel sum never grows. With the truncated normal alone every event would
// multiply the path by (Z / G) cos^2 theta_o, a grey factor of mean one whose product over the tens of
// events of a cotton walk spreads over orders of magnitude (fireflies in the explicit-fiber reference;
// tests/cpp/test_fiber_bsdf.cpp measures both).
//
// von Mises concentration: kappa = 1 / gamma_TT^2, as the paper writes f(.; ., gamma^-2). For small
// gamma this von Mises equals a wrapped normal of standard deviation gamma to O(gamma^4); the authors'
// code uses a Gaussian of standard deviation gamma. docs/decisions.md compares the two.
#pragma once

#include "frames.h"
#include "longitudinal.h"
#include "platform.h"
#include "sampling.h"

namespace ny {

/* Fiber parameters in the units the kernel uses (radians). Host code converts presets (degrees). */
struct FiberBsdfParams {
  Rgb C_R;        /* attenuation of reflection (Schlick F0), in [0, 1] */
  Rgb C_TT;       /* attenuation of transmission, in [0, 1]            */
  float beta_R;   /* longitudinal std. deviation of R, radians, > 0    */
  float beta_TT;  /* longitudinal std. deviation of TT, radians, > 0   */
  float gamma_TT; /* azimuthal width of TT, radians, > 0               */
};

/* Everything that depends on w_i only, computed once per shading point. */
struct FiberLobes {
  float theta_i, phi_i, cos_theta_i;
  Rgb energy_R;  /* F = F_R(theta_i), Schlick: the R lobe's share of the albedo */
  Rgb energy_TT; /* (1 - F) C_TT                            */
  float p_R;     /* probability of sampling R               */
  float kappa_TT;
  LongitudinalLobe m_R, m_TT; /* gbar with their normalisers */
  TruncatedNormal tn_R, tn_TT; /* the sampling densities    */
};

NY_KERNEL_FN Rgb schlick_fresnel(Rgb C_R, float cos_theta)
{
  const float f = pow5(1.0f - clampf(cos_theta, 0.0f, 1.0f));
  return C_R + (make_rgb(1.0f) - C_R) * f;
}

/* Probability of sampling R from the lobes' energies e_R = F and e_TT = (1 - F) C_TT: by their channel means. */
NY_KERNEL_FN float fiber_probability_R(Rgb e_R, Rgb e_TT)
{
  const float a_R = average(e_R);
  const float a_TT = average(e_TT);
  return (a_R + a_TT > 0.0f) ? a_R / (a_R + a_TT) : 0.0f;
}

/* The same with the energies weighted by the path's throughput (see the top of this file); a throughput that
 * weights nothing (zero, NaN, infinite) falls back to the channel means. */
NY_KERNEL_FN float fiber_probability_R(Rgb e_R, Rgb e_TT, Rgb throughput)
{
  const float a_R = throughput.r * e_R.r + throughput.g * e_R.g + throughput.b * e_R.b;
  const float a_TT = throughput.r * e_TT.r + throughput.g * e_TT.g + throughput.b * e_TT.b;
  const float a = a_R + a_TT;
  return (a > 0.0f && a < kFloatMax) ? a_R / a : fiber_probability_R(e_R, e_TT);
}

/* The lobes' energies at incidence w_i: e_R = F and e_TT = (1 - F) C_TT (their sum is the albedo). */
NY_KERNEL_FN void fiber_energies(NY_PRIVATE const FiberBsdfParams &p, Vec3 wi, NY_PRIVATE Rgb *e_R,
                                 NY_PRIVATE Rgb *e_TT)
{
  *e_R = schlick_fresnel(p.C_R, cos_theta(wi));
  *e_TT = (make_rgb(1.0f) - *e_R) * p.C_TT;
}

/* The w_i-dependent setup. `with_eval` = false skips the two cos^2 normalisers, which eval, pdf and sample need
 * (they are the expensive part: up to 2 x 32 exp/cos); m_R and m_TT are then left zero. */
NY_KERNEL_FN FiberLobes fiber_lobes(NY_PRIVATE const FiberBsdfParams &p, Vec3 wi, bool with_eval = true)
{
  FiberLobes l;
  l.cos_theta_i = cos_theta(wi);
  l.theta_i = theta_of(wi);
  l.phi_i = phi_of(wi);
  fiber_energies(p, wi, &l.energy_R, &l.energy_TT);
  l.p_R = fiber_probability_R(l.energy_R, l.energy_TT);
  l.kappa_TT = 1.0f / (p.gamma_TT * p.gamma_TT);
  const float mu = -l.theta_i;
  if (with_eval) {
    l.m_R = make_longitudinal_lobe(mu, p.beta_R);
    l.m_TT = make_longitudinal_lobe(mu, p.beta_TT);
  }
  else {
    l.m_R = LongitudinalLobe{mu, p.beta_R, 0.0f};
    l.m_TT = LongitudinalLobe{mu, p.beta_TT, 0.0f};
  }
  l.tn_R = make_truncated_normal(mu, p.beta_R, -kHalfPi, kHalfPi);
  l.tn_TT = make_truncated_normal(mu, p.beta_TT, -kHalfPi, kHalfPi);
  return l;
}

/* Albedo: integral of eval over the sphere, F + (1 - F) C_TT. */
NY_KERNEL_FN Rgb fiber_albedo(NY_PRIVATE const FiberLobes &l) { return l.energy_R + l.energy_TT; }


/* Rejection sampling of theta_o (see the top of this file) where its acceptance rate is at least this; a
 * loop that ran kFiberExactMaxRounds proposals (probability below 0.8^64 = 6e-7) returns no sample. */
constexpr float kFiberExactMinAcceptance = 0.2f;
constexpr int kFiberExactMaxRounds = 64;

/* Whether lobe (m, tn) draws theta_o exactly from gbar cos^2: its acceptance rate G / Z = 1 / (beta G^-1 Z)
 * is at least kFiberExactMinAcceptance. Needs the lobe's normaliser (fiber_lobes with eval). */
NY_KERNEL_FN bool fiber_lobe_exact(NY_PRIVATE const LongitudinalLobe &m, NY_PRIVATE const TruncatedNormal &tn)
{
  return m.inv_beta_G > 0.0f && m.beta * m.inv_beta_G * tn.mass * kFiberExactMinAcceptance <= 1.0f;
}

/* Lobe k's sampling density of theta_o. */
NY_KERNEL_FN float fiber_theta_pdf(NY_PRIVATE const LongitudinalLobe &m, NY_PRIVATE const TruncatedNormal &tn,
                                   float theta)
{
  if (fiber_lobe_exact(m, tn)) {
    const float c = cosf(theta);
    return longitudinal_eval(m, theta) * c * c;
  }
  return truncated_normal_pdf(tn, theta);
}

/* Smallest cos(theta_o) used to convert a (theta, phi) density to solid angle: the density is then
 * finite (if huge) at the poles, where eval is zero. */
constexpr float kFiberMinCosTheta = 1e-7f;

/* Requires lobes set up with eval (the exact branch's density needs the normalisers). */
NY_KERNEL_FN float fiber_pdf_lobes(NY_PRIVATE const FiberLobes &l, Vec3 wo)
{
  if (!(l.p_R > 0.0f) && !(average(l.energy_TT) > 0.0f)) {
    return 0.0f;
  }
  const float theta_o = theta_of(wo);
  const float phi_o = phi_of(wo);
  const float pdf_R = fiber_theta_pdf(l.m_R, l.tn_R, theta_o) * kInvTwoPi;
  const float pdf_TT = fiber_theta_pdf(l.m_TT, l.tn_TT, theta_o) *
                       von_mises_pdf(wrap_angle(phi_o - l.phi_i - kPi), l.kappa_TT);
  const float pdf = l.p_R * pdf_R + (1.0f - l.p_R) * pdf_TT;
  return pdf / maxf(cos_theta(wo), kFiberMinCosTheta);
}

NY_KERNEL_FN Rgb fiber_eval_lobes(NY_PRIVATE const FiberLobes &l, Vec3 wo)
{
  const float theta_o = theta_of(wo);
  const float phi_o = phi_of(wo);
  const float cos_o = cos_theta(wo);
  const float s_R = longitudinal_eval(l.m_R, theta_o) * kInvTwoPi;
  const float s_TT = longitudinal_eval(l.m_TT, theta_o) *
                     von_mises_pdf(wrap_angle(phi_o - l.phi_i - kPi), l.kappa_TT);
  return (l.energy_R * s_R + l.energy_TT * s_TT) * cos_o;
}

/* eval = S_f(w_i, w_o) cos(theta_o); optionally also returns the sampling pdf of w_o. */
NY_KERNEL_FN Rgb fiber_eval(NY_PRIVATE const FiberBsdfParams &p, Vec3 wi, Vec3 wo, NY_PRIVATE float *pdf)
{
  const FiberLobes l = fiber_lobes(p, wi);
  if (pdf) {
    *pdf = fiber_pdf_lobes(l, wo);
  }
  return fiber_eval_lobes(l, wo);
}

NY_KERNEL_FN float fiber_pdf(NY_PRIVATE const FiberBsdfParams &p, Vec3 wi, Vec3 wo)
{
  return fiber_pdf_lobes(fiber_lobes(p, wi), wo);
}

/* Draws w_o from the lobes set up for w_i (with eval), given three uniform numbers in [0, 1) and a generator
 * `next()` of further ones for the rejection loop. Returns false (and zero weight) when the fiber scatters
 * nothing (C_R = C_TT = 0 at this angle) or the loop ran out. */
template<class Uniform>
NY_KERNEL_FN bool fiber_sample_lobes(NY_PRIVATE const FiberLobes &l,
                                     float u_lobe,
                                     float u_theta,
                                     float u_phi,
                                     NY_PRIVATE Uniform &&next,
                                     NY_PRIVATE Vec3 *wo,
                                     NY_PRIVATE Rgb *weight,
                                     NY_PRIVATE float *pdf)
{
  const float e_TT = average(l.energy_TT);
  *weight = make_rgb(0.0f);
  *pdf = 0.0f;
  if (!(l.p_R > 0.0f) && !(e_TT > 0.0f)) {
    return false;
  }
  const bool lobe_R = u_lobe < l.p_R;
  NY_PRIVATE const LongitudinalLobe &m = lobe_R ? l.m_R : l.m_TT;
  NY_PRIVATE const TruncatedNormal &tn = lobe_R ? l.tn_R : l.tn_TT;
  float theta_o = sample_truncated_normal(tn, u_theta);
  if (fiber_lobe_exact(m, tn)) {
    for (int round = 1;; round++) {
      const float c = cosf(theta_o);
      if (next() < c * c) {
        break;
      }
      if (round == kFiberExactMaxRounds) {
        return false;
      }
      theta_o = sample_truncated_normal(tn, next());
    }
  }
  float phi_o;
  if (lobe_R) {
    /* R: azimuth uniform. */
    phi_o = kTwoPi * u_phi - kPi;
  }
  else {
    /* TT: azimuth von Mises about the forward direction. The lobe-selection number, rescaled to [0, 1),
     * is the von Mises acceptance variate. */
    const float u_reuse = clampf((u_lobe - l.p_R) / (1.0f - l.p_R), 0.0f, 0.99999994f);
    phi_o = l.phi_i + kPi + sample_von_mises(l.kappa_TT, u_phi, u_reuse);
  }
  *wo = direction_from_angles(theta_o, phi_o);
  *pdf = fiber_pdf_lobes(l, *wo);
  if (!(*pdf > 0.0f)) {
    return false;
  }
  /* Divide per channel rather than multiply by 1/pdf: the ratio is bounded even where 1/pdf is not. */
  const Rgb f = fiber_eval_lobes(l, *wo);
  *weight = make_rgb(f.r / *pdf, f.g / *pdf, f.b / *pdf);
  return true;
}

template<class Uniform>
NY_KERNEL_FN bool fiber_sample(NY_PRIVATE const FiberBsdfParams &p,
                               Vec3 wi,
                               float u_lobe,
                               float u_theta,
                               float u_phi,
                               NY_PRIVATE Uniform &&next,
                               NY_PRIVATE Vec3 *wo,
                               NY_PRIVATE Rgb *weight,
                               NY_PRIVATE float *pdf)
{
  return fiber_sample_lobes(fiber_lobes(p, wi), u_lobe, u_theta, u_phi, next, wo, weight, pdf);
}

}  // namespace ny
