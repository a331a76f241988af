// SPDX-License-Identifier: Apache-2.0
//
// Special functions needed by the exact samplers: erfc, the standard normal CDF and its inverse, and the
// exponentially scaled modified Bessel function I0 (the von Mises normaliser).
//
// Accuracy (checked against Boost.Math in double by tests/cpp/test_special.cpp): a few float ulps for
// erfc, Phi and Phi^-1 over their whole range including the far tails, about 5e-7 relative for I0e.
#pragma once

#include "platform.h"

namespace ny {

/* Standard normal density. */
NY_KERNEL_FN float normal_pdf(float z) { return kInvSqrtTwoPi * expf(-0.5f * z * z); }

/* The same with the kernel's own exp (fast_exp, within 1.3 float ulps of exp): no library call, so that a loop of
 * it vectorises (the R nodes' lanes, yarn_R_lanes). */
NY_KERNEL_FN float normal_pdf_lanes(float z) { return kInvSqrtTwoPi * fast_exp(-0.5f * z * z); }

/* erfc(x) without libm's erfcf, which takes two exponentials per call and was a fifth of the yarn closure's
 * per-shading-point work (docs/decisions.md D59). For a = |x|, h(a) = (1 + 2a) exp(a^2) erfc(a) runs smoothly
 * from 1 to 2 / sqrt(pi) over [0, inf): h = 1 + (1 + t) Q(t) with t = (a - 2) / (a + 2) and Q of degree 8, in
 * Estrin's form, holds it to 1.3e-8 relative (scripts/make_erfc_fit.py), so erfc(a) = exp(-a^2) h / (1 + 2a)
 * keeps full relative precision deep into the tail, erfc(0) is 1 exactly, and erfc(-a) = 2 - erfc(a). Past
 * a = 10.1 erfc is below float's smallest denormal. */
/* Past this |x| erfc(x) is below float's smallest denormal: fast_erfc and erfc_lanes return 0 (or 2) there. */
constexpr float kErfcCut = 10.1f;

/* erfc(a) for 0 <= a < kErfcCut, the body of fast_erfc and erfc_lanes: exp(-a^2) by libm's expf (kLanes false) or the
 * kernel's fast_exp (true). */
template<bool kLanes> NY_KERNEL_FN float erfc_nonnegative(float a)
{
  const float r = 1.0f / (a + 2.0f);
  const float t = (a - 2.0f) * r, one_plus_t = 2.0f * a * r;
  const float t2 = t * t, t4 = t2 * t2;
  const float Q = ((0.276978403f - 0.369742364f * t) + t2 * (0.203710958f - 0.0396555625f * t)) +
                  t4 * ((-0.0145488139f + 0.00648865988f * t) + t2 * (0.00214332598f - 0.000829156081f * t)) -
                  0.000401109864f * (t4 * t4);
  const float h = 1.0f + one_plus_t * Q;
  /* exp(-a^2) with a^2 = s + d split exactly (Dekker: a's upper 12 significand bits squared are exact), as
   * exp(-s) (1 - d): the rounding of a^2 alone costs up to a^2 ulps, 64 at a = 9. */
  const float s = a * a;
  const float a_hi = float_from_bits(float_bits(a) & 0xfffff000u), a_lo = a - a_hi;
  const float d = ((a_hi * a_hi - s) + 2.0f * a_hi * a_lo) + a_lo * a_lo;
  const float ex = kLanes ? fast_exp(-s) : expf(-s);
  return h / (1.0f + 2.0f * a) * (ex * (1.0f - d));
}

NY_KERNEL_FN float fast_erfc(float x)
{
  const float a = fabsf(x);
  if (!(a < kErfcCut)) {
    return x < 0.0f ? 2.0f : (a == a ? 0.0f : x); /* NaN stays NaN */
  }
  const float e = erfc_nonnegative<false>(a);
  return x < 0.0f ? 2.0f - e : e;
}

/* fast_erfc with the kernel's exp and without branches, for loops that run lanes side by side (the R nodes'
 * truncated normals, yarn_lobes): within a few float ulps of it (tests/cpp/test_special.cpp). Past kErfcCut it
 * is 0 or 2 as fast_erfc; a NaN gives some number. */
NY_KERNEL_FN float erfc_lanes(float x)
{
  const float a = fabsf(x);
  const float e = erfc_nonnegative<true>(a < kErfcCut ? a : kErfcCut);
  const float e_cut = a < kErfcCut ? e : 0.0f;
  return x < 0.0f ? 2.0f - e_cut : e_cut;
}

/* Phi(z) = P(Z <= z). Written with erfc so that the lower tail keeps full relative precision down to
 * about z = -13 (where erf-based 0.5 * (1 + erf) would already have cancelled to zero at z = -5.5). */
NY_KERNEL_FN float normal_cdf(float z) { return 0.5f * fast_erfc(-z * kInvSqrt2); }

/* 1 - Phi(z) = Phi(-z), accurate in the upper tail. */
NY_KERNEL_FN float normal_ccdf(float z) { return 0.5f * fast_erfc(z * kInvSqrt2); }

/* Phi^-1(p) by Wichura's algorithm AS 241 (PPND16, Applied Statistics 37(3), 1988): rational
 * approximations in three regions, relative accuracy ~1e-16 in double and therefore float-exact here.
 * The core works on a tail mass p <= 1/2 and returns the lower-tail quantile, or its negation (the
 * upper-tail quantile) when `negate` is set: callers that know the upper tail mass q = 1 - p pass q
 * itself, so that quantiles near +inf keep their precision (forming 1 - q would round it away). */
NY_KERNEL_FN float normal_quantile_impl(float p_lower_tail, bool negate)
{
  /* p_lower_tail <= 0.5 here; the result is -x for the lower tail, x for the upper tail (negate). */
  const float p = p_lower_tail;
  float x;
  const float q = p - 0.5f;
  if (fabsf(q) <= 0.425f) {
    const float r = 0.180625f - q * q;
    x = q *
        (((((((2509.0809287301226727f * r + 33430.575583588128105f) * r + 67265.770927008700853f) * r +
             45921.953931549871457f) * r + 13731.693765509461125f) * r + 1971.5909503065514427f) * r +
          133.14166789178437745f) * r + 3.387132872796366608f) /
        (((((((5226.495278852854561f * r + 28729.085735721942674f) * r + 39307.89580009271061f) * r +
             21213.794301586595867f) * r + 5394.1960214247511077f) * r + 687.1870074920579083f) * r +
          42.313330701600911252f) * r + 1.0f);
  }
  else {
    float r = sqrtf(-logf(p));
    if (r <= 5.0f) {
      r -= 1.6f;
      x = (((((((7.7454501427834140764e-4f * r + 0.0227238449892691845833f) * r +
                0.24178072517745061177f) * r + 1.27045825245236838258f) * r +
              3.64784832476320460504f) * r + 5.7694972214606914055f) * r + 4.6303378461565452959f) * r +
           1.42343711074968357734f) /
          (((((((1.05075007164441684324e-9f * r + 5.475938084995344946e-4f) * r +
                0.0151986665636164571966f) * r + 0.14810397642748007459f) * r +
              0.68976733498510000455f) * r + 1.6763848301838038494f) * r + 2.05319162663775882187f) * r +
           1.0f);
    }
    else {
      r -= 5.0f;
      x = (((((((2.01033439929228813265e-7f * r + 2.71155556874348757815e-5f) * r +
                1.24266094738807843860e-3f) * r + 2.65321895265761230930e-2f) * r +
              2.96560571828504891230e-1f) * r + 1.78482653991729133580f) * r + 5.46378491116411436990f) * r +
           6.65790464350110377720f) /
          (((((((2.04426310338993978564e-15f * r + 1.42151175831644588870e-7f) * r +
                1.84631831751005468180e-5f) * r + 7.86869131145613259100e-4f) * r +
              1.48753612908506148525e-2f) * r + 1.36929880922735805310e-1f) * r +
            5.99832206555887937690e-1f) * r + 1.0f);
    }
    x = -x; /* lower tail: negative quantile */
  }
  return negate ? -x : x;
}

/* Phi^-1(p) for a lower-tail probability p. */
NY_KERNEL_FN float normal_quantile(float p)
{
  if (!(p > 0.0f)) {
    return -NY_INFINITY;
  }
  if (!(p < 1.0f)) {
    return NY_INFINITY;
  }
  return (p <= 0.5f) ? normal_quantile_impl(p, false) : normal_quantile_impl(1.0f - p, true);
}

/* Phi^-1(1 - q) given the upper-tail probability q, without forming 1 - q. */
NY_KERNEL_FN float normal_quantile_upper(float q)
{
  if (!(q > 0.0f)) {
    return NY_INFINITY;
  }
  if (!(q < 1.0f)) {
    return -NY_INFINITY;
  }
  return (q <= 0.5f) ? normal_quantile_impl(q, true) : normal_quantile_impl(1.0f - q, false);
}

/* I0e(x) = exp(-x) I0(x) for x >= 0 (Abramowitz & Stegun 9.8.1 and 9.8.2; |rel. error| < 5e-7).
 * The scaled form never overflows, which matters for narrow von Mises lobes (kappa in the thousands). */
NY_KERNEL_FN float bessel_i0e(float x)
{
  x = fabsf(x);
  if (x < 3.75f) {
    const float t = sqr(x * (1.0f / 3.75f));
    const float i0 =
        1.0f + t * (3.5156229f + t * (3.0899424f + t * (1.2067492f + t * (0.2659732f + t * (0.0360768f + t * 0.0045813f)))));
    return i0 * expf(-x);
  }
  const float t = 3.75f / x;
  const float p = 0.39894228f +
                  t * (0.01328592f +
                       t * (0.00225319f +
                            t * (-0.00157565f +
                                 t * (0.00916281f +
                                      t * (-0.02057706f + t * (0.02635537f + t * (-0.01647633f + t * 0.00392377f)))))));
  return p / sqrtf(x);
}

}  // namespace ny
