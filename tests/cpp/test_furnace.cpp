// SPDX-License-Identifier: Apache-2.0
//
// White furnace of the aggregated yarn BSDF (issue 19), after pbrt-v4's Hair.WhiteFurnace: under a uniform
// white environment the energy a model scatters from w_i is P_T + the R lobe's exact energy (weight_R / 2)
// + the M lobe's integral (model/calibration.h m_lobe_energy). For every shipped model and any model file
// named in NY_FURNACE_MODELS (colon-separated; with NY_FURNACE_ONLY_LISTED those only: CTest's
// model.furnace_custom_yarn passes a fresh bake of a non-preset yarn), at every
// incident bin centre of the paper's maps (22 theta_i x 90 phi_i, where the calibration table holds):
//   * it never exceeds 1 by more than 1 % in any channel: the calibration table multiplies the networks'
//     energies up to 100x, and nothing else keeps the sum of the three lobes below 1;
//   * the sampler's mean weight (yarn_sample with the T lobe, 20 000 draws) equals it within 1 % plus
//     4 standard errors, at 11 x 12 directions, and within 0.5 % averaged over them: the weights the
//     renderer multiplies are the BSDF it evaluates.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/random.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

namespace {

std::vector<std::string> furnace_models()
{
  std::vector<std::string> paths;
  if (!std::getenv("NY_FURNACE_ONLY_LISTED")) {
    for (const char *p : {"fleece", "silk", "polyester", "cotton", "gabardine"}) {
      paths.push_back(model::builtin_model_path(p));
    }
  }
  if (const char *extra = std::getenv("NY_FURNACE_MODELS")) {
    std::stringstream ss(extra);
    for (std::string item; std::getline(ss, item, ':');) {
      if (!item.empty()) {
        paths.push_back(item);
      }
    }
  }
  return paths;
}

/* The largest furnace value of every model at sub x sub directions inside every incident bin of the paper's
 * maps (sub = 1: the bin centres) is at most 1 + 1 %. */
void expect_no_gain(int sub, const char *where)
{
  const std::vector<ny::Vec3> dirs = model::furnace_directions({22, 90, 45, 90}, sub, false);
  for (const std::string &path : furnace_models()) {
    const model::YarnModel m = model::load_model(path);
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    const model::FurnaceMax worst = model::white_furnace_max(p, dirs);
    ASSERT_TRUE(std::isfinite(worst.value)) << path;
    std::printf("%s: %s, largest white-furnace value %.4f (theta_i %.2f deg)\n", path.c_str(), where, worst.value,
                std::acos(double(worst.wi.z)) / kDeg);
    EXPECT_LE(worst.value, 1.01) << path << " " << where;
  }
}

}  // namespace

TEST(Furnace, NoModelScattersMoreThanItReceives)
{
  /* Where the calibration was computed and bounds P_T + E_R + E_M. */
  expect_no_gain(1, "at the bin centres");
}

/* Between the centres the table is bilinear while the networks (P_T above all) vary inside a cell; there
 * cotton scattered up to 4.7 % more than it received (1.0467 at theta_i 86.6 deg) and gabardine 3.9 % until
 * every bake bounded its table between the centres (D28). Checked at 2 x 2 directions inside every bin --
 * none of them where the bound evaluates the furnace. */
TEST(Furnace, NoGainBetweenCalibrationCentres)
{
  expect_no_gain(2, "between the centres");
}

/* bound_between_centres on a coarse table (6 x 8 nodes) of cotton's networks, with one node's c_M inflated
 * 3x: afterwards no direction it evaluates scatters more than it receives, a second pass changes nothing,
 * nodes that share no cell with the lowered ones keep their values, dP_T is never touched, and the table
 * is the same at 1 and 2 threads. */
