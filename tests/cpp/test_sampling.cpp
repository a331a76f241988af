// SPDX-License-Identifier: Apache-2.0
//
// The primitive samplers against their densities: chi^2 goodness of fit (fixed seeds, Sidak-corrected
// alpha = 0.01 over each family of cases) and normalisation by independent quadrature.
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "chi2.h"
#include "neuralyarn/kernel/sampling.h"
#include "neuralyarn/rdm/normal_ziggurat.h"
#include "neuralyarn/rdm/von_mises_stream.h"
#include "neuralyarn/units.h"
#include "quadrature.h"

using neuralyarn::kPi;

namespace {

struct TnCase {
  double mu, sigma, a, b;
  const char *why;
};

const TnCase kTnCases[] = {
    {0.0, 1.0, -3.0, 3.0, "central"},
    {-1.2, 0.0175, -kPi / 2, kPi / 2, "narrow, inside"},
    {1.5, 0.02, -kPi / 2, kPi / 2, "narrow, cut by the upper bound"},
    {-kPi / 2, 0.0175, -kPi / 2, kPi / 2, "mean on the bound: half a Gaussian"},
    {5.0, 1.0, -1.0, 1.0, "mean far above the interval: the lower-tail-only inversion would fail"},
    {-5.0, 0.5, 0.0, 1.0, "mean far below: 10 sigma into the upper tail"},
    {0.3, 100.0, -1.0, 1.0, "almost uniform"},
    {0.0, 0.4747, -kPi / 2, kPi / 2, "cotton TT width"},
};

class TruncatedNormalTest : public ::testing::TestWithParam<int> {};

TEST_P(TruncatedNormalTest, SamplesFollowPdf)
{
  const TnCase c = kTnCases[GetParam()];
  const ny::TruncatedNormal tn = ny::make_truncated_normal(float(c.mu), float(c.sigma), float(c.a), float(c.b));
  ASSERT_GT(tn.mass, 0.0f) << c.why;
  const auto r = nytest::chi2_1d(
      [&](neuralyarn::Rng &rng) { return double(ny::sample_truncated_normal(tn, neuralyarn::uniform_float(rng))); },
      [&](double x) { return double(ny::truncated_normal_pdf(tn, float(x))); }, 1000000, 200, 1000 + GetParam());
  ASSERT_TRUE(r.failure.empty()) << c.why << ": " << r.failure;
  EXPECT_LE(r.interior_mass, 1.0 + 1e-4) << c.why;
  EXPECT_GT(r.p_value, nytest::sidak_alpha(0.01, std::size(kTnCases))) << c.why << ": chi2 " << r.chi2 << " dof " << r.dof;
}

TEST_P(TruncatedNormalTest, PdfIntegratesToOne)
{
  const TnCase c = kTnCases[GetParam()];
  const ny::TruncatedNormal tn = ny::make_truncated_normal(float(c.mu), float(c.sigma), float(c.a), float(c.b));
  const auto pts = nytest::breakpoints({c.mu - 3 * c.sigma, c.mu - c.sigma, c.mu, c.mu + c.sigma, c.mu + 3 * c.sigma},
                                       c.a, c.b);
  const double total = nytest::integrate_panels([&](double x) { return double(ny::truncated_normal_pdf(tn, float(x))); }, pts);
  EXPECT_NEAR(total, 1.0, 2e-5) << c.why;
}

TEST_P(TruncatedNormalTest, SamplesStayInSupportAtExtremeUniforms)
{
  const TnCase c = kTnCases[GetParam()];
  const ny::TruncatedNormal tn = ny::make_truncated_normal(float(c.mu), float(c.sigma), float(c.a), float(c.b));
  for (float u : {0.0f, 1e-30f, 1e-7f, 0.5f, 1.0f - 1e-7f, 0.99999994f}) {
    const float x = ny::sample_truncated_normal(tn, u);
    EXPECT_TRUE(std::isfinite(x)) << c.why << " u=" << u;
    EXPECT_GE(x, float(c.a) - 1e-6f) << c.why << " u=" << u;
    EXPECT_LE(x, float(c.b) + 1e-6f) << c.why << " u=" << u;
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, TruncatedNormalTest, ::testing::Range(0, int(std::size(kTnCases))));

/* truncated_normal_lanes (yarn_lobes' R nodes) against make_truncated_normal: the same case for every interval
 * (each table case, and 10^5 random means over [-2, 2] and widths from 0.5 to 60 degrees on [-pi/2, pi/2], the R
 * nodes' range, plus intervals wholly above or below the mean): za and zb bit for bit, lower, upper and mass within
 * 8 float ulps of the larger of the value and 1e-30 (erfc_lanes and fast_erfc differ by their exp: a few ulps each;
 * the mass of an interval in one tail is a difference of two such values). Swapping the case of an interval
 * above the mean fails it (its lower would be 1 - mass). */
TEST(TruncatedNormal, LanesAreTheScalarOnes)
{
  auto close = [](float got, float want) {
    return std::fabs(double(got) - double(want)) <= 8.0 * std::ldexp(1.0, std::ilogb(std::max(std::fabs(double(want)), 1e-30)) - 23);
  };
  auto check = [&](float mu, float sigma, float a, float b) {
    const ny::TruncatedNormal tn = ny::make_truncated_normal(mu, sigma, a, b);
    float za, zb, lower, upper, mass;
    ny::truncated_normal_lanes(mu, sigma, a, b, za, zb, lower, upper, mass);
    ASSERT_EQ(za, tn.za) << mu << " " << sigma;
    ASSERT_EQ(zb, tn.zb) << mu << " " << sigma;
    ASSERT_TRUE(close(lower, tn.lower)) << mu << " " << sigma << ": lower " << lower << " against " << tn.lower;
    ASSERT_TRUE(close(upper, tn.upper)) << mu << " " << sigma << ": upper " << upper << " against " << tn.upper;
    ASSERT_TRUE(close(mass, tn.mass)) << mu << " " << sigma << ": mass " << mass << " against " << tn.mass;
  };
  for (const TnCase &c : kTnCases) {
    check(float(c.mu), float(c.sigma), float(c.a), float(c.b));
  }
  neuralyarn::Rng rng(23);
  const float deg = float(kPi / 180);
  for (int k = 0; k < 100000; k++) {
    const float mu = 4.0f * neuralyarn::uniform_float(rng) - 2.0f;
    const float sigma = deg * (0.5f + 59.5f * neuralyarn::uniform_float(rng));
    check(mu, sigma, -float(kPi / 2), float(kPi / 2));
    check(mu, sigma, mu + sigma * 3.0f * neuralyarn::uniform_float(rng), mu + 4.0f * sigma); /* above the mean */
    check(mu, sigma, mu - 4.0f * sigma, mu - sigma * 3.0f * neuralyarn::uniform_float(rng)); /* below it */
  }
}

const double kKappas[] = {1e-5, 0.1, 1.0, 2.23, 8.35, 100.0, 3283.0, 1e6};

class VonMisesTest : public ::testing::TestWithParam<int> {};

TEST_P(VonMisesTest, SamplesFollowPdf)
{
  const double kappa = kKappas[GetParam()];
  const auto r = nytest::chi2_1d(
      [&](neuralyarn::Rng &rng) {
        const float u1 = neuralyarn::uniform_float(rng), u2 = neuralyarn::uniform_float(rng);
        return double(ny::sample_von_mises(float(kappa), u1, u2));
      },
      [&](double x) { return double(ny::von_mises_pdf(float(x), float(kappa))); }, 1000000, 200, 2000 + GetParam());
  ASSERT_TRUE(r.failure.empty()) << "kappa " << kappa << ": " << r.failure;
  EXPECT_LE(r.interior_mass, 1.0 + 1e-4) << "kappa " << kappa;
  EXPECT_GT(r.p_value, nytest::sidak_alpha(0.01, std::size(kKappas))) << "kappa " << kappa << ": chi2 " << r.chi2
                                                                      << " dof " << r.dof;
}

/* The random walk's sampler (host code): the same density, the proposal's tangent from the quarter disc. */
TEST_P(VonMisesTest, StreamSamplerFollowsPdf)
{
  const double kappa = kKappas[GetParam()];
  const ny::VonMisesProposal p = ny::make_von_mises_proposal(float(kappa));
  const auto r = nytest::chi2_1d(
      [&](neuralyarn::Rng &rng) {
        return 2.0 * std::atan(double(
                         neuralyarn::rdm::sample_von_mises_half_tan(p, [&rng] { return neuralyarn::uniform_float(rng); })));
      },
      [&](double x) { return double(ny::von_mises_pdf(float(x), float(kappa))); }, 1000000, 200, 3000 + GetParam());
  ASSERT_TRUE(r.failure.empty()) << "kappa " << kappa << ": " << r.failure;
  EXPECT_GT(r.p_value, nytest::sidak_alpha(0.01, std::size(kKappas))) << "kappa " << kappa << ": chi2 " << r.chi2
                                                                      << " dof " << r.dof;
}

TEST_P(VonMisesTest, PdfIntegratesToOne)
{
  const double kappa = kKappas[GetParam()];
  const double s = 1.0 / std::sqrt(kappa);
  const auto pts = nytest::breakpoints({-10 * s, -3 * s, -s, 0.0, s, 3 * s, 10 * s}, -kPi, kPi);
  const double total =
      nytest::integrate_panels([&](double x) { return double(ny::von_mises_pdf(float(x), float(kappa))); }, pts);
  EXPECT_NEAR(total, 1.0, 5e-6) << "kappa " << kappa;
}

INSTANTIATE_TEST_SUITE_P(Concentrations, VonMisesTest, ::testing::Range(0, int(std::size(kKappas))));

TEST(UniformSphere, SamplesFollowPdf)
{
  const auto r = nytest::chi2_sphere(
      [](neuralyarn::Rng &rng, ny::Vec3 &w) {
        w = ny::sample_uniform_sphere(neuralyarn::uniform_float(rng), neuralyarn::uniform_float(rng));
        return true;
      },
      [](ny::Vec3) { return double(ny::uniform_sphere_pdf()); }, 1000000, 20, 40, 3000);
  ASSERT_TRUE(r.failure.empty()) << r.failure;
  EXPECT_LE(r.interior_mass, 1.0 + 1e-4);
  EXPECT_GT(r.p_value, 0.01) << "chi2 " << r.chi2 << " dof " << r.dof;
}

/* The random walk's normal (host code): the ziggurat's layers and its draws. */
TEST(NormalZiggurat, LayersHaveEqualArea)
{
  using Z = neuralyarn::rdm::NormalZiggurat;
  const Z &z = Z::get();
  /* Layer 0: the rectangle up to r and the tail beyond it, integral_r^inf exp(-x^2 / 2) = sqrt(pi / 2) erfc(r / sqrt 2). */
  const double tail = std::sqrt(kPi / 2.0) * std::erfc(Z::kR / std::sqrt(2.0));
  EXPECT_NEAR((Z::kR * z.f[0] + tail) / Z::kArea, 1.0, 1e-9);
  EXPECT_NEAR(z.x[0] * z.f[0] / Z::kArea, 1.0, 1e-12);
  for (int i = 1; i < Z::kLayers; i++) {
    EXPECT_NEAR(z.x[i] * (z.f[i + 1] - z.f[i]) / Z::kArea, 1.0, 1e-8) << "layer " << i;
    EXPECT_NEAR(z.f[i], std::exp(-0.5 * z.x[i] * z.x[i]), 1e-15) << "layer " << i;
    EXPECT_GT(z.x[i], z.x[i + 1]) << "layer " << i;
  }
}

double standard_normal_pdf(double x) { return std::exp(-0.5 * x * x) / std::sqrt(2.0 * kPi); }

TEST(NormalZiggurat, SamplesFollowTheNormal)
{
  const auto r = nytest::chi2_1d(
      [](neuralyarn::Rng &rng) {
        return neuralyarn::rdm::sample_standard_normal(neuralyarn::rdm::NormalZiggurat::get(), [&rng] { return neuralyarn::uniform_float(rng); });
      },
      standard_normal_pdf, 4000000, 400, 77);
  ASSERT_TRUE(r.failure.empty()) << r.failure;
  EXPECT_NEAR(r.interior_fraction, r.interior_mass, 1e-3);
  EXPECT_GT(r.p_value, 0.01) << "chi2 " << r.chi2 << " dof " << r.dof;
}

/* |z| beyond 2: the wedges of the bottom layers and the tail past r = 3.44, which the whole-line test sees in
 * a few cells only. */
TEST(NormalZiggurat, TailFollowsTheNormal)
{
  const double cut = 2.0;
  const double mass = std::erfc(cut / std::sqrt(2.0)); /* P(|z| > cut) */
  const auto r = nytest::chi2_1d(
      [&](neuralyarn::Rng &rng) {
        for (;;) {
          const double z = std::abs(neuralyarn::rdm::sample_standard_normal(neuralyarn::rdm::NormalZiggurat::get(), [&rng] { return neuralyarn::uniform_float(rng); }));
          if (z > cut) {
            return z;
          }
        }
      },
      [&](double x) { return x > cut ? 2.0 * standard_normal_pdf(x) / mass : 0.0; }, 1000000, 200, 78);
  ASSERT_TRUE(r.failure.empty()) << r.failure;
  EXPECT_GT(r.p_value, 0.01) << "chi2 " << r.chi2 << " dof " << r.dof;
}

}  // namespace
