// SPDX-License-Identifier: Apache-2.0
//
// The forward peak's fit (model/forward_peak.h) on synthetic maps whose peak is known: a flat background
// plus a von Mises-Fisher lobe about -w_i of known energy and concentration, integrated over the map bins as
// a gather records it (the incident bin's extent included); and an arc (the surface fibers' TT form).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <utility>

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

namespace {

/* An arc lobe (model::arc_density, the surface fibers' TT form) of energy w per channel tint, for theta_i
 * bins from `first_peak` on, on a background, integrated over the bins as a gather records them (3 x 3
 * incident and outgoing directions per bin); `noise` as synthetic(). 18 phi_i bins: a window of one bin. */
const rdm::MapResolution kArcBins{12, 18, 45, 90};

rdm::RdmMaps synthetic_arc(double beta, double gamma, double w, int first_peak, double noise, uint64_t seed)
{
  rdm::RdmMaps m;
  m.bins = kArcBins;
  m.preset = find_preset("polyester");
  const ny::TwistRotation twist = ny::make_twist_rotation(float(m.surface_alpha()));
  m.m.assign(size_t(kArcBins.theta_i) * kArcBins.phi_i * kArcBins.theta_o * kArcBins.phi_o * 3, 0.0f);
  const double bg[3] = {0.02, 0.03, 0.05}, tint[3] = {0.5, 1.0, 2.0};
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  const int sub = 3;
  auto dir = [](double th, double ph) {
    return ny::make_vec3(float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)), float(std::cos(th)));
  };
  for (int ti = 0; ti < kArcBins.theta_i; ti++) {
    for (int pi = 0; pi < kArcBins.phi_i; pi++) {
      for (int to = 0; to < kArcBins.theta_o; to++) {
        const double c0 = std::cos(kPi * to / kArcBins.theta_o), c1 = std::cos(kPi * (to + 1) / kArcBins.theta_o);
        for (int po = 0; po < kArcBins.phi_o; po++) {
          double lobe = 0.0;
          if (ti >= first_peak) {
            for (int si = 0; si < sub * sub; si++) {
              const double ci = std::cos(0.5 * kPi * ti / kArcBins.theta_i),
                           cj = std::cos(0.5 * kPi * (ti + 1) / kArcBins.theta_i);
              const double th_i = std::acos(ci + (si / sub + 0.5) / sub * (cj - ci));
              const double ph_i = -kPi + 2.0 * kPi * (pi + (si % sub + 0.5) / sub) / kArcBins.phi_i;
              const ny::Vec3 wi_f = ny::yarn_to_surface_fiber(twist, dir(th_i, ph_i));
              for (int so = 0; so < sub * sub; so++) {
                const double th_o = std::acos(c0 + (so / sub + 0.5) / sub * (c1 - c0));
                const double ph_o = -kPi + 2.0 * kPi * (po + (so % sub + 0.5) / sub) / kArcBins.phi_o;
                lobe += model::arc_density(wi_f, ny::yarn_to_surface_fiber(twist, dir(th_o, ph_o)), beta, gamma);
              }
            }
            lobe /= sub * sub * sub * sub; /* the mean density over the bin pair: times dO / dO */
          }
          for (int c = 0; c < 3; c++) {
            const double v = bg[c] + w * tint[c] * lobe;
            m.m[m.map_index(ti, pi, to, po) + size_t(c)] = float(v * (1.0 + noise * N(rng)));
          }
        }
      }
    }
  }
  return m;
}

}  // namespace

