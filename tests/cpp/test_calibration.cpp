// SPDX-License-Identifier: Apache-2.0
//
// The energy calibration table (model/calibration.h): computed on maps, it makes the model's P_T, R and M
// energies equal the maps' at every incident bin centre (coarse maps: no phi window, so exactly, up to
// float rounding), and against independent maps it lowers the albedo error of the uncalibrated networks.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/bake.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/fidelity.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"
#include "synthetic_model.h"

using namespace neuralyarn;

namespace {
rdm::RdmMaps small_maps(const FiberPreset &preset, uint64_t seed)
{
  rdm::GatherOptions o;
  o.paths = 1200000;
  o.seed = seed;
  o.bins = {6, 24, 12, 24};
  return rdm::gather(preset, o);
}
}  // namespace

TEST(Calibration, MatchesTheMapsAtBinCentresAndHelpsOnIndependentMaps)
{
  model::YarnModel m = model::load_model(model::builtin_model_path("cotton"));
  m.calibration = model::EnergyCalibration{};
  const rdm::RdmMaps a = small_maps(m.preset, 101), b = small_maps(m.preset, 102);
  model::FidelityOptions fo;
  fo.variance_directions = 0;
  const model::FidelityReport before_a = model::check_model(m, a, fo), before_b = model::check_model(m, b, fo);

  /* The table at the centres, before its bound between them (D28), which this test checks apart below. */
  model::YarnModel c = m;
  c.calibration = model::calibrate_energy(m, a, 0, 0);
  ASSERT_EQ(c.calibration.theta_bins, 6);
  ASSERT_EQ(c.calibration.phi_bins, 24);
  EXPECT_EQ(c.calibration.clamped, 0);
  const model::FidelityReport after_a = model::check_model(c, a, fo), after_b = model::check_model(c, b, fo);
  std::printf("maps A: albedo %.4f -> %.4f, P_T rms %.4f -> %.4f, R %.4f -> %.4f, M %.4f -> %.4f\n",
              before_a.albedo_mae_rel, after_a.albedo_mae_rel, before_a.T_rmse, after_a.T_rmse,
              before_a.R_energy_mae_rel, after_a.R_energy_mae_rel, before_a.M_energy_mae_rel, after_a.M_energy_mae_rel);
  std::printf("maps B: albedo %.4f -> %.4f, P_T rms %.4f -> %.4f, R %.4f -> %.4f, M %.4f -> %.4f\n",
              before_b.albedo_mae_rel, after_b.albedo_mae_rel, before_b.T_rmse, after_b.T_rmse,
              before_b.R_energy_mae_rel, after_b.R_energy_mae_rel, before_b.M_energy_mae_rel, after_b.M_energy_mae_rel);
  /* On the maps it was computed from: the exit energy is T + R + M, so every error is float rounding
   * (energies are sums of ~1000 floats) -- except where a bin's noisy total exceeds 1 (cotton's albedo is
   * ~0.99, 8300 paths per bin): there R and M are scaled so that it scatters what it receives, no more
   * (tests/cpp/test_furnace.cpp), which moves the means by ~0.2 %. */
  EXPECT_LT(after_a.T_rmse, 1e-5);
  EXPECT_LT(after_a.R_energy_mae_rel, 0.005);
  EXPECT_LT(after_a.M_energy_mae_rel, 0.005);
  EXPECT_LT(after_a.albedo_mae_rel, 0.005);
  /* Positive control: without its table the model is off by several per cent, five times the calibrated
   * model's error on independent maps, so a check_model that compared the model with itself (error 0)
   * fails here however the comparisons below are written. */
  EXPECT_GT(before_a.albedo_mae_rel, 0.02);
  EXPECT_GT(before_b.albedo_mae_rel, 0.02);
  /* On independent maps of the same size: what is left is the noise of two 8300-path bins (~1.5 % relative
   * each, both maps), far below the networks' own error. */
  EXPECT_LT(after_b.albedo_mae_rel, 0.5 * before_b.albedo_mae_rel);
  EXPECT_LT(after_b.albedo_mae_rel, 0.03);

  /* The bound between the centres only lowers R and M (never P_T), and on these coarse cells (15 x 15 deg, in
   * which the networks vary most) it still leaves the table closer to independent maps than no table. */
  model::YarnModel bounded = m;
  bounded.calibration = model::calibrate_energy(m, a);
  ASSERT_EQ(bounded.calibration.values.size(), c.calibration.values.size());
  double lowered = 0.0;
  for (size_t k = 0; k < c.calibration.values.size(); k++) {
    const float was = c.calibration.values[k], now = bounded.calibration.values[k];
    if (k % ny::kYarnCalStride == 0) {
      EXPECT_EQ(now, was) << "dP_T of node " << k / ny::kYarnCalStride;
    }
    else {
      EXPECT_LE(now, was) << "entry " << k;
      lowered = std::max(lowered, 1.0 - double(now) / double(was));
    }
  }
  const model::FidelityReport bounded_b = model::check_model(bounded, b, fo);
  std::printf("bounded between centres: largest cut %.1f %%, albedo on maps B %.4f\n", 100.0 * lowered,
              bounded_b.albedo_mae_rel);
  EXPECT_GT(lowered, 0.0); /* cotton at 6 x 24 gains energy between centres: the bound has work to do */
  EXPECT_LT(bounded_b.albedo_mae_rel, 0.75 * before_b.albedo_mae_rel);
}

