// SPDX-License-Identifier: Apache-2.0
//
// The 4D lobe fidelity measure (model/lobe_fidelity.h) on lobes whose error is known: a synthetic truth,
// two maps of it with independent Gaussian bin noise, and models that are exact, off by a known relative
// L1, or missing a known share of the transmitted energy. Then the model side on a real model: the R grid
// holds the R lobe's exact energy, the M grid the M lobe's.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

namespace {

const rdm::MapResolution kBins{4, 24, 30, 60};

/* A smooth lobe with a reflection and a transmission part, energy per map bin. */
double truth(int ti, int pi, int to, int po)
{
  const double th_i = rdm::bin_center(ti, 0, 0.5 * kPi, kBins.theta_i), ph_i = rdm::bin_center(pi, -kPi, kPi, kBins.phi_i);
  const double th = rdm::bin_center(to, 0, kPi, kBins.theta_o), ph = rdm::bin_center(po, -kPi, kPi, kBins.phi_o);
  const double refl = std::exp(-std::pow(th - th_i, 2) / 0.3) * (1.2 + std::cos(ph - ph_i));
  const double trans = 0.6 * std::exp(-std::pow(th - (kPi - th_i), 2) / 0.5);
  rdm::RdmMaps g;
  g.bins = kBins;
  return (refl + trans) * g.outgoing_solid_angle(to);
}

/* Grid of truth(.) * factor(.) plus, with sigma > 0, independent Gaussian noise of standard deviation
 * sigma * sqrt(truth) per map bin (Monte Carlo bins: variance proportional to the mean). */
template <class Factor>
model::LobeGrid grid(Factor factor, double sigma, uint64_t seed, const model::LobePooling &pooling = {})
{
  model::LobeGrid g = model::make_lobe_grid(kBins, pooling);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    for (int pi = 0; pi < kBins.phi_i; pi++) {
      for (int to = 0; to < kBins.theta_o; to++) {
        for (int po = 0; po < kBins.phi_o; po++) {
          const double t = truth(ti, pi, to, po) * factor(ti, pi, to, po);
          double v[3];
          for (double &c : v) {
            c = t + sigma * std::sqrt(t) * N(rng);
          }
          add_to_lobe_grid(&g, ti, pi, to, po, v, 1.0);
        }
      }
    }
  }
  return g;
}

auto one = [](int, int, int, int) { return 1.0; };

/* The expected L1 distance of the mean of maps a and b from the truth, per theta_i row. */
std::vector<double> true_noise(const model::LobeGrid &a, const model::LobeGrid &b, const model::LobeGrid &t)
{
  std::vector<double> out;
  const size_t row = a.cells.size() / size_t(kBins.theta_i);
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    double d = 0, m = 0;
    for (size_t i = size_t(ti) * row; i < size_t(ti + 1) * row; i++) {
      d += std::abs(0.5 * (a.cells[i] + b.cells[i]) - t.cells[i]);
      m += t.cells[i];
    }
    out.push_back(d / m);
  }
  return out;
}
}  // namespace

TEST(LobeFidelity, NoiseFloorAndNoiseRemovalOnAnExactModel)
{
  const model::LobeGrid t = grid(one, 0.0, 0), a = grid(one, 0.02, 1), b = grid(one, 0.02, 2);
  const model::LobeComparison c = model::compare_lobes(t, a, &b);
  const std::vector<double> expected = true_noise(a, b, t);
  ASSERT_TRUE(c.noise_removed);
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    std::printf("theta_i %d: floor %.4f (true %.4f), raw %.4f, model error %.4f\n", ti, c.noise_floor[size_t(ti)],
                expected[size_t(ti)], c.l1_raw[size_t(ti)], c.l1[size_t(ti)]);
    /* The floor estimates the mean map's distance from the truth (thousands of cells: within 10 %). */
    EXPECT_NEAR(c.noise_floor[size_t(ti)], expected[size_t(ti)], 0.1 * expected[size_t(ti)]);
    /* An exact model's raw distance is that noise; the noise-removed error is 0.6 of it (the expectation
     * of sqrt(max(0, e1 e2)) for independent Gaussians against that of |e1 + e2| / 2). */
    EXPECT_NEAR(c.l1_raw[size_t(ti)], c.noise_floor[size_t(ti)], 0.1 * c.noise_floor[size_t(ti)]);
    EXPECT_NEAR(c.l1[size_t(ti)], 0.6 * c.noise_floor[size_t(ti)], 0.1 * c.noise_floor[size_t(ti)]);
    EXPECT_NEAR(c.reflection_ratio[size_t(ti)], 1.0, 0.01);
    EXPECT_NEAR(c.transmission_ratio[size_t(ti)], 1.0, 0.01);
  }
}

