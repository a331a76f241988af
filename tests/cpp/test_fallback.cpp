// SPDX-License-Identifier: Apache-2.0
//
// The view-dependent fallback tables (model/fallback.h):
//   * at cell centres, P_T is the kernel's yarn_transmission + the calibration's dP_T, E_M_up + E_M_down is
//     m_lobe_energy, and E_R is the R lobe's energy by an independent quadrature around the specular cone
//     (beta_R = 1 degree for silk and cotton);
//   * P_T + E_R + E_M_up + E_M_down is the albedo that an independent Monte Carlo estimate through
//     yarn_sample gives (synthetic networks and a shipped model);
//   * the M quadrature has converged (default grid against 4x finer);
//   * the tables round-trip through the model file, the loader rejects corrupt or stale ones by name, and
//     models without them still load; the shipped models carry current tables.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/cycles_lobes.h"
#include "neuralyarn/model/fallback.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/units.h"
#include "quadrature.h"
#include "synthetic_model.h"

using namespace neuralyarn;
using neuralyarn::testing::synthetic_model;
namespace fs = std::filesystem;

namespace {

ny::Vec3 view(const model::FallbackTables &f, int i, int j)
{
  return ny::direction_from_angles(float(f.theta_center(i)), float(f.phi_center(j)));
}

double chan(const ny::Rgb &c, int k) { return k == 0 ? c.r : k == 1 ? c.g : c.b; }

/* The cells the expensive checks visit: normal view, oblique, near-grazing in theta and in phi. */
const std::vector<std::pair<int, int>> kCells = {{9, 9}, {4, 12}, {13, 3}, {1, 8}, {16, 16}, {9, 0}};

}  // namespace

TEST(Fallback, TablesAreTheKernelsValuesAtCellCentres)
{
  const model::YarnModel m = synthetic_model("fleece", 3);
  /* On m_lobe_energy's own grid the M energies must be its value split in two, to float rounding. */
  model::FallbackOptions o;
  o.quad_theta = 64;
  o.quad_phi = 128;
  const model::FallbackTables f = model::compute_fallback(m, o);
  ASSERT_EQ(f.theta_bins, 18);
  ASSERT_EQ(f.phi_bins, 18);
  ASSERT_EQ(f.P_T.size(), 324u);
  ASSERT_EQ(f.E_R.size(), 972u);
  EXPECT_NEAR(f.theta_center(0), -85.0 * kDeg, 1e-12);
  EXPECT_NEAR(f.phi_center(17), 85.0 * kDeg, 1e-12);
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  for (int i = 0; i < f.theta_bins; i++) {
    for (int j = 0; j < f.phi_bins; j++) {
      const size_t k = size_t(i * f.phi_bins + j);
      const ny::Vec3 wi = view(f, i, j);
      float dP_T;
      ny::Rgb c_R, c_M;
      /* Energies at the kernel's energy direction (w_i itself but past the table's last theta_i centre). */
      const ny::Vec3 we = ny::yarn_energy_direction(p, wi);
      ny::yarn_calibration(p, we, &dP_T, &c_R, &c_M);
      const float pt = std::clamp(ny::yarn_transmission(p, we) + dP_T, 0.0f, 1.0f);
      EXPECT_NEAR(f.P_T[k], pt, 1e-6) << i << " " << j;
      const ny::Rgb em = model::m_lobe_energy(p, ny::yarn_lobes(p, wi));
      for (int c = 0; c < 3; c++) {
        const double sum = double(f.E_M_up[k * 3 + size_t(c)]) + f.E_M_down[k * 3 + size_t(c)];
        EXPECT_NEAR(sum, chan(em, c), 1e-5 * chan(em, c) + 1e-9) << i << " " << j << " channel " << c;
      }
    }
  }
  /* The scalars are the model's. */
  EXPECT_NEAR(f.beta_R_rad, m.preset.fiber_params().beta_R, 1e-7);
  EXPECT_NEAR(f.twist_tilt_rad, std::atan(kPi * m.preset.alpha), 1e-6);
  EXPECT_NEAR(f.beta_M_rad, m.proxy.beta_M, 1e-7);
  EXPECT_NEAR(f.gamma_M_rad, m.proxy.gamma_M, 1e-7);
  EXPECT_NEAR(f.kappa_M, m.proxy.kappa_M, 1e-7);
  EXPECT_GT(f.kappa_M_up, f.kappa_M); /* the lobe is centred on the normal: more of it is up than uniform */
  EXPECT_LT(f.kappa_M_up, 1.0);
}