/* The M lobe's quadrature runs the network on 16 exits at once; it must be bit for bit the plain sum of
 * yarn_eval_M over the grid in row-major order (the shipped cotton model, and gabardine's wider 6-32-32-3 M),
 * split at the equator or not, on a grid whose rows are not a multiple of 16 cells (the padded last block); and
 * a two-sided M. */
TEST(Calibration, MLobeQuadratureIsThePlainSumOfYarnEvalM)
{
  /* And a two-sided M (6 -> 6, D45), whose rows read one side's outputs each. */
  for (const char *preset : {"cotton", "gabardine", "two-sided"}) {
    const std::string name(preset);
    const model::YarnModel m = name == "two-sided" ? neuralyarn::testing::synthetic_model("fleece", 5, -3.0, -1.0, 6)
                                                   : model::load_model(model::builtin_model_path(preset));
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    for (const auto &[nt, np] : {std::pair{64, 128}, std::pair{6, 21}}) {
      const model::ExitGrid g(nt, np);
      for (const ny::Vec3 wi : {ny::make_vec3(0.3f, -0.2f, 0.93f), ny::make_vec3(0.9f, 0.4f, 0.17f)}) {
        const ny::YarnLobes l = ny::yarn_lobes(p, ny::normalize(wi));
        /* The plain sum, into `up` alone or split at the equator. */
        auto plain_sum = [&](bool split, double up[3], double down[3]) {
          for (int to = 0; to < nt; to++) {
            double *e = split && 2 * to >= nt ? down : up;
            for (int po = 0; po < np; po++) {
              const size_t q = size_t(to) * size_t(np) + size_t(po);
              const ny::Rgb v = ny::yarn_eval_M(p, l, ny::make_vec3(g.x[q], g.y[q], g.z[q]));
              e[0] += v.r * g.solid_angle[size_t(to)];
              e[1] += v.g * g.solid_angle[size_t(to)];
              e[2] += v.b * g.solid_angle[size_t(to)];
            }
          }
        };
        double up[3] = {0, 0, 0}, down[3] = {0, 0, 0};
        plain_sum(true, up, down);
        double su[3], sd[3];
        model::m_lobe_energy_split(p, l, g, true, su, sd);
        for (int c = 0; c < 3; c++) {
          EXPECT_EQ(su[c], up[c]) << preset << " " << nt << "x" << np << " channel " << c;
          EXPECT_EQ(sd[c], down[c]) << preset << " " << nt << "x" << np << " channel " << c;
          EXPECT_GT(down[c], 0.0) << preset;
        }
        if (nt == 64 && np == 128) {
          /* m_lobe_energy: the same cells summed into one accumulator. */
          double all[3] = {0, 0, 0}, none[3] = {0, 0, 0};
          plain_sum(false, all, none);
          const ny::Rgb e = model::m_lobe_energy(p, l);
          EXPECT_EQ(e.r, float(all[0]));
          EXPECT_EQ(e.g, float(all[1]));
          EXPECT_EQ(e.b, float(all[2]));
        }
      }
    }
  }
  EXPECT_THROW(model::ExitGrid(7, 16), std::invalid_argument);
}

/* The stability suite's very dark fiber (fleece with C_R 0.01 and C_TT 0.02), baked small. Near grazing
 * incidence P_T varies within a phi window (the gaps between fibers) and the T network's P_T is above the
 * window's mean at some bins; there P_T + E_R + E_M exceeds the window's exit energy while staying far below 1.
 * The table must leave R and M at their window's ratio there: the bound is energy conservation, not the
 * window's exit energy, which cut the dark fiber's R by up to 68 % at 88 deg (docs/decisions.md D35). Maps
 * at 36 phi_i bins: the first resolution with a window of 3 bins. */