TEST(LobeFidelity, RecoversAKnownShapeErrorThroughTheNoise)
{
  /* +-10 % in a checkerboard of map bins: the energy-weighted relative L1 error is exactly 0.1. */
  auto checker = [](int, int, int to, int po) { return (to + po) % 2 ? 1.1 : 0.9; };
  const model::LobeGrid x = grid(checker, 0.0, 0), t = grid(one, 0.0, 0);
  /* Pooled cells average the checkerboard out: measure on unpooled cells (1-degree cells keep every bin). */
  model::LobePooling fine;
  fine.cell_deg = 1.0;
  /* Map noise with a floor of 1.5-3 %, a fifth to a third of the error. */
  const model::LobeGrid xf = grid(checker, 0.0, 0, fine), af = grid(one, 0.0025, 3, fine),
                        bf = grid(one, 0.0025, 4, fine);
  const model::LobeComparison c = model::compare_lobes(xf, af, &bf);
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    std::printf("theta_i %d: raw %.4f, floor %.4f, model error %.4f (true 0.1)\n", ti, c.l1_raw[size_t(ti)],
                c.noise_floor[size_t(ti)], c.l1[size_t(ti)]);
    /* Where the error is 3-7 times the floor both read close to it: the raw distance high and the
     * noise-removed error low, each by about floor^2 / (2 error) (second order in noise / error), so the
     * true error lies between them. */
    EXPECT_GT(c.noise_floor[size_t(ti)], 0.012);
    EXPECT_NEAR(c.l1_raw[size_t(ti)], 0.1, 0.003);
    EXPECT_GT(c.l1[size_t(ti)], 0.09);
    EXPECT_LE(c.l1[size_t(ti)], 0.1);
  }
  /* Pooled 12-degree cells (2 x 2 bins here) see almost nothing of a checkerboard of single bins: the
   * measure's resolution is the cell. */
  const model::LobeComparison pooled = model::compare_lobes(x, t);
  EXPECT_LT(pooled.l1_max_but_grazing, 0.02);
}

TEST(LobeFidelity, EnergyRatiosPerExitBand)
{
  /* A model that transmits half of what the maps transmit and nothing near the ply axis. */
  auto half_transmission = [](int, int, int to, int po) {
    const double th = rdm::bin_center(to, 0, kPi, kBins.theta_o), ph = rdm::bin_center(po, -kPi, kPi, kBins.phi_o);
    if (std::abs(std::sin(th) * std::cos(ph)) > std::cos(30.0 * kDeg)) {
      return 0.0;
    }
    return th > 0.5 * kPi ? 0.5 : 1.0;
  };
  const model::LobeGrid x = grid(half_transmission, 0.0, 0), a = grid(one, 0.0, 0);
  const model::LobeComparison c = model::compare_lobes(x, a);
  EXPECT_FALSE(c.noise_removed);
  EXPECT_TRUE(c.noise_floor.empty());
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    EXPECT_EQ(c.band_ratio[size_t(ti)][model::kLobeAxialBand], 0.0);
    /* The 150-180 band is nowhere near the axis: exactly half. */
    EXPECT_NEAR(c.band_ratio[size_t(ti)][5], 0.5, 1e-9);
    EXPECT_LT(c.transmission_ratio[size_t(ti)], 0.5 + 1e-9);
    EXPECT_LT(c.reflection_ratio[size_t(ti)], 1.0 + 1e-9);
    double share = 0;
    for (int k = 0; k < 6; k++) {
      share += c.band_share[size_t(ti)][size_t(k)];
    }
    EXPECT_NEAR(share, 1.0, 1e-9);
  }
}