/* E_R = c_R rho_R F / 2 (what the tables store) against the integral of the R lobe, node by node in each
 * node's fiber frame: 30-point Gauss-Legendre panels no wider than beta_R / 2 within 12 beta_R of the
 * specular cone theta~_o = -theta~_i, wider outside; the azimuth is uniform on (-pi/2, pi/2) (one panel set
 * split at the cut). */
TEST(Fallback, ReflectionEnergyMatchesQuadratureAroundTheSpecularCone)
{
  for (const char *preset : {"silk", "cotton", "fleece"}) {
    const model::YarnModel m = synthetic_model(preset, 7);
    model::FallbackOptions o;
    o.theta_bins = 6;
    o.phi_bins = 6;
    const model::FallbackTables f = model::compute_fallback(m, o);
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    const double beta = p.fiber.beta_R;
    for (int i = 0; i < f.theta_bins; i++) {
      for (int j = 0; j < f.phi_bins; j++) {
        const ny::YarnLobes l = ny::yarn_lobes(p, view(f, i, j));
        std::array<double, 3> e{};
        for (int q = 0; q < l.n_R; q++) {
          /* Node q's lobe in its own fiber frame, about its specular cone (its mean, the -theta~ of w_i). */
          const double mu = double(l.node[q].tn_R.mu);
          std::vector<double> pts;
          for (int s = -12; s <= 12; s++) {
            pts.push_back(mu + 0.5 * s * beta);
          }
          const std::vector<double> ts = nytest::breakpoints(pts, -0.5 * kPi, 0.5 * kPi, 0.2);
          const std::vector<double> ps = nytest::breakpoints({-0.5 * kPi, 0.5 * kPi}, -kPi, kPi, 0.5);
          const auto eq = nytest::integrate_2d_fixed<3>(
              [&](double th, double ph) {
                ny::Rgb R, TT;
                ny::yarn_eval_R_parts(l, q, ny::yarn_outgoing(ny::direction_from_angles(float(th), float(ph))), &R,
                                      &TT);
                const ny::Rgb v = (ny::make_rgb(1.0f) - l.tau) * R + l.tau * TT;
                const double w = std::cos(th) / l.n_R;
                return std::array<double, 3>{v.r * w, v.g * w, v.b * w};
              },
              ts, ps);
          for (int c = 0; c < 3; c++) {
            e[size_t(c)] += eq[size_t(c)];
          }
        }
        const size_t k = size_t(i * f.phi_bins + j);
        for (int c = 0; c < 3; c++) {
          EXPECT_NEAR(f.E_R[k * 3 + size_t(c)], e[size_t(c)], 1e-4 * e[size_t(c)] + 1e-9)
              << preset << " cell " << i << " " << j << " channel " << c;
        }
      }
    }
  }
}

/* P_T + E_R + E_M_up + E_M_down against the mean of yarn_sample's weights (T lobe included: weight 1
 * with probability P_T, eval / mixture pdf otherwise), which shares only the kernel's eval with the tables.
 * 400 000 samples per cell, fixed seed; the tolerance is 4.5 standard errors of that mean (measured per
 * cell and channel) plus 0.2 % for the 128 x 256 M quadrature (see MQuadratureHasConverged). The standard errors are
 * themselves required to be small, so that the check means something. */
