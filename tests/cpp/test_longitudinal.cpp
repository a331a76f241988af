// SPDX-License-Identifier: Apache-2.0
//
// The cos^2 normaliser G(mu, beta) of Khungurn's longitudinal Gaussian against independent adaptive
// quadrature in double, over the widths the presets use and well beyond, at every mean including the
// bounds; and the defining property int gbar(theta) cos^2(theta) d(theta) = 1.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "neuralyarn/kernel/longitudinal.h"
#include "neuralyarn/units.h"
#include "quadrature.h"

using neuralyarn::kPi;

namespace {

double reference_G(double mu, double beta)
{
  const auto pts = nytest::breakpoints({mu - 6 * beta, mu - 2 * beta, mu, mu + 2 * beta, mu + 6 * beta}, -kPi / 2, kPi / 2);
  return nytest::integrate_panels(
      [&](double t) {
        const double z = (t - mu) / beta;
        return std::exp(-0.5 * z * z) / (beta * std::sqrt(2 * kPi)) * std::cos(t) * std::cos(t);
      },
      pts, 1e-13);
}

TEST(Longitudinal, NormaliserMatchesReferenceQuadrature)
{
  /* Float evaluation: 16 nodes per panel are exact to ~1e-8 in double (measured), so the tolerance is set
   * by float rounding of the exp/cos sums. */
  double worst = 0.0;
  for (double beta_deg : {0.5, 1.0, 2.141, 5.238, 7.238, 10.0, 20.0, 27.197, 45.0, 90.0, 180.0}) {
    const double beta = beta_deg * kPi / 180;
    for (int k = 0; k <= 60; k++) {
      const double mu = -kPi / 2 + kPi * k / 60.0;
      const double want = reference_G(mu, beta);
      const double got = ny::cos2_gaussian_normalizer(float(mu), float(beta));
      const double rel = std::fabs(got - want) / want;
      worst = std::max(worst, rel);
      EXPECT_LT(rel, 1e-5) << "beta " << beta_deg << " deg, mu " << mu;
    }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(Longitudinal, TableMatchesReferenceQuadratureWhereverItIsUsed)
{
  /* The tabulated ratio (cos2_table.h) at random points of its whole domain, between the grid nodes: widths
   * from 0.3 degrees to the table's 30, means from the bound to 6 beta inside it. The table's own error is
   * below 4e-6 in double (scripts/make_cos2_table.py's grid); float rounding on top. Fixed seed. */
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0.0;
  for (int k = 0; k < 3000; k++) {
    const double beta = (0.3 + (30.0 - 0.3) * u(rng)) * kPi / 180;
    const double d = 6.0 * beta * u(rng);
    const float mu = float((k % 2 ? 1.0 : -1.0) * (kPi / 2 - d)), beta_f = float(beta);
    /* The kernel's bounds are the float +-kHalfPi (4e-8 off pi / 2: 1e-5 of G at d = 0.006 degrees): the
     * reference takes the distance to the bound that the kernel sees. */
    const double d_f = double(ny::kHalfPi) - std::fabs(double(mu));
    const double rel = std::fabs(ny::cos2_gaussian_normalizer(mu, beta_f) / reference_G(kPi / 2 - d_f, beta_f) - 1.0);
    worst = std::max(worst, rel);
    EXPECT_LT(rel, 1e-5) << "beta " << beta * 180 / kPi << " deg, d " << d_f;
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(Longitudinal, TableAndQuadratureAgreeAtTheTablesWidestLobe)
{
  /* Past kCos2TableBetaMax the two-panel quadrature takes over: no seam in beta either. */
  for (double d : {0.0, 0.1, 0.5, 1.5}) {
    const float mu = float(kPi / 2 - d);
    const float at = ny::cos2_gaussian_normalizer(mu, ny::kCos2TableBetaMax);
    const float past = ny::cos2_gaussian_normalizer(mu, ny::kCos2TableBetaMax * (1.0f + 1e-6f));
    EXPECT_NEAR(at / past, 1.0, 1e-5) << "d " << d;
    EXPECT_NEAR(at / reference_G(mu, ny::kCos2TableBetaMax), 1.0, 1e-5) << "d " << d;
  }
}

TEST(Longitudinal, WideNormaliserMatchesReferenceQuadrature)
{
  /* The one-panel rule of the TT part (beta >= 5 degrees; narrower widths go to the full normaliser):
   * 1e-5 in double over these widths (measured), float rounding on top. */
  double worst = 0.0;
  for (double beta_deg : {0.5, 2.141, 4.9, 5.0, 7.238, 10.0, 20.0, 27.197, 38.269, 45.0, 90.0, 180.0}) {
    const double beta = beta_deg * kPi / 180;
    for (int k = 0; k <= 60; k++) {
      const double mu = -kPi / 2 + kPi * k / 60.0;
      const double rel = std::fabs(ny::cos2_gaussian_normalizer_wide(float(mu), float(beta)) - reference_G(mu, beta)) /
                         reference_G(mu, beta);
      worst = std::max(worst, rel);
      EXPECT_LT(rel, 3e-5) << "beta " << beta_deg << " deg, mu " << mu;
    }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(Longitudinal, LobeIntegratesToOneAgainstCos2)
{
  for (double beta_deg : {1.0, 7.238, 27.197, 90.0}) {
    const double beta = beta_deg * kPi / 180;
    for (double mu : {-kPi / 2, -1.2, -0.3, 0.0, 0.9, 1.5, kPi / 2}) {
      const ny::LongitudinalLobe lobe = ny::make_longitudinal_lobe(float(mu), float(beta));
      const auto pts = nytest::breakpoints({mu - 6 * beta, mu - 2 * beta, mu, mu + 2 * beta, mu + 6 * beta}, -kPi / 2, kPi / 2);
      const double integral = nytest::integrate_panels(
          [&](double t) { return double(ny::longitudinal_eval(lobe, float(t))) * std::cos(t) * std::cos(t); }, pts);
      EXPECT_NEAR(integral, 1.0, 1e-5) << "beta " << beta_deg << " deg, mu " << mu;
    }
  }
}

TEST(Longitudinal, ClosedFormAndQuadratureBranchesAgreeAtTheSwitch)
{
  /* The closed form is used when both bounds are >= 6 beta away; just across the switch the table takes
   * over. Both sides must give the same value (no visible seam in renders). */
  const float beta = 0.05f;
  const float mu_switch = float(kPi / 2) - 6.0f * beta;
  const float inside = ny::cos2_gaussian_normalizer(mu_switch - 1e-4f, beta);
  const float outside = ny::cos2_gaussian_normalizer(mu_switch + 1e-4f, beta);
  const double want_in = reference_G(mu_switch - 1e-4, beta), want_out = reference_G(mu_switch + 1e-4, beta);
  EXPECT_NEAR(inside / want_in, 1.0, 1e-6);
  EXPECT_NEAR(outside / want_out, 1.0, 1e-6);
}

TEST(Longitudinal, ZeroOutsideTheLongitudinalRange)
{
  const ny::LongitudinalLobe lobe = ny::make_longitudinal_lobe(0.2f, 0.1f);
  EXPECT_EQ(ny::longitudinal_eval(lobe, 1.6f), 0.0f);
  EXPECT_EQ(ny::longitudinal_eval(lobe, NAN), 0.0f);
}

}  // namespace
