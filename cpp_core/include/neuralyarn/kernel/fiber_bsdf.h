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
// Sampling is exact and matches pdf: the lobe is chosen with probability
//   p_R = mean(F) / (mean(F) + mean((1 - F) C_TT)),
// theta_o from the truncated normal N(-theta_i, beta_k) on [-pi/2, pi/2] by inverse CDF, and the azimuth
// uniformly (R) or from the von Mises (TT). The pdf is the density of that mixture,
//   pdf = [p_R TN_R(theta_o) / (2 pi) + (1 - p_R) TN_TT(theta_o) vM(phi_o - phi_i - pi)] / cos theta_o,
// the 1 / cos theta_o converting from (theta, phi) to solid angle. The sample weight is therefore
// bounded: the truncated normal is proportional to g, so eval / pdf ~ (Z_TN / G) cos^2 theta_o.
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
  Rgb F;       /* Schlick Fresnel F_R(theta_i)            */
  Rgb energy_R;  /* F: the R lobe's share of the albedo     */
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

/* The w_i-dependent setup. `with_eval` = false skips the two cos^2 normalisers, which only eval needs
 * (they are the expensive part: up to 2 x 32 exp/cos); m_R and m_TT are then left zero. */
NY_KERNEL_FN FiberLobes fiber_lobes(const FiberBsdfParams &p, Vec3 wi, bool with_eval = true)
{
  FiberLobes l;
  l.cos_theta_i = cos_theta(wi);
  l.theta_i = theta_of(wi);
  l.phi_i = phi_of(wi);
  l.F = schlick_fresnel(p.C_R, l.cos_theta_i);
  l.energy_R = l.F;
  l.energy_TT = (make_rgb(1.0f) - l.F) * p.C_TT;
  const float e_R = average(l.energy_R);
  const float e_TT = average(l.energy_TT);
  l.p_R = (e_R + e_TT > 0.0f) ? e_R / (e_R + e_TT) : 0.0f;
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
NY_KERNEL_FN Rgb fiber_albedo(const FiberLobes &l) { return l.energy_R + l.energy_TT; }

/* Smallest cos(theta_o) used to convert a (theta, phi) density to solid angle: the density is then
 * finite (if huge) at the poles, where eval is zero. */
constexpr float kFiberMinCosTheta = 1e-7f;

NY_KERNEL_FN float fiber_pdf_lobes(const FiberLobes &l, Vec3 wo)
{
  if (!(l.p_R > 0.0f) && !(average(l.energy_TT) > 0.0f)) {
    return 0.0f;
  }
  const float theta_o = theta_of(wo);
  const float phi_o = phi_of(wo);
  const float pdf_R = truncated_normal_pdf(l.tn_R, theta_o) * kInvTwoPi;
  const float pdf_TT = truncated_normal_pdf(l.tn_TT, theta_o) *
                       von_mises_pdf(wrap_angle(phi_o - l.phi_i - kPi), l.kappa_TT);
  const float pdf = l.p_R * pdf_R + (1.0f - l.p_R) * pdf_TT;
  return pdf / fmaxf(cos_theta(wo), kFiberMinCosTheta);
}

NY_KERNEL_FN Rgb fiber_eval_lobes(const FiberLobes &l, Vec3 wo)
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
NY_KERNEL_FN Rgb fiber_eval(const FiberBsdfParams &p, Vec3 wi, Vec3 wo, float *pdf)
{
  const FiberLobes l = fiber_lobes(p, wi);
  if (pdf) {
    *pdf = fiber_pdf_lobes(l, wo);
  }
  return fiber_eval_lobes(l, wo);
}

NY_KERNEL_FN float fiber_pdf(const FiberBsdfParams &p, Vec3 wi, Vec3 wo)
{
  return fiber_pdf_lobes(fiber_lobes(p, wi, false), wo);
}

/* Draws w_o given three uniform numbers in [0, 1). Returns false (and zero weight) when the fiber
 * scatters nothing (C_R = C_TT = 0 at this angle). */
NY_KERNEL_FN bool fiber_sample(const FiberBsdfParams &p,
                               Vec3 wi,
                               float u_lobe,
                               float u_theta,
                               float u_phi,
                               Vec3 *wo,
                               Rgb *weight,
                               float *pdf)
{
  const FiberLobes l = fiber_lobes(p, wi);
  const float e_TT = average(l.energy_TT);
  *weight = make_rgb(0.0f);
  *pdf = 0.0f;
  if (!(l.p_R > 0.0f) && !(e_TT > 0.0f)) {
    return false;
  }
  float theta_o, phi_o;
  if (u_lobe < l.p_R) {
    /* R: azimuth uniform. */
    theta_o = sample_truncated_normal(l.tn_R, u_theta);
    phi_o = kTwoPi * u_phi - kPi;
  }
  else {
    /* TT: azimuth von Mises about the forward direction. The lobe-selection number, rescaled to [0, 1),
     * is the von Mises acceptance variate. */
    const float u_reuse = clampf((u_lobe - l.p_R) / (1.0f - l.p_R), 0.0f, 0.99999994f);
    theta_o = sample_truncated_normal(l.tn_TT, u_theta);
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

}  // namespace ny