TEST(Fallback, AlbedoMatchesMonteCarloThroughTheSampler)
{
  struct Case {
    std::string name;
    model::YarnModel m;
  };
  std::vector<Case> cases;
  cases.push_back({"synthetic fleece", synthetic_model("fleece", 5)});
  cases.push_back({"synthetic silk", synthetic_model("silk", 9, -2.0)});
  cases.push_back({"shipped silk", model::load_model(model::builtin_model_path("silk"))});
  cases.push_back({"shipped gabardine", model::load_model(model::builtin_model_path("gabardine"))});
  model::FallbackOptions o; /* 128 x 256: M energy within 0.2 % (MQuadratureHasConverged), 4x faster */
  o.quad_theta = 128;
  o.quad_phi = 256;
  for (const Case &cs : cases) {
    const model::FallbackTables f = model::compute_fallback(cs.m, o);
    const std::vector<float> flat = cs.m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    std::mt19937_64 rng(20240611);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    for (const auto &[i, j] : kCells) {
      const ny::Vec3 wi = view(f, i, j);
      constexpr int n = 400000;
      double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
      for (int s = 0; s < n; s++) {
        ny::YarnSample smp;
        const float u0 = U(rng), u1 = U(rng), u2 = U(rng);
        if (!ny::yarn_sample(p, wi, std::min(u0, 0.99999994f), std::min(u1, 0.99999994f),
                             std::min(u2, 0.99999994f), true, &smp)) {
          continue;
        }
        for (int c = 0; c < 3; c++) {
          const double w = chan(smp.weight, c);
          sum[c] += w;
          sum2[c] += w * w;
        }
      }
      const size_t k = size_t(i * f.phi_bins + j);
      for (int c = 0; c < 3; c++) {
        const double mean = sum[c] / n, se = std::sqrt(std::max(0.0, sum2[c] / n - mean * mean) / (n - 1));
        const double table = double(f.P_T[k]) + f.E_R[k * 3 + size_t(c)] + f.E_M_up[k * 3 + size_t(c)] +
                             f.E_M_down[k * 3 + size_t(c)];
        EXPECT_LT(se, 0.01 * table + 1e-4) << cs.name << ": the estimate is too noisy to test anything";
        EXPECT_NEAR(table, mean, 4.5 * se + 2e-3 * table)
            << cs.name << " cell (" << i << ", " << j << ") channel " << c << ": MC " << mean << " +- " << se;
      }
    }
  }
}

/* The M grid against 512 x 1024 on every shipped model, 3 x 3 views (theta, phi in {-60, 0, 60} degrees).
 * The midpoint rule converges as h^2 (each doubling divides the error by 4), so the default 256 x 512 is
 * off by about a third of its difference to 512 x 1024, and 128 x 256 by 4/3 of its own. Measured (6 x 6
 * views, silk and gabardine, against 1024 x 2048): 64 x 128 (m_lobe_energy's grid) 0.77 %, 128 x 256
 * 0.11 %, 256 x 512 0.02 % of the M energy. */
TEST(Fallback, MQuadratureHasConverged)
{
  double worst_default = 0.0, worst_half = 0.0;
  for (const char *preset : {"fleece", "silk", "polyester", "cotton", "gabardine"}) {
    const model::YarnModel m = model::load_model(model::builtin_model_path(preset));
    model::FallbackOptions half, def, fine;
    half.theta_bins = def.theta_bins = fine.theta_bins = 3;
    half.phi_bins = def.phi_bins = fine.phi_bins = 3;
    half.quad_theta = 128;
    half.quad_phi = 256;
    fine.quad_theta = 512;
    fine.quad_phi = 1024;
    const model::FallbackTables a = model::compute_fallback(m, half), d = model::compute_fallback(m, def),
                                b = model::compute_fallback(m, fine);
    auto worst = [&](const model::FallbackTables &t) {
      double w = 0.0;
      for (size_t k = 0; k < t.E_M_up.size(); k++) {
        const double total = double(b.E_M_up[k]) + b.E_M_down[k];
        w = std::max(w, std::abs(double(t.E_M_up[k]) - b.E_M_up[k]) / total);
        w = std::max(w, std::abs(double(t.E_M_down[k]) - b.E_M_down[k]) / total);
      }
      return w;
    };
    const double wa = worst(a), wd = worst(d);
    std::printf("%-10s M energy against 512x1024: 128x256 %.2e, %dx%d (default) %.2e of the M energy\n", preset, wa,
                def.quad_theta, def.quad_phi, wd);
    worst_half = std::max(worst_half, wa);
    worst_default = std::max(worst_default, wd);
  }
  EXPECT_LT(worst_half, 3e-3);
  EXPECT_LT(worst_default, 1e-3);
}

/* The hash that ties tables to their model: FNV-1a 64 over little-endian float32 bytes, pinned to values
 * that osl/generate_osl.py's implementation gives too (the generator refuses stale tables with it). */