TEST(ForwardPeak, ArcDensityIsNormalisedForNarrowWidths)
{
  /* The normal in theta~ and the wrapped normal in phi~ over the sphere, dw = cos theta~ dtheta~ dphi~: 1 when
   * the longitudinal normal lies well inside [-pi/2, pi/2] (it is not truncated there). */
  const ny::Vec3 wi_f = ny::normalize(ny::make_vec3(0.2f, 0.9f, 0.3f));
  for (const auto &[beta, gamma] : {std::pair{2.0, 5.0}, std::pair{6.0, 40.0}}) {
    const int nt = 3000, np = 3000;
    double sum = 0.0;
    for (int i = 0; i < nt; i++) {
      const double th = -0.5 * kPi + kPi * (i + 0.5) / nt;
      for (int j = 0; j < np; j++) {
        const double ph = -kPi + 2.0 * kPi * (j + 0.5) / np;
        sum += model::arc_density(wi_f, ny::direction_from_angles(float(th), float(ph)), beta * kDeg, gamma * kDeg) *
               std::cos(th) * (kPi / nt) * (2.0 * kPi / np);
      }
    }
    EXPECT_NEAR(sum, 1.0, 5e-3) << beta << " " << gamma;
  }
}

TEST(ForwardPeak, ArcRecoversAKnownArcThatASpotDoesNot)
{
  /* beta 3 and gamma 12 degrees on the search's grid (1.5, 3, 6) x (6, 12, 24); from theta_i 60 degrees on. */
  const rdm::RdmMaps maps = synthetic_arc(3.0 * kDeg, 12.0 * kDeg, 0.02, 8, 0.0, 0);
  model::ForwardPeakOptions o;
  o.threads = 2;
  o.shape = model::ForwardShape::kArc;
  o.beta_min_deg = 1.5, o.beta_max_deg = 6.0, o.gamma_min_deg = 6.0, o.gamma_max_deg = 24.0, o.arc_steps = 3;
  const model::ForwardPeakTable arc = model::fit_forward_peaks(maps, o, &maps);
  o.shape = model::ForwardShape::kSpot;
  const model::ForwardPeakTable spot = model::fit_forward_peaks(maps, o);
  double arc_explained = 0.0, spot_explained = 0.0;
  int n = 0;
  for (int ti = 8; ti < kArcBins.theta_i; ti++) {
    for (int pi = 0; pi < kArcBins.phi_i; pi++) {
      const model::ForwardPeak &p = arc.at(ti, pi);
      EXPECT_NEAR(p.beta / kDeg, 3.0, 1e-6) << ti << " " << pi;
      EXPECT_NEAR(p.gamma / kDeg, 12.0, 1e-6) << ti << " " << pi;
      EXPECT_GT(p.explained, 0.9) << ti << " " << pi;
      /* The same map twice: no noise, all of the excess explicable. */
      EXPECT_DOUBLE_EQ(p.ceiling, 1.0) << ti << " " << pi;
      arc_explained += p.explained;
      spot_explained += spot.at(ti, pi).explained;
      n++;
    }
  }
  EXPECT_GT(arc_explained / n, spot_explained / n + 0.1);
}

TEST(ForwardPeak, CeilingIsTheShareOfTheExcessAboveTheMapsNoise)
{
  /* Two maps with independent 20 % noise: the ceiling falls below 1; without maps B there is none. */
  const rdm::RdmMaps a = synthetic_arc(3.0 * kDeg, 12.0 * kDeg, 0.02, 8, 0.2, 1);
  const rdm::RdmMaps b = synthetic_arc(3.0 * kDeg, 12.0 * kDeg, 0.02, 8, 0.2, 2);
  model::ForwardPeakOptions o;
  o.threads = 2;
  const model::ForwardPeakTable t = model::fit_forward_peaks(a, o, &b);
  const model::ForwardPeakTable alone = model::fit_forward_peaks(a, o);
  for (int pi = 0; pi < kArcBins.phi_i; pi++) {
    EXPECT_GT(t.at(10, pi).ceiling, 0.0) << pi;
    EXPECT_LT(t.at(10, pi).ceiling, 0.99) << pi;
    EXPECT_EQ(alone.at(10, pi).ceiling, -1.0) << pi;
  }
  rdm::RdmMaps other = b;
  other.bins.phi_o = 45;
  EXPECT_THROW(model::fit_forward_peaks(a, o, &other), ParameterError);
  o.shape = model::ForwardShape::kArc;
  o.beta_min_deg = 0.0;
  EXPECT_THROW(model::fit_forward_peaks(a, o), ParameterError);
}