TEST(Furnace, BoundBetweenCentresCapsEveryCellAndOnlyWhatItMust)
{
  if (std::getenv("NY_FURNACE_ONLY_LISTED")) {
    GTEST_SKIP() << "a property of the bound, not of the listed models";
  }
  model::YarnModel m = model::load_model(model::builtin_model_path("cotton"));
  constexpr int nt = 6, np = 8, sub = 3;
  m.calibration = model::EnergyCalibration{};
  m.calibration.theta_bins = nt;
  m.calibration.phi_bins = np;
  m.calibration.values.assign(size_t(nt * np * ny::kYarnCalStride), 1.0f);
  for (int k = 0; k < nt * np; k++) {
    m.calibration.values[size_t(k * ny::kYarnCalStride)] = 0.01f * float(k % 5); /* dP_T, to be left alone */
  }
  model::bound_between_centres(&m, sub, 1);
  const model::EnergyCalibration before = m.calibration;
  const int hot_t = 3, hot_p = 5, hot = hot_t * np + hot_p;
  for (int ch = 0; ch < 3; ch++) {
    m.calibration.values[size_t(hot * ny::kYarnCalStride + 4 + ch)] *= 3.0f;
  }
  model::YarnModel m2 = m;
  const model::CentreBound b = model::bound_between_centres(&m, sub, 1);
  model::bound_between_centres(&m2, sub, 2);
  EXPECT_EQ(m.calibration.values, m2.calibration.values) << "the table depends on the thread count";
  std::printf("inflated node: %d nodes lowered, smallest factor %.4f\n", b.nodes, b.smallest);
  ASSERT_GE(b.nodes, 1);
  EXPECT_LT(b.smallest, 0.75); /* 3x more M than a bounded table held cannot fit without cutting it */

  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const model::FurnaceMax worst = model::white_furnace_max(p, model::centre_cell_directions(nt, np, sub));
  EXPECT_LE(worst.value, 1.0 + 2e-5) << "theta_i " << std::acos(double(worst.wi.z)) / kDeg;
  EXPECT_EQ(model::bound_between_centres(&m, sub, 1).nodes, 0) << "a bounded table is bounded";

  for (int t = 0; t < nt; t++) {
    for (int q = 0; q < np; q++) {
      const int k = t * np + q;
      const float *now = &m.calibration.values[size_t(k * ny::kYarnCalStride)];
      const float *was = &before.values[size_t(k * ny::kYarnCalStride)];
      EXPECT_EQ(now[0], was[0]) << "dP_T of node " << k;
      /* Lowered: the inflated node and those that share a cell with it; every other node keeps its value. */
      const int dq = std::min((q - hot_p + np) % np, (hot_p - q + np) % np);
      if (std::abs(t - hot_t) > 1 || dq > 1) {
        for (int j = 1; j < ny::kYarnCalStride; j++) {
          EXPECT_EQ(now[j], was[j]) << "node " << k << " entry " << j;
        }
      }
    }
  }
  const float *at_hot = &m.calibration.values[size_t(hot * ny::kYarnCalStride)];
  EXPECT_LT(at_hot[4], 3.0f * before.values[size_t(hot * ny::kYarnCalStride + 4)]);
}

/* Past the calibration table's last theta_i centre (87.95 deg) a direction scatters exactly what that
 * centre's direction at the same azimuth scatters (D26), so at the phi_i bin centres, where the table is
 * bounded, it stays within 1 % of 1 all the way to 89.975 deg (before: up to 1.206, cotton at 89.975 deg). */
TEST(Furnace, NoGainPastTheLastCalibrationCentre)
{
  auto dir = [](double theta_deg, double phi) {
    const double th = theta_deg * kDeg;
    return ny::make_vec3(float(std::sin(th) * std::cos(phi)), float(std::sin(th) * std::sin(phi)), float(std::cos(th)));
  };
  for (const std::string &path : furnace_models()) {
    const model::YarnModel m = model::load_model(path);
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    ASSERT_GT(p.cal_theta_bins, 0) << path;
    const double theta_c = (p.cal_theta_bins - 0.5) * 90.0 / p.cal_theta_bins;
    double worst_centre = 0.0, worst_diff = 0.0;
    for (int k = 0; k < 2 * p.cal_phi_bins; k++) {
      const double phi = -kPi + k * kPi / p.cal_phi_bins; /* odd k: a phi_i bin centre, even k: an edge */
      const ny::Rgb at_c = model::white_furnace(p, dir(theta_c - 1e-4, phi));
      for (double theta_deg : {88.5, 89.4, 89.975}) {
        const ny::Rgb e = model::white_furnace(p, dir(theta_deg, phi));
        worst_diff = std::max({worst_diff, std::abs(double(e.r - at_c.r)), std::abs(double(e.g - at_c.g)),
                               std::abs(double(e.b - at_c.b))});
        if (k % 2 == 1) {
          worst_centre = std::max({worst_centre, double(e.r), double(e.g), double(e.b)});
        }
      }
    }
    std::printf("%s: past the last centre, largest value at the phi_i centres %.4f, largest difference from the "
                "centre row %.2e\n", path.c_str(), worst_centre, worst_diff);
    EXPECT_LE(worst_centre, 1.01) << path;
    EXPECT_LT(worst_diff, 2e-4) << path;
  }
}