TEST(Fallback, KernelArrayHashIsFnv1a64OfLittleEndianFloats)
{
  EXPECT_EQ(model::fnv1a64_hex({}), "cbf29ce484222325");
  EXPECT_EQ(model::fnv1a64_hex({1.0f, -0.0f, 2.5f}), "9a4c6dab8532d978");
}

TEST(Fallback, RoundTripsThroughTheModelFileAndBadTablesAreRejected)
{
  const fs::path dir = fs::temp_directory_path() / ("ny_fallback_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  model::YarnModel m = synthetic_model("polyester", 13);
  {
    /* Without tables: written without the key, loads without them. */
    const nlohmann::json j = model::model_to_json(m);
    EXPECT_FALSE(j.contains("fallback"));
    EXPECT_FALSE(model::model_from_json(j, "test").fallback.has_value());
  }
  model::FallbackOptions o;
  o.theta_bins = 5;
  o.phi_bins = 7;
  m.fallback = model::compute_fallback(m, o);
  const std::string good = (dir / "good.json").string();
  model::save_model(m, good);
  const model::YarnModel back = model::load_model(good);
  ASSERT_TRUE(back.fallback.has_value());
  const model::FallbackTables &a = *m.fallback, &b = *back.fallback;
  EXPECT_EQ(b.theta_bins, 5);
  EXPECT_EQ(b.phi_bins, 7);
  EXPECT_EQ(a.P_T, b.P_T) << "the tables must round-trip exactly";
  EXPECT_EQ(a.E_R, b.E_R);
  EXPECT_EQ(a.E_M_up, b.E_M_up);
  EXPECT_EQ(a.E_M_down, b.E_M_down);
  EXPECT_EQ(a.C_R, b.C_R);
  EXPECT_EQ(a.kernel_flat_hash, b.kernel_flat_hash);
  EXPECT_DOUBLE_EQ(a.kappa_M_up, b.kappa_M_up);
  EXPECT_EQ(model::model_to_json(back), model::model_to_json(m)) << "load + save must be the identity";

  const nlohmann::json j = model::model_to_json(m);
  ASSERT_TRUE(j.contains("fallback"));
  EXPECT_EQ(j["fallback"]["version"], 2);
  EXPECT_EQ(a.W, b.W);
  ASSERT_EQ(b.lobes.size(), 6u);
  EXPECT_EQ(j["fallback"]["theta_range_deg"], nlohmann::json({-90, 90}));
  auto expect_error = [&](const std::string &name, const nlohmann::json &v, const std::string &needle) {
    const std::string path = (dir / name).string();
    std::ofstream(path) << v.dump();
    try {
      model::load_model(path);
      ADD_FAILURE() << name << " was accepted";
    }
    catch (const model::ModelError &e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("fallback"), std::string::npos) << name << ": " << what;
      EXPECT_NE(what.find(needle), std::string::npos) << name << ": " << what;
      EXPECT_NE(what.find(path), std::string::npos) << "the message must name the file";
    }
  };
  nlohmann::json v = j;
  v["fallback"]["E_R"].erase(v["fallback"]["E_R"].size() - 1);
  expect_error("short.json", v, "'E_R' has 104 values, expected 105");
  v = j;
  v["fallback"]["theta_bins"] = 6;
  expect_error("bins.json", v, "'P_T' has 35 values, expected 42");
  v = j;
  v["fallback"]["E_M_up"][7] = nullptr; /* what a NaN becomes in JSON */
  expect_error("nan.json", v, "'E_M_up' entry 7 is not a number");
  v = j;
  v["fallback"]["P_T"][3] = 1.01;
  expect_error("pt.json", v, "'P_T' entry 3 = 1.01 is outside [0, 1]");
  v = j;
  v["fallback"]["E_M_down"][0] = -0.001;
  expect_error("negative.json", v, "'E_M_down' entry 0 = -0.001 is outside [0, 1.5]");
  v = j;
  v["fallback"]["E_R"][2] = 1e39;
  expect_error("huge.json", v, "'E_R' entry 2");
  v = j;
  v["fallback"]["version"] = 1;
  expect_error("version.json", v, "version 1 is not supported");
  v = j;
  v["fallback"]["W"][11] = -0.5;
  expect_error("weight.json", v, "'W' entry 11 = -0.5 is outside [0, 100]");
  v = j;
  v["fallback"]["lobes"][0]["alpha_x"] = 0.5;
  expect_error("lobes.json", v, "'lobes' must be");
  v = j;
  v["fallback"].erase("E_M_down");
  expect_error("missing.json", v, "missing array 'E_M_down'");
  v = j;
  v["fallback"]["beta_M_rad"] = 0.5;
  expect_error("scalar.json", v, "'beta_M_rad' = 0.5 disagrees with the model");
  v = j;
  v["fallback"]["kernel_flat_fnv1a64"] = "0123456789abcdef";
  expect_error("hash.json", v, "computed for another model");
  {
    /* Stale: the model was changed (here its calibration table) after the tables were computed. */
    model::YarnModel changed = m;
    changed.calibration.values[1] *= 1.5f;
    expect_error("stale.json", model::model_to_json(changed), "re-run `neuralyarn fallback MODEL`");
  }
  fs::remove_all(dir);
}

