// SPDX-License-Identifier: Apache-2.0
//
// The forward peak's fit (model/forward_peak.h) on synthetic maps whose peak is known: a flat background
// plus a von Mises-Fisher lobe about -w_i of known energy and concentration, integrated over the map bins as
// a gather records it (the incident bin's extent included).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "neuralyarn/model/forward_peak.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

namespace {

/* Coarser than the paper's in theta_i and phi_i (7.5 and 5 degrees: the maps blur the peak by the incident
 * bin's extent, which must stay well inside the 12-degree cone), its outgoing resolution (4 degrees). */
const rdm::MapResolution kBins{12, 72, 45, 90};

/* Maps of background radiance `bg` (RGB) and, for theta_i bins from `first_peak` on, a peak of energy
 * w_scale * (theta_i bin + 1) * (0.5, 1, 2) and concentration kappa; with noise > 0, each bin value gets
 * independent Gaussian noise of that relative standard deviation. */
rdm::RdmMaps synthetic(double kappa, double w_scale, int first_peak, double noise, uint64_t seed)
{
  rdm::RdmMaps m;
  m.bins = kBins;
  m.m.assign(size_t(kBins.theta_i) * kBins.phi_i * kBins.theta_o * kBins.phi_o * 3, 0.0f);
  const double bg[3] = {0.02, 0.03, 0.05}, tint[3] = {0.5, 1.0, 2.0};
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    for (int pi = 0; pi < kBins.phi_i; pi++) {
      for (int to = 0; to < kBins.theta_o; to++) {
        const double dO = m.outgoing_solid_angle(to);
        for (int po = 0; po < kBins.phi_o; po++) {
          /* Only within 30 degrees of -w_i: the lobe's integral is below 1e-50 of its energy farther out. */
          const double th_i = rdm::bin_center(ti, 0, 0.5 * kPi, kBins.theta_i), ph_i = rdm::bin_center(pi, -kPi, kPi, kBins.phi_i);
          const double th = rdm::bin_center(to, 0, kPi, kBins.theta_o), ph = rdm::bin_center(po, -kPi, kPi, kBins.phi_o);
          const double c = -(std::sin(th_i) * std::sin(th) * std::cos(ph - ph_i) + std::cos(th_i) * std::cos(th));
          const double lobe = ti >= first_peak && c > std::cos(30.0 * kDeg)
                                  ? model::forward_lobe_in_bin(kBins, ti, pi, to, po, kappa, 3)
                                  : 0.0;
          for (int c = 0; c < 3; c++) {
            const double v = bg[c] + w_scale * (ti + 1) * tint[c] * lobe / dO;
            m.m[m.map_index(ti, pi, to, po) + size_t(c)] = float(v * (1.0 + noise * N(rng)));
          }
        }
      }
    }
  }
  return m;
}

}  // namespace

TEST(ForwardPeak, VmfDensityIsNormalisedAndStableForLargeKappa)
{
  /* Integral over the sphere: 2 pi int_{-1}^{1} f(c) dc, by the midpoint rule in c. */
  for (double kappa : {0.5, 30.0, 3000.0}) {
    const int n = 400000;
    double sum = 0.0;
    for (int i = 0; i < n; i++) {
      sum += model::vmf_density(-1.0 + 2.0 * (i + 0.5) / n, kappa) * 2.0 / n;
    }
    EXPECT_NEAR(2.0 * kPi * sum, 1.0, 1e-4) << kappa;
  }
  EXPECT_TRUE(std::isfinite(model::vmf_density(1.0, 1e6)));
  EXPECT_EQ(model::vmf_density(-1.0, 1e6), 0.0);
}

TEST(ForwardPeak, RecoversAKnownPeakOnABackground)
{
  /* kappa 400: 1/sqrt(kappa) = 2.9 degrees, narrower than a map bin, which the fit must see through. */
  const double kappa = 400.0, w_scale = 0.01;
  const rdm::RdmMaps maps = synthetic(kappa, w_scale, 6, 0.0, 0);
  model::ForwardPeakOptions o;
  o.threads = 1;
  const model::ForwardPeakTable t = model::fit_forward_peaks(maps, o);
  ASSERT_EQ(t.theta_bins, kBins.theta_i);
  ASSERT_EQ(t.phi_bins, kBins.phi_i);
  /* The search refines the kappa grid (steps of (3000 / 30)^(1/23) = 1.22) by golden sections. */
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    for (int pi = 0; pi < kBins.phi_i; pi++) {
      const model::ForwardPeak &p = t.at(ti, pi);
      if (ti < 6) {
        /* A flat background: no excess in the cone over its ring. */
        EXPECT_LT(p.w[1], 1e-6) << ti << " " << pi;
        continue;
      }
      EXPECT_NEAR(p.kappa / kappa, 1.0, 0.03) << ti << " " << pi;
      const double w = w_scale * (ti + 1);
      /* The lobe's tail outside the 12-degree cone (e^{-400 (1 - cos 12 deg)} ~ 1e-4 at its edge). */
      EXPECT_NEAR(p.w[0] / (0.5 * w), 1.0, 0.01) << ti << " " << pi;
      EXPECT_NEAR(p.w[1] / w, 1.0, 0.01) << ti << " " << pi;
      EXPECT_NEAR(p.w[2] / (2.0 * w), 1.0, 0.01) << ti << " " << pi;
      EXPECT_GT(p.explained, 0.9) << ti << " " << pi;
    }
  }
}

TEST(ForwardPeak, NoisyMapsGiveTheEnergyWithinTheirNoise)
{
  /* 20 % noise per bin (a few M paths per bin, as the maps at grazing incidence): the window of incident
   * bins and the cone's bins average it down; the energy comes out within 10 %. */
  const rdm::RdmMaps maps = synthetic(200.0, 0.01, 6, 0.2, 7);
  model::ForwardPeakOptions o;
  o.threads = 2;
  const model::ForwardPeakTable t = model::fit_forward_peaks(maps, o);
  for (int ti = 6; ti < kBins.theta_i; ti++) {
    double sum = 0.0;
    for (int pi = 0; pi < kBins.phi_i; pi++) {
      sum += t.at(ti, pi).w[1];
    }
    EXPECT_NEAR(sum / kBins.phi_i / (0.01 * (ti + 1)), 1.0, 0.1) << ti;
  }
}

TEST(ForwardPeak, RejectsOptionsOutOfRange)
{
  const rdm::RdmMaps maps = synthetic(100.0, 0.0, 99, 0.0, 0);
  model::ForwardPeakOptions o;
  o.cone_deg = 25.0;
  EXPECT_THROW(model::fit_forward_peaks(maps, o), ParameterError);
  o = {};
  o.kappa_min = 0.0;
  EXPECT_THROW(model::fit_forward_peaks(maps, o), ParameterError);
  o = {};
  o.sub = 0;
  EXPECT_THROW(model::fit_forward_peaks(maps, o), ParameterError);
}