namespace {

/* The incident and outgoing directions of map bin centres. */
Eigen::Vector3f incident(int ti, int pi)
{
  return train::entry_direction(rdm::bin_center(ti, 0, 0.5 * kPi, kBins.theta_i), rdm::bin_center(pi, -kPi, kPi, kBins.phi_i));
}
Eigen::Vector3f outgoing(int to, int po)
{
  return train::entry_direction(rdm::bin_center(to, 0, kPi, kBins.theta_o), rdm::bin_center(po, -kPi, kPi, kBins.phi_o));
}

/* A model with `factor` times the maps' energy in the bins `in_band` selects and the maps' own elsewhere:
 * band `band` reads `factor` in every theta_i row, and its share is that of those bins. */
template <class InBand>
void expect_band_reads(InBand in_band, double factor, int band)
{
  auto scaled = [&](int ti, int pi, int to, int po) { return in_band(ti, pi, to, po) ? factor : 1.0; };
  const model::LobeComparison c = model::compare_lobes(grid(scaled, 0.0, 0), grid(one, 0.0, 0));
  for (int ti = 0; ti < kBins.theta_i; ti++) {
    double in = 0, all = 0;
    for (int pi = 0; pi < kBins.phi_i; pi++) {
      for (int to = 0; to < kBins.theta_o; to++) {
        for (int po = 0; po < kBins.phi_o; po++) {
          all += truth(ti, pi, to, po);
          in += in_band(ti, pi, to, po) ? truth(ti, pi, to, po) : 0.0;
        }
      }
    }
    ASSERT_GT(in, 1e-3 * all) << "the synthetic lobe holds energy in the band at theta_i bin " << ti;
    EXPECT_NEAR(c.band_ratio[size_t(ti)][size_t(band)], factor, 1e-9) << ti;
    EXPECT_NEAR(c.band_share[size_t(ti)][size_t(band)], in / all, 1e-9) << ti;
  }
}

}  // namespace

TEST(LobeFidelity, ForwardBandHoldsTheExitsAroundMinusWi)
{
  /* The bins whose centre is within 12 degrees of -w_i (the incident bin's centre) at 2/3. With the band
   * centred on +w_i instead (the mirror image through the ply), the ratio would be 1 and the test fails. */
  expect_band_reads([](int ti, int pi, int to, int po) {
    return -double(incident(ti, pi).dot(outgoing(to, po))) > std::cos(model::kLobeForwardDeg * kDeg);
  }, 2.0 / 3.0, model::kLobeForwardBand);
}

TEST(LobeFidelity, ThroughBandHoldsWhatALightBehindThePlyShows)
{
  /* The bins where w_i and w_o lie within 15 degrees of the plane normal to the ply axis and w_o leaves on
   * the far side at 3/2. With the far side taken as w_o.z > 0 (the near side) the ratio would be 1 and the
   * test fails. */
  expect_band_reads([](int ti, int pi, int to, int po) {
    const double s = std::sin(model::kLobeThroughDeg * kDeg);
    const Eigen::Vector3f wi = incident(ti, pi), wo = outgoing(to, po);
    return std::abs(wi.x()) < s && std::abs(wo.x()) < s && wo.z() < 0.0f;
  }, 1.5, model::kLobeThroughBand);
}