/* The shipped models carry tables (the loader has checked, by the kernel array's hash, that they belong to
 * the model); for two of them (recomputing costs ~5 s each) they also render as a fresh computation does. */
TEST(Fallback, ShippedModelsCarryCurrentTables)
{
  for (const char *preset : {"fleece", "silk", "polyester", "cotton", "gabardine"}) {
    const model::YarnModel m = model::load_model(model::builtin_model_path(preset));
    ASSERT_TRUE(m.fallback.has_value()) << preset << ": run `neuralyarn fallback models/" << preset << ".json`";
    EXPECT_EQ(m.fallback->theta_bins, 18);
    EXPECT_EQ(m.fallback->phi_bins, 18);
    if (std::string(preset) != "silk" && std::string(preset) != "gabardine") {
      continue;
    }
    const model::FallbackTables f = model::compute_fallback(m);
    for (size_t k = 0; k < f.P_T.size(); k++) {
      EXPECT_NEAR(m.fallback->P_T[k], f.P_T[k], 1e-6) << preset;
    }
    /* The weights are a means; what renders is their lobes' sum. Where two lobes coincide (silk: its R lobe and the
     * M ladder's first, both at the roughness floor) a cell's split between them is not unique, and a machine of
     * another instruction set (-march=native) splits it otherwise. So the fallback as it renders, at every cell
     * centre's w_i and 400 w_o over the sphere, must equal the fresh tables' within 1e-5 (relative to the larger of
     * 1 and the value). */
    ASSERT_EQ(m.fallback->W.size(), f.W.size());
    double worst = 0.0;
    for (int i = 0; i < f.theta_bins; i++) {
      for (int j = 0; j < f.phi_bins; j++) {
        const ny::Vec3 wi = ny::direction_from_angles(float(f.theta_center(i)), float(f.phi_center(j)));
        for (int a = 0; a < 20; a++) {
          for (int b = 0; b < 20; b++) {
            const double t = kPi * (a + 0.5) / 20.0, ph = 2.0 * kPi * (b + 0.5) / 20.0;
            const model::cycles_lobes::Dir wo{std::sin(t) * std::cos(ph), std::sin(t) * std::sin(ph), std::cos(t)};
            const auto shipped = model::fallback_eval(*m.fallback, {wi.x, wi.y, wi.z}, wo);
            const auto fresh = model::fallback_eval(f, {wi.x, wi.y, wi.z}, wo);
            for (int c = 0; c < 3; c++) {
              worst = std::max(worst, std::abs(double(shipped[c]) - fresh[c]) / std::max(1.0, std::abs(double(fresh[c]))));
            }
          }
        }
      }
    }
    EXPECT_LT(worst, 1e-5) << preset;
    for (size_t k = 0; k < f.E_R.size(); k++) {
      EXPECT_NEAR(m.fallback->E_R[k], f.E_R[k], 1e-6) << preset;
      EXPECT_NEAR(m.fallback->E_M_up[k], f.E_M_up[k], 1e-6) << preset;
      EXPECT_NEAR(m.fallback->E_M_down[k], f.E_M_down[k], 1e-6) << preset;
    }
  }
}

/* fallback_lobes: alpha = 0.9147 beta where that is above the floor; no GGX lobe below kFallbackAlphaMin
 * (a glossy fiber's R lobe as a stock GGX renders garments as glitter, D60), and the M ladder's lobes distinct
 * and in order even where beta_M's alpha is below the floor. */
