// SPDX-License-Identifier: Apache-2.0
//
// The kernel's float special functions against Boost.Math in double.
#include <cfloat>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include <boost/math/distributions/normal.hpp>
#include <boost/math/special_functions/bessel.hpp>
#include <boost/math/special_functions/erf.hpp>
#include <gtest/gtest.h>

#include "neuralyarn/kernel/special.h"
#include "neuralyarn/units.h"

using neuralyarn::kPi;

namespace {

const boost::math::normal_distribution<double> kStd(0.0, 1.0);

double rel_err(double got, double want) { return std::fabs(got - want) / std::fabs(want); }

TEST(Special, NormalCdfMatchesBoostIncludingFarTails)
{
  /* Relative accuracy in the lower tail down to z = -13 (Phi = 6e-39, just above float's normal range
   * ends at 1.2e-38; below that denormals lose digits and we stop). */
  for (double zd = -12.5; zd <= 8.0; zd += 0.01) {
    /* Reference at the float argument: the tail amplifies an argument error by |z|. */
    const double z = double(float(zd));
    const double want = boost::math::cdf(kStd, z);
    /* Phi's relative condition number in the tail is ~z^2, so the float rounding of z / sqrt(2) alone
     * costs z^2 * 6e-8: that, plus a few ulps, is the tolerance. */
    const double tol = 2e-6 + 1.2e-7 * z * z;
    EXPECT_LT(rel_err(ny::normal_cdf(float(z)), want), tol) << "z = " << z;
    const double want_c = boost::math::cdf(boost::math::complement(kStd, z));
    if (z > -8.0) {
      EXPECT_LT(rel_err(ny::normal_ccdf(float(z)), want_c), tol) << "z = " << z;
    }
  }
}

TEST(Special, NormalQuantileMatchesBoostOverAllMagnitudes)
{
  /* Log-spaced tail masses from 1e-37 to 0.5 exercise all three AS241 regions. */
  for (double lg = -37.0; lg <= std::log10(0.5); lg += 0.05) {
    const double p = std::pow(10.0, lg);
    const float pf = float(p);
    const double want = boost::math::quantile(kStd, double(pf));
    EXPECT_LT(rel_err(ny::normal_quantile(pf), want), 2e-6) << "p = " << p;
    /* Upper-tail form: Phi^-1(1 - q) = -Phi^-1(q). */
    EXPECT_LT(rel_err(ny::normal_quantile_upper(pf), -want), 2e-6) << "q = " << p;
  }
  for (double p = 0.01; p < 1.0; p += 0.01) {
    const float pf = float(p);
    const double want = boost::math::quantile(kStd, double(pf));
    EXPECT_NEAR(ny::normal_quantile(pf), want, 2e-6 * std::max(1.0, std::fabs(want))) << "p = " << p;
  }
  EXPECT_EQ(ny::normal_quantile(0.0f), -INFINITY);
  EXPECT_EQ(ny::normal_quantile(1.0f), INFINITY);
  EXPECT_EQ(ny::normal_quantile_upper(0.0f), INFINITY);
}

TEST(Special, QuantileInvertsCdf)
{
  for (float z = -9.0f; z <= 9.0f; z += 0.125f) {
    const float back = (z <= 0.0f) ? ny::normal_quantile(ny::normal_cdf(z)) : ny::normal_quantile_upper(ny::normal_ccdf(z));
    EXPECT_NEAR(back, z, 2e-5f * std::max(1.0f, std::fabs(z))) << "z = " << z;
  }
}

TEST(Special, ScaledBesselI0MatchesBoost)
{
  for (double lg = -6.0; lg <= 7.0; lg += 0.01) {
    const double x = double(float(std::pow(10.0, lg)));
    /* exp(-x) I0(x) evaluated stably: Boost's I0 overflows past x ~ 700, use the asymptotic ratio there. */
    double want;
    if (x < 600.0) {
      want = std::exp(-x) * boost::math::cyl_bessel_i(0.0, x);
    }
    else {
      const double t = 1.0 / (8.0 * x);
      want = (1.0 + t + 9.0 * t * t / 2.0 + 225.0 * t * t * t / 6.0) / std::sqrt(2.0 * kPi * x);
    }
    EXPECT_LT(rel_err(ny::bessel_i0e(float(x)), want), 1e-6) << "x = " << x;
  }
  EXPECT_FLOAT_EQ(ny::bessel_i0e(0.0f), 1.0f);
}

/* fast_exp against double exp over its whole float range, stepping through the floats' bit patterns (every
 * 211th, ~10^7 arguments, each binade sampled alike): within 2 ulps of the result where it is a normal float
 * (measured over every float: 1.3), within one smallest denormal below, +inf past ln(FLT_MAX); and the points
 * callers rely on exactly. */
TEST(Special, FastExpIsWithinTwoUlpsOverTheFloatRange)
{
  double worst = 0.0;
  auto check = [&](float x) {
    const double want = std::exp(double(x));
    const float got = ny::fast_exp(x);
    if (want > double(FLT_MAX)) {
      ASSERT_TRUE(std::isinf(got) && got > 0.0f) << "exp(" << x << ")";
    }
    else if (want < double(FLT_MIN)) {
      ASSERT_LE(std::fabs(double(got) - want), double(std::numeric_limits<float>::denorm_min())) << "exp(" << x << ")";
    }
    else {
      const double ulp = std::ldexp(1.0, std::ilogb(want) - 23);
      const double err = std::fabs(double(got) - want) / ulp;
      worst = std::max(worst, err);
      ASSERT_LE(err, 2.0) << "exp(" << x << ")";
    }
  };
  const uint32_t kStride = 211;
  for (uint32_t u = 0; u <= ny::float_bits(110.0f); u += kStride) {
    check(ny::float_from_bits(u));              /* 0 .. 110 */
    check(-ny::float_from_bits(u));             /* -110 .. 0 */
  }
  RecordProperty("worst_ulps", std::to_string(worst));
  EXPECT_EQ(ny::fast_exp(0.0f), 1.0f);
  EXPECT_EQ(ny::fast_exp(-INFINITY), 0.0f);
  EXPECT_EQ(ny::fast_exp(INFINITY), INFINITY);
  EXPECT_EQ(ny::fast_exp(-200.0f), 0.0f);
  EXPECT_TRUE(std::isnan(ny::fast_exp(NAN)));
  /* The network's exp head clamps at kMlpMaxExpArgument: that value must be finite. */
  EXPECT_TRUE(std::isfinite(ny::fast_exp(80.0f)));
}

/* An erfc against Boost's in double over every 97th float in [-11, 11]: within 6 ulps where erfc is a normal float,
 * within two smallest denormals below; the worst error in ulps and where, as "<ulps> at <x>". */
template<class Erfc> std::string check_erfc_against_boost(Erfc erfc, const char *name)
{
  double worst = 0.0;
  float worst_x = 0.0f;
  auto check = [&](float x) {
    const double want = boost::math::erfc(double(x));
    const float got = erfc(x);
    if (want < double(FLT_MIN)) {
      ASSERT_LE(std::fabs(double(got) - want), 2.0 * double(std::numeric_limits<float>::denorm_min()))
          << name << "(" << x << ")";
      return;
    }
    const double err = std::fabs(double(got) - want) / std::ldexp(1.0, std::ilogb(want) - 23);
    if (err > worst) {
      worst = err;
      worst_x = x;
    }
    ASSERT_LE(err, 6.0) << name << "(" << x << ")";
  };
  for (uint32_t u = 0; u <= ny::float_bits(11.0f); u += 97) {
    check(ny::float_from_bits(u));
    check(-ny::float_from_bits(u));
  }
  return std::to_string(worst) + " at " + std::to_string(worst_x);
}

/* fast_erfc against Boost's erfc in double over every 97th float in [-11, 11] (~2*10^7 arguments, each binade
 * sampled alike): within 6 ulps where erfc is a normal float (measured: 4.7 at a ~ 1.6 with the host's and with
 * Cycles' float flags; libm's erfcf 3.1), within two smallest denormals below; erfc(0) = 1 exactly, the cut-offs
 * and NaN. Dropping the exact split of a^2 costs 64 ulps at a = 9, a coefficient off in its fifth digit 97. */
TEST(Special, FastErfcIsWithinSixUlpsOverTheFloatRange)
{
  RecordProperty("worst_ulps", check_erfc_against_boost(ny::fast_erfc, "erfc"));
  EXPECT_EQ(ny::fast_erfc(0.0f), 1.0f);
  EXPECT_EQ(ny::fast_erfc(INFINITY), 0.0f);
  EXPECT_EQ(ny::fast_erfc(-INFINITY), 2.0f);
  EXPECT_EQ(ny::fast_erfc(10.1f), 0.0f);
  EXPECT_EQ(ny::fast_erfc(-10.1f), 2.0f);
  EXPECT_TRUE(std::isnan(ny::fast_erfc(NAN)));
}

/* erfc_lanes (the kernel's exp, no branches; the R nodes' truncated normals in yarn_lobes) against Boost as
 * fast_erfc above, over the same floats: within 6 ulps where erfc is a normal float (measured 5.0 at x = 3.66,
 * fast_erfc 4.7: fast_exp's error adds little to the polynomial's), two smallest denormals below; the same cut-offs.
 * Using fast_exp without the exact split of a^2 fails it (64 ulps at a = 9). */
TEST(Special, ErfcLanesIsWithinSixUlpsOverTheFloatRange)
{
  RecordProperty("worst_ulps", check_erfc_against_boost(ny::erfc_lanes, "erfc_lanes"));
  EXPECT_EQ(ny::erfc_lanes(0.0f), 1.0f);
  EXPECT_EQ(ny::erfc_lanes(10.1f), 0.0f);
  EXPECT_EQ(ny::erfc_lanes(-10.1f), 2.0f);
  EXPECT_EQ(ny::erfc_lanes(INFINITY), 0.0f);
  EXPECT_EQ(ny::erfc_lanes(-INFINITY), 2.0f);
}

/* sincos_lanes against double sin and cos over [-16, 16] (every 31st float, ~10^8 / 31 arguments, each binade
 * alike): within 2 ulps of each result, or 6e-8 (half an ulp of 1) absolute where the result is smaller than
 * that allows (near the zeros, where the reduction's r carries the absolute error of pi/2's three parts). The
 * quadrant selection is checked by the signs at the four axes. A wrong quadrant or a two-part pi/2 fails it. */
TEST(Special, SincosLanesIsWithinTwoUlps)
{
  double worst = 0.0;
  auto check = [&](float a) {
    float s, c;
    ny::sincos_lanes(a, s, c);
    const double want[2] = {std::sin(double(a)), std::cos(double(a))};
    const float got[2] = {s, c};
    for (int k = 0; k < 2; k++) {
      const double err = std::fabs(double(got[k]) - want[k]);
      const double ulp = std::ldexp(1.0, std::ilogb(std::max(std::fabs(want[k]), 1e-30)) - 23);
      if (std::fabs(want[k]) > 1e-3) {
        worst = std::max(worst, err / ulp);
      }
      ASSERT_TRUE(err <= 2.0 * ulp || err <= 6e-8) << (k ? "cos(" : "sin(") << a << "): " << got[k] << " against "
                                                   << want[k];
    }
  };
  for (uint32_t u = 0; u <= ny::float_bits(16.0f); u += 31) {
    check(ny::float_from_bits(u));
    check(-ny::float_from_bits(u));
  }
  RecordProperty("worst_ulps", std::to_string(worst));
  for (int k = -8; k <= 8; k++) {
    const float a = float(k) * float(M_PI / 2);
    float s, c;
    ny::sincos_lanes(a, s, c);
    const int n = ((k % 4) + 4) % 4;
    EXPECT_NEAR(s, n == 1 ? 1.0f : n == 3 ? -1.0f : 0.0f, 1e-6f) << k;
    EXPECT_NEAR(c, n == 0 ? 1.0f : n == 2 ? -1.0f : 0.0f, 1e-6f) << k;
  }
}

/* wrap_angle_lanes is wrap_angle, bit for bit, over its range [-pi, 3 pi) (every 7th float of each sign up to 3 pi,
 * the bounds and the points where fmodf's result wraps). */
TEST(Special, WrapAngleLanesIsWrapAngle)
{
  auto check = [](float a) {
    ASSERT_EQ(ny::float_bits(ny::wrap_angle_lanes(a)), ny::float_bits(ny::wrap_angle(a))) << a;
  };
  for (uint32_t u = 0; u <= ny::float_bits(3.0f * float(M_PI)); u += 7) {
    const float a = ny::float_from_bits(u);
    if (a < 3.0f * ny::kPi) {
      check(a);
    }
    if (a <= ny::kPi) {
      check(-a);
    }
  }
  for (float a : {-ny::kPi, 0.0f, ny::kPi, std::nextafter(ny::kPi, 0.0f), std::nextafter(ny::kPi, 4.0f), ny::kTwoPi,
                  std::nextafter(3.0f * ny::kPi, 0.0f)}) {
    check(a);
  }
}

/* maxf, minf and clampf by comparisons are libm's fmaxf, fminf and fminf(fmaxf(x, lo), hi) (what they replaced, D59):
 * the same bits for random arguments and special first arguments against non-zero bounds, and a NaN first argument
 * gives the bound as before (a comparison written the other way round would pass the NaN on). Only the sign of a
 * zero against a zero may differ (fminf(-0, +0) is -0, minf's +0): no bound of the kernel is a zero that
 * another zero meets before an addition. */
TEST(Special, MinMaxAndClampAreLibmsValues)
{
  std::mt19937 rng(59);
  std::uniform_real_distribution<float> u(-4.0f, 4.0f);
  for (int i = 0; i < 1000000; i++) {
    const float x = u(rng), lo = u(rng), hi = u(rng);
    ASSERT_EQ(ny::float_bits(ny::maxf(x, lo)), ny::float_bits(std::fmax(x, lo))) << x << " " << lo;
    ASSERT_EQ(ny::float_bits(ny::minf(x, hi)), ny::float_bits(std::fmin(x, hi))) << x << " " << hi;
    ASSERT_EQ(ny::float_bits(ny::clampf(x, lo, hi)), ny::float_bits(std::fmin(std::fmax(x, lo), hi)))
        << x << " " << lo << " " << hi;
  }
  const float special[] = {0.0f, -0.0f, 1.0f, -1.0f, INFINITY, -INFINITY, NAN, 1e-45f};
  for (const float a : special) {
    for (const float b : {-1.0f, 1.0f, 1e-7f}) {
      EXPECT_EQ(ny::float_bits(ny::maxf(a, b)), ny::float_bits(std::fmax(a, b))) << a << " " << b;
      EXPECT_EQ(ny::float_bits(ny::minf(a, b)), ny::float_bits(std::fmin(a, b))) << a << " " << b;
    }
  }
  EXPECT_EQ(ny::float_bits(ny::maxf(-0.0f, 0.0f)), ny::float_bits(std::fmax(-0.0f, 0.0f))); /* safe_sqrtf(-0) */
  EXPECT_EQ(ny::clampf(NAN, -1.0f, 1.0f), -1.0f);
  EXPECT_EQ(ny::safe_sqrtf(NAN), 0.0f);
  EXPECT_EQ(ny::safe_sqrtf(-4.0f), 0.0f);
  EXPECT_EQ(ny::safe_sqrtf(4.0f), 2.0f);
}

}  // namespace