TEST(LobeFidelity, ModelGridsHoldTheLobesEnergies)
{
  for (const char *name : {"silk", "fleece"}) {
    const model::YarnModel m = model::load_model(model::builtin_model_path(name));
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    const rdm::MapResolution b{6, 12, 45, 90};
    const model::LobeGrid R = model::model_lobe_grid(m, b, model::Lobe::kR);
    const model::LobeGrid M = model::model_lobe_grid(m, b, model::Lobe::kM);
    ASSERT_EQ(R.phi_i_groups, 12); /* 30-degree incident bins: not pooled */
    for (int ti = 0; ti < b.theta_i; ti++) {
      for (int pi = 0; pi < b.phi_i; pi += 5) {
        /* The same incident sub-directions as the grid: kRSub x kRSub (R) and 2 x 2 (M), uniform in solid angle. */
        auto expected = [&](int n, bool r_lobe) {
          const double t0 = 0.5 * kPi * ti / b.theta_i, t1 = 0.5 * kPi * (ti + 1) / b.theta_i;
          double e[3] = {0, 0, 0};
          for (int s = 0; s < n * n; s++) {
            const double ct = std::cos(t0) + ((s / n) + 0.5) / n * (std::cos(t1) - std::cos(t0));
            const double st = std::sqrt(1 - ct * ct), ph = -kPi + 2 * kPi * (pi + (s % n + 0.5) / n) / b.phi_i;
            const ny::YarnLobes l =
                ny::yarn_lobes(p, ny::make_vec3(float(st * std::cos(ph)), float(st * std::sin(ph)), float(ct)));
            ny::Rgb v;
            if (r_lobe) {
              /* weight_R / 2 times the part of the cos^2-normalised Gaussian inside [-pi/2, pi/2] (all of it
               * but near grazing incidence), by quadrature, averaged over the R nodes. */
              double mass = 0;
              const int nq = 20000;
              for (int node = 0; node < l.n_R; node++) {
                for (int q = 0; q < nq; q++) {
                  const double th = -0.5 * kPi + kPi * (q + 0.5) / nq;
                  mass += ny::longitudinal_eval(l.node[node].m_R, float(th)) * std::cos(th) * std::cos(th) * kPi /
                          nq / l.n_R;
                }
              }
              v = l.weight_R * float(0.5 * mass);
            }
            else {
              v = model::m_lobe_energy(p, l);
            }
            e[0] += v.r / (n * n), e[1] += v.g / (n * n), e[2] += v.b / (n * n);
          }
          return std::array<double, 3>{e[0], e[1], e[2]};
        };
        const std::array<double, 3> er = expected(model::kRSub, true), em = expected(2, false);
        const size_t group = size_t(ti) * size_t(R.phi_i_groups) + size_t(pi);
        for (int c = 0; c < 3; c++) {
          double sr = 0, sm = 0;
          for (size_t k = 0; k < R.cells_per_group(); k++) {
            sr += R.cells[(group * R.cells_per_group() + k) * 3 + size_t(c)];
            sm += M.cells[(group * M.cells_per_group() + k) * 3 + size_t(c)];
          }
          /* R: 32 stratified quantiles of a narrow truncated normal (the cos^2 factor varies over it at grazing
           * incidence); M: 4-degree midpoint rule against m_lobe_energy's 64 x 128 grid. */
          EXPECT_NEAR(sr, er[size_t(c)], 0.01 * er[size_t(c)] + 1e-7) << name << " R " << ti << " " << pi;
          EXPECT_NEAR(sm, em[size_t(c)], 0.02 * em[size_t(c)] + 1e-6) << name << " M " << ti << " " << pi;
        }
      }
    }
  }
}

TEST(LobeFidelity, RejectsMapsThatAreNotIndependentOrDoNotFit)
{
  const model::YarnModel m = model::load_model(model::builtin_model_path("silk"));
  rdm::GatherOptions o;
  o.paths = 20000;
  o.bins = {4, 8, 6, 12};
  o.seed = 7;
  const rdm::RdmMaps a = rdm::gather(m.preset, o);
  EXPECT_THROW(model::check_lobes(m, a, &a), ParameterError);
  o.bins = {4, 8, 6, 24};
  o.seed = 8;
  const rdm::RdmMaps other_bins = rdm::gather(m.preset, o);
  EXPECT_THROW(model::check_lobes(m, a, &other_bins), ParameterError);
  EXPECT_THROW(rdm::mean_of_maps(a, a), ParameterError);
  const rdm::RdmMaps fleece = rdm::gather(find_preset("fleece"), o);
  EXPECT_THROW(model::check_lobes(m, fleece), ParameterError);
  /* A fitting pair gives finite numbers for every theta_i bin. */
  o.bins = {4, 8, 6, 12};
  const rdm::RdmMaps b = rdm::gather(m.preset, o);
  const model::LobeFidelity f = model::check_lobes(m, a, &b);
  ASSERT_EQ(f.M.l1.size(), 4u);
  for (double v : f.M.l1) {
    EXPECT_TRUE(std::isfinite(v));
  }
}