TEST(Fallback, LobesKeepTheRoughnessFloorAndADistinctLadder)
{
  const double per_beta = std::sqrt(2.0 * std::log(2.0)) / (2.0 * std::sqrt(std::sqrt(2.0) - 1.0));
  for (const double beta_R_deg : {0.5, 1.0, 3.0, 8.0, 20.0}) {
    for (const double beta_M_deg : {0.5, 2.0, 6.0, 12.0, 20.0}) {
      model::FallbackTables f;
      f.beta_R_rad = beta_R_deg * kPi / 180.0;
      f.beta_M_rad = beta_M_deg * kPi / 180.0;
      const std::vector<model::FallbackLobe> lobes = model::fallback_lobes(f);
      ASSERT_EQ(lobes.size(), 6u);
      for (int k = 0; k < 4; k++) {
        ASSERT_EQ(lobes[size_t(k)].closure, "ggx");
        EXPECT_GE(lobes[size_t(k)].alpha_x, model::kFallbackAlphaMin) << beta_R_deg << " " << beta_M_deg << " " << k;
        EXPECT_LE(lobes[size_t(k)].alpha_x, 1.0);
        EXPECT_EQ(lobes[size_t(k)].alpha_y, 1.0);
      }
      EXPECT_LT(lobes[1].alpha_x, lobes[2].alpha_x) << beta_M_deg;
      EXPECT_LT(lobes[2].alpha_x, lobes[3].alpha_x) << beta_M_deg;
      const double aR = per_beta * f.beta_R_rad, aM = per_beta * f.beta_M_rad;
      if (aR >= model::kFallbackAlphaMin) {
        EXPECT_NEAR(lobes[0].alpha_x, aR, 1e-12);
      }
      if (aM >= 2.0 * model::kFallbackAlphaMin) {
        EXPECT_NEAR(lobes[1].alpha_x, 0.5 * aM, 1e-12);
        EXPECT_NEAR(lobes[2].alpha_x, aM, 1e-12);
      }
      EXPECT_EQ(lobes[4].closure, "diffuse");
      EXPECT_EQ(lobes[5].closure, "translucent");
    }
  }
}

/* The host copy of Cycles' GGX (model/cycles_lobes.h): its importance-sampled albedo equals a brute
 * midpoint quadrature of its eval over the hemisphere, for a narrow anisotropic lobe (silk's R), a
 * medium one and an isotropic rough one, at normal, oblique and grazing views; the diffuse and
 * translucent lobes integrate to 1 over their hemispheres. */
TEST(Fallback, CyclesLobesAreNormalisedAsCyclesEvaluatesThem)
{
  namespace cl = model::cycles_lobes;
  const int nt = 2048, np = 1024;
  auto quad = [&](auto f) {
    double s = 0.0;
    for (int a = 0; a < nt; a++) {
      const double th = 0.5 * kPi * (a + 0.5) / nt; /* polar angle from N */
      const double dw = std::sin(th) * (0.5 * kPi / nt) * (2.0 * kPi / np);
      for (int b = 0; b < np; b++) {
        const double ph = 2.0 * kPi * (b + 0.5) / np;
        s += f(cl::Dir{std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)}) * dw;
      }
    }
    return s;
  };
  for (const auto &[ax, ay] : {std::pair{0.05, 1.0}, std::pair{0.2, 0.6}, std::pair{0.8, 0.8}}) {
    for (const cl::Dir &v : {cl::Dir{0.0, 0.0, 1.0}, cl::Dir{0.5, 0.3, std::sqrt(0.66)},
                             cl::Dir{0.2, -0.95, std::sqrt(1.0 - 0.04 - 0.9025)}}) {
      const double ref = quad([&](const cl::Dir &o) { return cl::ggx_eval(ax, ay, v, o); });
      const double is = cl::ggx_albedo(ax, ay, v);
      /* Both converge well below this (the quadrature resolves alpha_x = 0.05 with ~40 cells). */
      EXPECT_NEAR(is, ref, 0.003) << "alpha " << ax << " x " << ay << ", view z " << v.z;
      EXPECT_GT(is, 0.2);
      EXPECT_LE(is, 1.0);
    }
  }
  EXPECT_NEAR(quad([](const cl::Dir &o) { return cl::diffuse_eval(o); }), 1.0, 1e-5);
  EXPECT_NEAR(quad([](const cl::Dir &o) { return cl::translucent_eval(cl::Dir{o.x, o.y, -o.z}); }), 1.0, 1e-5);
}