TEST(Furnace, TheMaximumIsTheLargestChannelOverTheDirections)
{
  /* white_furnace_max against a plain loop (the verb `neuralyarn furnace` and the stability suite read it),
   * at 1 and 2 threads; the directions: bin centres of a coarse grid and the grazing edge. */
  const model::YarnModel m = model::load_model(model::builtin_model_path("cotton"));
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const std::vector<ny::Vec3> dirs = model::furnace_directions({6, 8, 45, 90}, 1, true);
  ASSERT_EQ(dirs.size(), 6u * 8u + 8u);
  EXPECT_NEAR(dirs.back().z, std::cos(89.975 * kDeg), 1e-6);
  double want = 0.0;
  for (const ny::Vec3 &wi : dirs) {
    const ny::Rgb e = model::white_furnace(p, wi);
    want = std::max({want, double(e.r), double(e.g), double(e.b)});
  }
  const model::FurnaceMax got = model::white_furnace_max(p, dirs, 1);
  EXPECT_EQ(got.value, want);
  EXPECT_EQ(model::white_furnace_max(p, dirs, 2).value, want);
  const ny::Rgb at = model::white_furnace(p, dirs[size_t(got.index)]);
  EXPECT_EQ(std::max({double(at.r), double(at.g), double(at.b)}), want);
}

TEST(Furnace, SampledWeightsIntegrateToTheFurnace)
{
  const rdm::MapResolution bins{11, 12, 45, 90};
  constexpr int kDraws = 20000;
  for (const std::string &path : furnace_models()) {
    const model::YarnModel m = model::load_model(path);
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    Rng rng(2024);
    double mean_rel = 0.0;
    int n = 0;
    for (int ti = 0; ti < bins.theta_i; ti++) {
      for (int pi = 0; pi < bins.phi_i; pi++) {
        const ny::Vec3 wi = model::incident_sub_direction(bins, ti, pi, 0, 1);
        const ny::Rgb want = model::white_furnace(p, wi);
        double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
        for (int k = 0; k < kDraws; k++) {
          ny::YarnSample s;
          const float u0 = uniform_float(rng), u1 = uniform_float(rng), u2 = uniform_float(rng);
          if (!ny::yarn_sample(p, wi, u0, u1, u2, true, &s)) {
            continue; /* nothing scattered: weight 0 */
          }
          const float w[3] = {s.weight.r, s.weight.g, s.weight.b};
          for (int c = 0; c < 3; c++) {
            sum[c] += w[c];
            sum2[c] += double(w[c]) * w[c];
          }
        }
        const float want_c[3] = {want.r, want.g, want.b};
        for (int c = 0; c < 3; c++) {
          const double mean = sum[c] / kDraws;
          const double se = std::sqrt(std::max(0.0, sum2[c] / kDraws - mean * mean) / kDraws);
          EXPECT_NEAR(mean, want_c[c], 0.01 * want_c[c] + 4.0 * se + 1e-6)
              << path << " theta_i bin " << ti << " phi_i bin " << pi << " channel " << c;
          if (want_c[c] > 1e-3) {
            mean_rel += mean / want_c[c] - 1.0;
            n++;
          }
        }
      }
    }
    mean_rel /= std::max(1, n);
    std::printf("%s: sampled furnace / integrated furnace - 1, mean over %d direction-channels: %+.4f\n",
                path.c_str(), n, mean_rel);
    EXPECT_LT(std::abs(mean_rel), 0.005) << path;
  }
}