TEST(Calibration, DarkFiberKeepsItsReflectionWhereTransmissionIsAboveTheWindowMean)
{
  FiberPreset dark = find_preset("fleece");
  dark.name = "dark";
  dark.C_R = {0.01, 0.01, 0.01};
  dark.C_TT = {0.02, 0.02, 0.02};
  rdm::GatherOptions o;
  o.paths = 2000000;
  o.seed = 35;
  o.bins = {6, 36, 12, 24};
  const rdm::RdmMaps maps = rdm::gather(dark, o);
  model::TrainModelOptions t;
  for (model::NetworkOptions *n : {&t.T, &t.R, &t.M}) {
    n->steps = 1000;
    n->samples = 20000;
    n->batch = 1024;
  }
  t.fit_proxy = false;
  model::YarnModel c = model::train_model(maps, t);
  c.calibration = model::calibrate_energy(c, maps, 0, 0); /* at the centres: D28's bound apart */

  model::FidelityOptions fo;
  fo.variance_directions = 0;
  const model::FidelityReport r = model::check_model(c, maps, fo);
  std::printf("R energy error per theta_i row:");
  for (const double e : r.R_rel_by_theta) {
    std::printf(" %.1f %%", 100.0 * e);
  }
  std::printf("; albedo %.2f %%\n", 100.0 * r.albedo_mae_rel);
  /* On the maps the table was computed from, the only differences left are the window's: R at a bin
   * against its 3-bin window's mean ratio, 1-2 % per row and 6.5 % in the last (82.5 deg), where the networks
   * vary most across a window. Bounded by the window's exit energy, that row was 40 % off. */
  for (size_t t = 0; t < r.R_rel_by_theta.size(); t++) {
    EXPECT_LT(r.R_rel_by_theta[t], 0.10) << "theta_i row " << t;
  }
}

/* The R-energy network with the maps' colour (3 -> 3, D65) leaves the calibration a rescaling of totals: on silk,
 * whose maps' single events are green-tinted by the light through a surface fiber (C_TT) while its C_R has almost no
 * green, the one-output network's colour (F of C_R) needed c_R of up to 24 in green, which the table alone made
 * right (issue 17: the calibration must not be what makes the model right). Trained on small maps the same way
 * both; the table at the centres, without its bound between them. */
TEST(Calibration, RgbReflectionNetworkLeavesTheTableNearOne)
{
  model::YarnModel m = model::load_model(model::builtin_model_path("silk"));
  const rdm::RdmMaps maps = small_maps(m.preset, 103);
  auto mean_deviation = [&](const char *widths) {
    model::NetworkOptions o = model::TrainModelOptions{}.R;
    o.widths = widths;
    o.samples = 50000;
    m.R = model::train_one("R", maps, o, ny::kMlpHeadExp, 2, 2, {}, nullptr);
    m.calibration = model::EnergyCalibration{};
    const model::EnergyCalibration c = model::calibrate_energy(m, maps, 2, 0);
    /* Mean |c_R - 1| per channel over every bin but the grazing row (where the maps' R is thinnest). */
    double dev[3] = {0, 0, 0};
    int n = 0;
    for (int ti = 0; ti + 1 < c.theta_bins; ti++) {
      for (int pi = 0; pi < c.phi_bins; pi++, n++) {
        const float *v = &c.values[(size_t(ti) * size_t(c.phi_bins) + size_t(pi)) * ny::kYarnCalStride];
        for (int k = 0; k < 3; k++) {
          dev[k] += std::abs(double(v[1 + k]) - 1.0);
        }
      }
    }
    std::printf("R %s: mean |c_R - 1| %.3f / %.3f / %.3f\n", widths, dev[0] / n, dev[1] / n, dev[2] / n);
    return std::array<double, 3>{dev[0] / n, dev[1] / n, dev[2] / n};
  };
  const std::array<double, 3> rgb = mean_deviation("3-7-7-3"), one = mean_deviation("3-7-7-1");
  /* Within 15 % on these maps (8 300 paths a bin: silk's green R energy a few per cent of its red, its noise
   * ~5 % a bin, and a network trained on 144 bins); the shipped-resolution bakes read 4-5 % (docs/benchmarks.md). */
  for (int k = 0; k < 3; k++) {
    EXPECT_LT(rgb[size_t(k)], 0.15) << "channel " << k;
  }
  /* Positive control: the one-output network's green is 180 % off, so the test sees the colour. */
  EXPECT_GT(one[1], 1.0);
}