/* The fitted weights (version 2): under uniform light the fallback returns the view's R + M albedo
 * (sum_k W_k albedo_k = E_R + E_M_up + E_M_down), and the fit follows the model's shape: over the light
 * directions its relative error is far below that of the same energy spread by the model's own sampling
 * lobes' Cycles counterparts of version 1 would give; measured on silk at the cells of kCells. */
TEST(Fallback, FittedWeightsKeepTheEnergyAndFollowTheModel)
{
  namespace cl = model::cycles_lobes;
  const model::YarnModel m = model::load_model(model::builtin_model_path("silk"));
  ASSERT_TRUE(m.fallback.has_value());
  const model::FallbackTables &f = *m.fallback;
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const size_t K = f.lobes.size();
  for (const auto &[i, j] : kCells) {
    const size_t k = size_t(i) * size_t(f.phi_bins) + size_t(j);
    const ny::Vec3 wv = view(f, i, j);
    const ny::Vec3 vf = ny::yarn_to_surface_fiber(p.twist, wv);
    const cl::Dir v{vf.x, vf.y, vf.z};
    for (int c = 0; c < 3; c++) {
      const double E = double(f.E_R[k * 3 + size_t(c)]) + f.E_M_up[k * 3 + size_t(c)] + f.E_M_down[k * 3 + size_t(c)];
      double sum = 0.0;
      for (size_t q = 0; q < K; q++) {
        sum += double(f.W[(k * K + q) * 3 + size_t(c)]) * model::fallback_lobe_albedo(f.lobes[q], v);
      }
      /* The constraint row weighs 10^4 times the fit: it holds to float rounding of the weights. */
      EXPECT_NEAR(sum, E, 1e-3 * E + 1e-6) << "cell " << i << "," << j << " channel " << c;
    }
    /* Shape, red channel: mean |fallback - S| / (S + eps) over the sphere, against the same energy in the
     * diffuse + translucent lobes only (the up / down split of the model). */
    const ny::YarnLobes l = ny::yarn_lobes(p, wv);
    const double E = double(f.E_R[k * 3]) + f.E_M_up[k * 3] + f.E_M_down[k * 3];
    const double up = double(f.E_R[k * 3]) + f.E_M_up[k * 3], down = f.E_M_down[k * 3];
    const double eps = 0.1 * E / (4.0 * kPi);
    double err_fit = 0.0, err_flat = 0.0, total = 0.0;
    const int nt = 256, np = 128;
    for (int a = 0; a < nt; a++) {
      const double th = -0.5 * kPi + kPi * (a + 0.5) / nt;
      for (int b = 0; b < np; b++) {
        const double ph = -kPi + 2.0 * kPi * (b + 0.5) / np;
        const double dw = std::cos(th) * (kPi / nt) * (2.0 * kPi / np);
        const cl::Dir o{std::sin(th), std::cos(th) * std::sin(ph), std::cos(th) * std::cos(ph)};
        const ny::Vec3 wo = ny::surface_fiber_to_yarn(p.twist, ny::make_vec3(float(o.x), float(o.y), float(o.z)));
        const double S = ny::yarn_eval_lobes(p, l, wo).r;
        double fit = 0.0;
        for (size_t q = 0; q < K; q++) {
          fit += double(f.W[(k * K + q) * 3]) * model::fallback_lobe_eval(f.lobes[q], v, o);
        }
        const double flat_lobes = up * cl::diffuse_eval(o) + down * cl::translucent_eval(o);
        err_fit += std::abs(fit - S) / (S + eps) * dw;
        err_flat += std::abs(flat_lobes - S) / (S + eps) * dw;
        total += dw;
      }
    }
    err_fit /= total;
    err_flat /= total;
    EXPECT_LT(err_fit, 0.5 * err_flat) << "cell " << i << "," << j << ": relative error " << err_fit << " vs "
                                       << err_flat;
  }
}

/* The fallback as stock Blender renders it (fallback_at / fallback_eval / fallback_albedo: the instrument of
 * `cycles-scene --predict-fallback`). At a cell centre it is that cell's weights on the lobes in the
 * surface-fiber frame of the kernel (yarn_to_surface_fiber: a sign error in the twist's tilt fails here on
 * fleece, tilt 37 degrees), under uniform light it returns the model's albedo there (the fit's constraint),
 * and between centres the weights are the bilinear mix of the four cells around the view. */
TEST(Fallback, RenderedFallbackIsTheTablesLookedUpAsTheShadersDo)
{
  namespace cl = model::cycles_lobes;
  const model::YarnModel m = model::load_model(model::builtin_model_path("fleece"));
  ASSERT_TRUE(m.fallback.has_value());
  const model::FallbackTables &f = *m.fallback;
  ASSERT_GT(f.twist_tilt_rad, 0.3);
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const size_t K = f.lobes.size();
  auto dir = [](const ny::Vec3 &w) { return cl::Dir{w.x, w.y, w.z}; };
  for (const auto &[i, j] : kCells) {
    const size_t k = size_t(i) * size_t(f.phi_bins) + size_t(j);
    const ny::Vec3 wv = view(f, i, j);
    const model::FallbackAt at = model::fallback_at(f, dir(wv));
    EXPECT_NEAR(at.P_T, f.P_T[k], 1e-6);
    for (size_t q = 0; q < K * 3; q++) {
      EXPECT_NEAR(at.W[q], f.W[k * K * 3 + q], 1e-6 * (1.0 + f.W[k * K * 3 + q]));
    }
    const auto albedo = model::fallback_albedo(f, dir(wv));
    for (int c = 0; c < 3; c++) {
      const double E = double(f.P_T[k]) + f.E_R[k * 3 + size_t(c)] + f.E_M_up[k * 3 + size_t(c)] +
                       f.E_M_down[k * 3 + size_t(c)];
      EXPECT_NEAR(albedo[size_t(c)], E, 1e-3 * E + 1e-6) << "cell " << i << "," << j << " channel " << c;
    }
    /* Lights around the sphere, in the yarn frame. */
    for (int a = 0; a < 12; a++) {
      const double th = -1.4 + 2.8 * a / 11.0, ph = 0.5 + 2.0 * kPi * a / 12.0;
      const ny::Vec3 wl = ny::make_vec3(float(std::sin(th)), float(std::cos(th) * std::sin(ph)),
                                        float(std::cos(th) * std::cos(ph)));
      const ny::Vec3 vf = ny::yarn_to_surface_fiber(p.twist, wv), lf = ny::yarn_to_surface_fiber(p.twist, wl);
      double expect[3] = {0.0, 0.0, 0.0};
      for (size_t q = 0; q < K; q++) {
        const double e = model::fallback_lobe_eval(f.lobes[q], dir(vf), dir(lf));
        for (int c = 0; c < 3; c++) {
          expect[c] += double(f.W[(k * K + q) * 3 + size_t(c)]) * e;
        }
      }
      const auto got = model::fallback_eval(f, dir(wv), dir(wl));
      for (int c = 0; c < 3; c++) {
        EXPECT_NEAR(got[size_t(c)], expect[c], 1e-4 * expect[c] + 1e-7) << "cell " << i << "," << j << " light " << a;
      }
    }
  }
  /* Halfway between cell centres (4, 12) and (5, 13) in both angles: the mean of the four cells. */
  const ny::Vec3 mid = ny::direction_from_angles(float(0.5 * (f.theta_center(4) + f.theta_center(5))),
                                                 float(0.5 * (f.phi_center(12) + f.phi_center(13))));
  const model::FallbackAt at = model::fallback_at(f, dir(mid));
  const size_t cells[4] = {4u * 18u + 12u, 4u * 18u + 13u, 5u * 18u + 12u, 5u * 18u + 13u};
  ASSERT_EQ(f.phi_bins, 18);
  for (size_t q = 0; q < K * 3; q++) {
    double mean = 0.0;
    for (size_t c : cells) {
      mean += 0.25 * f.W[c * K * 3 + q];
    }
    EXPECT_NEAR(at.W[q], mean, 1e-5 * (1.0 + mean)) << "weight " << q;
  }
}
