// SPDX-License-Identifier: Apache-2.0
//
// The aggregated yarn BSDF of kernel/yarn_bsdf.h on synthetic models (seeded random networks: every
// property below must hold for any networks, not just trained ones):
//   * the R lobe's energy is exactly rho_R F / 2 (quadrature);
//   * the conditional pdf integrates to 1 and the sampler draws from it (chi-square), and the T lobe is
//     chosen with probability P_T (binomial);
//   * a sample's weight is eval / pdf;
//   * w_i below the surface gives zero (never NaN), and 10^7 fuzzed calls are finite and non-negative;
//   * the flat array round-trips through the model file, and the loader rejects bad files by name.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <cstring>
#include <random>

#include <boost/math/distributions/chi_squared.hpp>

#include "neuralyarn/geometry/yarn.h"
#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/units.h"
#include "synthetic_model.h"
#include "yarn_fuzz.h"

using namespace neuralyarn;
using neuralyarn::testing::FuzzResult;
using neuralyarn::testing::fuzz_yarn_bsdf;
using neuralyarn::testing::synthetic_model;
using neuralyarn::testing::synthetic_yarn_model;
namespace fs = std::filesystem;

namespace {

/* Equal to the bit (0 and -0 apart, NaN equal to itself): the paths that must compute one value. */
bool bit_equal(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

ny::Vec3 from_polar(double theta, double phi)
{
  return ny::make_vec3(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)),
                       float(std::cos(theta)));
}

/* The R lobe's energy (mean channel) by the midpoint rule on an nt x np grid: each R node over its own fiber
 * frame's (theta~, phi~), dw = cos theta~ dtheta~ dphi~, averaged over the nodes. */
double r_lobe_energy(const ny::YarnLobes &l, int nt, int np)
{
  double e = 0.0;
  for (int q = 0; q < l.n_R; q++) {
    for (int i = 0; i < nt; i++) {
      const double th = -kPi / 2 + kPi * (i + 0.5) / nt;
      for (int j = 0; j < np; j++) {
        const double ph = -kPi + 2 * kPi * (j + 0.5) / np;
        ny::Rgb R, TT;
        ny::yarn_eval_R_parts(l, q, ny::yarn_outgoing(ny::direction_from_angles(float(th), float(ph))), &R, &TT);
        e += ny::average((ny::make_rgb(1.0f) - l.tau) * R + l.tau * TT) * std::cos(th) * (kPi / nt) *
             (2 * kPi / np) / l.n_R;
      }
    }
  }
  return e;
}

/* Fallback tables of 4 x 4 cells: enough to follow them through a file. */
model::FallbackTables small_fallback(const model::YarnModel &m)
{
  model::FallbackOptions fo;
  fo.theta_bins = 4;
  fo.phi_bins = 4;
  return model::compute_fallback(m, fo);
}

/* A kernel array without R node frames as layout 5 wrote it (no frames' offset) or layout 4 (no free path
 * either): the header's last fields dropped, the offsets moved back past them. */
std::vector<float> older_layout(std::vector<float> f, int layout)
{
  const int dropped = int(ny::kYarnFlatFormat) - layout;
  f.erase(f.begin() + ny::kYarnFlatHeader - dropped, f.begin() + ny::kYarnFlatHeader);
  for (int k : {ny::kYarnFlatOffset_T, ny::kYarnFlatOffset_R, ny::kYarnFlatOffset_M, ny::kYarnFlatOffset_Cal,
                ny::kYarnFlatOffset_Az}) {
    f[size_t(k)] -= float(dropped);
  }
  f[ny::kYarnFlatVersion] = float(layout);
  f[ny::kYarnFlatSize] = float(f.size());
  return f;
}

}  // namespace

TEST(YarnBsdf, ReflectionLobeEnergyIsHalfTheFiberR)
{
  /* The free path's nodes, and a yarn's nodes in the frames of its visible surface fibers (D51). */
  for (const char *preset : {"fleece", "polyester", "silk", "polyester yarn"}) {
    const bool yarn = std::string(preset) == "polyester yarn";
    const model::YarnModel m = yarn ? synthetic_yarn_model("polyester", 3) : synthetic_model(preset, 3);
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    for (double theta_i : {0.1, 0.7, 1.2, 1.5}) {
      const ny::YarnLobes l = ny::yarn_lobes(p, from_polar(theta_i, 0.8));
      /* The synthetic model's R azimuth table makes the lobe far from uniform in phi~; its energy must not
       * change (each row of the table integrates to 1). */
      EXPECT_GT(std::abs(std::log(ny::yarn_r_azimuth(l, -1.2f) / ny::yarn_r_azimuth(l, 0.9f))), 0.1);
      /* Near grazing the forward azimuth reaches the upper half: the TT part carries energy there too. */
      if (theta_i > 1.4) {
        EXPECT_GT(l.q_TT, 0.1f) << preset;
      }
      ASSERT_EQ(l.n_R, ny::kYarnRNodes) << preset;
      const double e = r_lobe_energy(l, 6000, 512);
      EXPECT_NEAR(e, 0.5 * ny::average(l.weight_R), 2e-3 * ny::average(l.weight_R)) << preset << " " << theta_i;
    }
  }
}

/* A renderer's glossy filter (yarn_lobes_blur, Cycles' bsdf_blur): the R nodes' lobes become at least that
 * wide, the R lobe keeps its energy (rho_R F / 2 by quadrature), the pdf still integrates to 1 and the sampler
 * draws with the blurred lobes' density; a width below the model's changes nothing. */
TEST(YarnBsdf, BlurWidensTheRLobeAndKeepsItsEnergy)
{
  const model::YarnModel m = synthetic_model("silk", 3);
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const float beta_min = ny::yarn_beta_of_ggx_alpha(0.3f);
  ASSERT_LT(p.fiber.beta_R, 0.5f * beta_min);
  for (double theta_i : {0.3, 1.0, 1.45}) {
    SCOPED_TRACE(theta_i);
    const ny::Vec3 wi = from_polar(theta_i, 0.6);
    const ny::YarnLobes l = ny::yarn_lobes(p, wi);
    ny::YarnLobes same = l;
    ny::yarn_lobes_blur(same, 0.5f * p.fiber.beta_R);
    EXPECT_EQ(std::memcmp(&same.node, &l.node, sizeof(l.node)), 0) << "a width below the model's changed a lobe";
    ny::YarnLobes b = l;
    ny::yarn_lobes_blur(b, beta_min);
    for (int q = 0; q < b.n_R; q++) {
      EXPECT_EQ(b.node[q].tn_R.sigma, beta_min);
      EXPECT_EQ(b.node[q].m_R.beta, beta_min);
      EXPECT_GE(b.node[q].tn_TT.sigma, beta_min);
      EXPECT_EQ(b.node[q].tn_R.mu, l.node[q].tn_R.mu);
    }
    /* Energy of the blurred R lobe (a wide lobe: a coarser grid than ReflectionLobeEnergyIsHalfTheFiberR's). */
    const double e = r_lobe_energy(b, 1200, 256);
    EXPECT_NEAR(e, 0.5 * ny::average(l.weight_R), 2e-3 * ny::average(l.weight_R));
    /* The blurred lobe is lower at its peak: the R node 0's value at its specular direction. */
    const ny::Vec3 peak_f = ny::direction_from_angles(l.node[0].tn_R.mu, 0.0f);
    ny::Rgb R0, TT0, R1, TT1;
    ny::yarn_eval_R_parts(l, 0, ny::yarn_outgoing(peak_f), &R0, &TT0);
    ny::yarn_eval_R_parts(b, 0, ny::yarn_outgoing(peak_f), &R1, &TT1);
    EXPECT_LT(ny::average(R1), 0.5f * ny::average(R0));
    /* The pdf over the sphere (yarn frame, midpoint rule) and the sampler's density at its own draws. */
    const int mt = 720, mp = 720;
    double total = 0.0;
    for (int i = 0; i < mt; i++) {
      const double th = kPi * (i + 0.5) / mt;
      for (int j = 0; j < mp; j++) {
        const double ph = 2 * kPi * (j + 0.5) / mp;
        total += ny::yarn_pdf_lobes(p, b, from_polar(th, ph)) * std::sin(th) * (kPi / mt) * (2 * kPi / mp);
      }
    }
    EXPECT_NEAR(total, 1.0, 5e-3);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int k = 0; k < 2000; k++) {
      ny::YarnSample s;
      if (!ny::yarn_sample_lobes(p, b, u(rng), u(rng), u(rng), false, &s)) {
        continue;
      }
      const float pdf = ny::yarn_pdf_lobes(p, b, s.wo);
      ASSERT_NEAR(s.pdf, pdf, 1e-4f * pdf + 1e-6f) << k;
    }
  }
}

TEST(YarnBsdf, PdfIntegratesToOneAndSamplerMatchesIt)
{
  /* The free path's R nodes, and a yarn's in the frames of its surface fibers (their own P_q turns). */
  for (const bool yarn : {false, true}) {
    SCOPED_TRACE(yarn ? "yarn with R node frames" : "ply");
    const model::YarnModel m = yarn ? synthetic_yarn_model("fleece", 5) : synthetic_model("fleece", 5);
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    /* Bins over the surface-fiber frame's (theta~, phi~); expected counts by 24 x 24 sub-quadrature: the R
     * nodes' horizons, where near-normal light puts the TT part's mass, cut these bins obliquely (8 x 8 read
     * chi2 1996 for 1727 degrees of freedom there). */
    const int nt = 36, np = 48, sub = 24;
    for (double theta_i : {0.2, 0.9, 1.45}) {
      const ny::Vec3 wi = from_polar(theta_i, 0.4);
      const ny::YarnLobes l = ny::yarn_lobes(p, wi);
      if (theta_i > 1.4) {
        EXPECT_GT(l.q_TT, 0.1f) << "the sampler's TT part is not exercised";
      }
      std::vector<double> expected(size_t(nt * np), 0.0);
      double total = 0.0;
      for (int i = 0; i < nt; i++) {
        for (int j = 0; j < np; j++) {
          double s = 0.0;
          for (int a = 0; a < sub; a++) {
            const double th = -kPi / 2 + kPi * (i + (a + 0.5) / sub) / nt;
            for (int b = 0; b < sub; b++) {
              const double ph = -kPi + 2 * kPi * (j + (b + 0.5) / sub) / np;
              const ny::Vec3 wo = ny::surface_fiber_to_yarn(p.twist, ny::direction_from_angles(float(th), float(ph)));
              s += ny::yarn_pdf_lobes(p, l, wo) * std::cos(th);
            }
          }
          expected[size_t(i * np + j)] = s * (kPi / nt / sub) * (2 * kPi / np / sub);
          total += expected[size_t(i * np + j)];
        }
      }
      EXPECT_NEAR(total, 1.0, 5e-3) << "theta_i " << theta_i;
      const int n = 1000000;
      std::vector<double> observed(expected.size(), 0.0);
      std::mt19937 rng(17);
      std::uniform_real_distribution<float> U(0.0f, 1.0f);
      for (int k = 0; k < n; k++) {
        ny::YarnSample s;
        ASSERT_TRUE(ny::yarn_sample(p, wi, U(rng), U(rng), U(rng), false, &s));
        ASSERT_FALSE(s.delta);
        const ny::Vec3 wf = ny::yarn_to_surface_fiber(p.twist, s.wo);
        const int i = std::min(nt - 1, int((ny::theta_of(wf) + kPi / 2) / kPi * nt));
        const int j = std::min(np - 1, int((ny::phi_of(wf) + kPi) / (2 * kPi) * np));
        observed[size_t(i * np + j)] += 1.0;
        if (k < 2000) {
          /* weight = eval / pdf, and the pdf is the one pdf() reports. */
          float pdf;
          const ny::Rgb f = ny::yarn_eval(p, wi, s.wo, &pdf);
          ASSERT_NEAR(s.pdf, pdf, 1e-4f * pdf + 1e-6f);
          ASSERT_NEAR(s.weight.g, f.g / pdf, 1e-3f * (f.g / pdf) + 1e-6f);
        }
      }
      /* Pool bins with fewer than 5 expected samples (Cochran's rule), then chi-square. */
      double chi2 = 0.0, pooled_e = 0.0, pooled_o = 0.0;
      int dof = -1;
      for (size_t b = 0; b < expected.size(); b++) {
        const double e = expected[b] / total * n;
        if (e < 5.0) {
          pooled_e += e;
          pooled_o += observed[b];
          continue;
        }
        chi2 += (observed[b] - e) * (observed[b] - e) / e;
        dof++;
      }
      if (pooled_e > 0.0) {
        chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
        dof++;
      }
      const double pval = boost::math::cdf(boost::math::complement(boost::math::chi_squared(dof), chi2));
      /* A fixed seed; 1e-3 would be a false alarm once in a thousand seeds, a wrong sampler (e.g. the pdf
       * missing its 1/cos theta) gives p ~ 0. */
      EXPECT_GT(pval, 1e-3) << "theta_i " << theta_i << " chi2 " << chi2 << " dof " << dof;
    }
  }
}

/* A yarn model's R nodes are the fibers the geometry finds on its visible ply surface: node q's fiber frame
 * has the tangent T_q along its x and the surface normal N_q along its z, exactly as
 * geometry::visible_surface_frames gives them, and the node's rotation is inverted by r_node_to_yarn. */
TEST(YarnBsdf, RNodeFramesAreTheVisibleSurfaceFibers)
{
  const model::YarnModel m = synthetic_yarn_model("cotton", 7);
  const std::vector<float> flat = m.kernel_flat();
  ASSERT_EQ(ny::yarn_flat_check(flat.data(), int(flat.size())), nullptr);
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const std::vector<geometry::SurfaceFrame> frames = geometry::visible_surface_frames(
      geometry::Yarn(geometry::yarn_params(m.preset, m.structure), 1), ny::kYarnRNodes, model::kRSurfaceSpread);
  const ny::YarnLobes l = ny::yarn_lobes(p, from_polar(0.6, 0.3));
  ASSERT_EQ(l.n_R, ny::kYarnRNodes);
  double turn_spread = 0.0;
  for (int q = 0; q < ny::kYarnRNodes; q++) {
    const ny::Vec3 T = ny::r_node_to_yarn(l.node[q], ny::make_vec3(1.0f, 0.0f, 0.0f));
    const ny::Vec3 N = ny::r_node_to_yarn(l.node[q], ny::make_vec3(0.0f, 0.0f, 1.0f));
    const geometry::SurfaceFrame &f = frames[size_t(q)];
    for (int c = 0; c < 3; c++) {
      EXPECT_NEAR((&T.x)[c], f.T[c], 2e-6) << q << " " << c;
      EXPECT_NEAR((&N.x)[c], f.N[c], 2e-6) << q << " " << c;
    }
    const ny::Vec3 w = ny::normalize(ny::make_vec3(0.3f, -0.5f, 0.8f));
    const ny::Vec3 back = ny::r_node_to_yarn(l.node[q], ny::yarn_to_r_node(l.node[q], w));
    EXPECT_NEAR(back.x, w.x, 1e-6f);
    EXPECT_NEAR(back.y, w.y, 1e-6f);
    EXPECT_NEAR(back.z, w.z, 1e-6f);
    turn_spread = std::max(turn_spread, std::abs(f.turn));
  }
  EXPECT_GT(turn_spread, 0.2); /* the frames are the ridges' flanks, not one surface fiber */
  /* A free path beside the frames is refused: each node's frame is one or the other. */
  std::vector<float> both = flat;
  both[ny::kYarnFlatFreePath] = 0.5f;
  EXPECT_NE(ny::yarn_flat_check(both.data(), int(both.size())), nullptr);
  std::vector<float> skewed = flat;
  skewed[size_t(ny::kYarnFlatHeader)] *= 1.1f;
  EXPECT_STREQ(ny::yarn_flat_check(skewed.data(), int(skewed.size())), "has an R node frame that is not a rotation");
  std::vector<float> cut(flat.begin(), flat.begin() + ny::kYarnFlatHeader + 10); /* ends inside the frames */
  cut[ny::kYarnFlatSize] = float(cut.size());
  EXPECT_STREQ(ny::yarn_flat_check(cut.data(), int(cut.size())), "has R node frames out of place");
}

TEST(YarnBsdf, CalibrationTableIsBilinearAndPeriodicInPhi)
{
  model::YarnModel m = synthetic_model("cotton", 5);
  const int nt = 3, np = 8;
  m.calibration.theta_bins = nt;
  m.calibration.phi_bins = np;
  m.calibration.values.clear();
  /* Entry k of bin (t, q): a value that identifies it. */
  auto value = [](int t, int q, int k) { return 0.01f * float(k) + 0.1f * float(t) + 0.3f * float(q) / 8.0f; };
  for (int t = 0; t < nt; t++) {
    for (int q = 0; q < np; q++) {
      for (int k = 0; k < ny::kYarnCalStride; k++) {
        m.calibration.values.push_back(value(t, q, k));
      }
    }
  }
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const double dt = kPi / 2 / nt, dp = 2 * kPi / np;
  auto at = [&](double theta, double phi, float out[7]) {
    ny::Rgb c_R, c_M;
    ny::yarn_calibration(p, from_polar(theta, phi), &out[0], &c_R, &c_M);
    out[1] = c_R.r, out[2] = c_R.g, out[3] = c_R.b, out[4] = c_M.r, out[5] = c_M.g, out[6] = c_M.b;
  };
  float c[7];
  for (int t = 0; t < nt; t++) {
    for (int q = 0; q < np; q++) {
      at((t + 0.5) * dt, -kPi + (q + 0.5) * dp, c);
      for (int k = 0; k < 7; k++) {
        EXPECT_NEAR(c[k], value(t, q, k), 2e-6) << "bin centre " << t << " " << q << " entry " << k;
      }
    }
  }
  /* Half way between two centres in theta; clamped beyond the first and last centre. */
  at(1.0 * dt, -kPi + 2.5 * dp, c);
  EXPECT_NEAR(c[1], 0.5f * (value(0, 2, 1) + value(1, 2, 1)), 2e-6);
  at(0.01, -kPi + 2.5 * dp, c);
  EXPECT_NEAR(c[1], value(0, 2, 1), 2e-6);
  at(kPi / 2 - 0.01, -kPi + 2.5 * dp, c);
  EXPECT_NEAR(c[1], value(2, 2, 1), 2e-6);
  /* phi = pi (= -pi) lies half way between the last and the first bin centre. */
  at(1.5 * dt, kPi - 1e-6, c);
  EXPECT_NEAR(c[6], 0.5f * (value(1, np - 1, 6) + value(1, 0, 6)), 1e-5);
  at(1.5 * dt, -kPi + 1e-6, c);
  EXPECT_NEAR(c[6], 0.5f * (value(1, np - 1, 6) + value(1, 0, 6)), 1e-5);

  /* The table acts on the three lobes exactly as documented: P_T + dP_T, c_R rho_R F, c_M e MLP_M. */
  model::YarnModel bare = m;
  bare.calibration = model::EnergyCalibration{};
  const std::vector<float> bare_flat = bare.kernel_flat();
  const ny::YarnBsdfParams q = ny::yarn_params_from_flat(bare_flat.data());
  const ny::Vec3 wi = from_polar(0.7, 0.4), wo = from_polar(2.0, -0.3);
  at(0.7, 0.4, c);
  const ny::YarnLobes lc = ny::yarn_lobes(p, wi), lb = ny::yarn_lobes(q, wi);
  EXPECT_NEAR(lc.P_T, std::clamp(lb.P_T + c[0], 0.0f, 1.0f), 1e-6);
  EXPECT_NEAR(lc.weight_R.g, lb.weight_R.g * c[2], 1e-6);
  const float scale = ny::yarn_escape(lc.P_T) / ny::yarn_escape(lb.P_T);
  EXPECT_NEAR(ny::yarn_eval_M(p, lc, wo).b, ny::yarn_eval_M(q, lb, wo).b * c[6] * scale, 1e-6);
}

TEST(YarnBsdf, DeltaLobeIsChosenWithProbabilityPT)
{
  const model::YarnModel m = synthetic_model("silk", 9);
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (double theta_i : {0.3, 1.0, 1.5}) {
    const ny::Vec3 wi = from_polar(theta_i, -1.1);
    const double P_T = ny::yarn_lobes(p, wi).P_T;
    ASSERT_GT(P_T, 0.02);
    const int n = 200000;
    int deltas = 0;
    for (int k = 0; k < n; k++) {
      ny::YarnSample s;
      ASSERT_TRUE(ny::yarn_sample(p, wi, U(rng), U(rng), U(rng), true, &s));
      if (s.delta) {
        deltas++;
        ASSERT_EQ(s.wo.x, -wi.x);
        ASSERT_EQ(s.wo.z, -wi.z);
        ASSERT_EQ(s.weight.r, 1.0f); /* P_T / p_T */
        ASSERT_NEAR(s.pdf, P_T, 1e-6);
      }
    }
    const double sigma = std::sqrt(P_T * (1 - P_T) / n);
    EXPECT_NEAR(double(deltas) / n, P_T, 5 * sigma) << "theta_i " << theta_i;
  }
}

TEST(YarnBsdf, BelowTheSurfaceIsZeroNotNaN)
{
  const model::YarnModel m = synthetic_model("cotton", 2);
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  for (const ny::Vec3 wi : {ny::make_vec3(0, 0, -1), ny::make_vec3(1, 0, 0), ny::make_vec3(0.6f, 0, -0.8f)}) {
    float pdf = -1;
    const ny::Rgb f = ny::yarn_eval(p, wi, ny::make_vec3(0, 0, 1), &pdf);
    EXPECT_EQ(f.r, 0.0f);
    EXPECT_EQ(pdf, 0.0f);
    ny::YarnSample s;
    EXPECT_FALSE(ny::yarn_sample(p, wi, 0.5f, 0.5f, 0.5f, true, &s));
    EXPECT_EQ(s.weight.g, 0.0f);
  }
}

TEST(YarnBsdf, TenMillionFuzzedCallsAreFiniteAndNonNegative)
{
  /* 2.5 M iterations x 4 calls on 77 random models (yarn_fuzz.h; the on-demand program fuzz_yarn_bsdf runs
   * 10^8 and more). */
  const FuzzResult r = fuzz_yarn_bsdf(2500000, 1);
  EXPECT_EQ(r.calls, 10000000);
  EXPECT_EQ(r.bad, 0) << r.first_bad;
}

TEST(ModelFile, RoundTripsAndRejectsBadFiles)
{
  const fs::path dir = fs::temp_directory_path() / ("ny_model_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const model::YarnModel m = synthetic_model("gabardine", 11);
  const std::string good = (dir / "good.json").string();
  model::save_model(m, good);
  const model::YarnModel back = model::load_model(good);
  EXPECT_EQ(back.kernel_flat(), m.kernel_flat()) << "the model file does not round-trip exactly";
  {
    /* A version 1 file (before the calibration table) still loads, without a table. */
    nlohmann::json v1 = model::model_to_json(m);
    v1["version"] = 1;
    v1.erase("calibration");
    v1.erase("kernel_flat");
    const std::string old = (dir / "v1.json").string();
    std::ofstream(old) << v1.dump();
    const model::YarnModel o = model::load_model(old);
    EXPECT_TRUE(o.calibration.empty());
    EXPECT_EQ(o.kernel_flat()[ny::kYarnFlatCalThetaBins], 0.0f);
  }
  {
    /* A version 3 file (layout 3: no TT fields in the header, azimuth rows without the TT share) loads
     * with its tables and no TT share, so it renders as it did. */
    model::YarnModel no_tt = m;
    no_tt.r_free_path = 0.0; /* layout 3 has none */
    for (size_t r = 0; r < no_tt.r_shape.values.size(); r += size_t(no_tt.r_shape.stride())) {
      std::fill_n(no_tt.r_shape.values.begin() + long(r) + no_tt.r_shape.azimuth_bins, 3, 0.0f);
    }
    nlohmann::json v3 = model::model_to_json(no_tt);
    std::vector<float> f = v3["kernel_flat"].get<std::vector<float>>(), f3(f.begin(), f.begin() + 24);
    for (int k : {ny::kYarnFlatOffset_T, ny::kYarnFlatOffset_R, ny::kYarnFlatOffset_M, ny::kYarnFlatOffset_Cal,
                  ny::kYarnFlatOffset_Az}) {
      f3[size_t(k)] -= float(ny::kYarnFlatHeader - 24); /* the header was shorter */
    }
    const size_t az = size_t(f[ny::kYarnFlatOffset_Az]);
    f3.insert(f3.end(), f.begin() + ny::kYarnFlatHeader, f.begin() + long(az));
    for (size_t r = az; r < f.size(); r += size_t(no_tt.r_shape.stride())) {
      f3.insert(f3.end(), f.begin() + long(r), f.begin() + long(r) + no_tt.r_shape.azimuth_bins);
    }
    f3[0] = 3.0f;
    f3[1] = float(f3.size());
    v3["kernel_flat"] = f3;
    v3["version"] = 3;
    v3["r_azimuth"] = v3["r_shape"];
    v3.erase("r_shape");
    v3.erase("r_free_path");
    v3.erase("fallback");
    const std::string old = (dir / "v3.json").string();
    std::ofstream(old) << v3.dump();
    const model::YarnModel o = model::load_model(old);
    EXPECT_EQ(o.kernel_flat(), no_tt.kernel_flat()) << "a layout 3 file must load as the same model without TT";
  }
  {
    /* A layout 4 file (no R free path and no R node frames: the header two floats shorter) loads as the same
     * model with the free path 0, its fallback tables (computed for the layout 4 array, named by its hash) with
     * it. */
    model::YarnModel surface = m;
    surface.r_free_path = 0.0;
    surface.fallback = small_fallback(surface);
    nlohmann::json v4 = model::model_to_json(surface);
    std::vector<float> f = v4["kernel_flat"].get<std::vector<float>>();
    ASSERT_EQ(f[ny::kYarnFlatOffset_RFrames], 0.0f);
    f = older_layout(f, 4);
    v4["kernel_flat"] = f;
    v4.erase("r_free_path");
    v4["fallback"]["kernel_flat_fnv1a64"] = model::fnv1a64_hex(f);
    const std::string old = (dir / "v4.json").string();
    std::ofstream(old) << v4.dump();
    const model::YarnModel o = model::load_model(old);
    EXPECT_EQ(o.kernel_flat(), surface.kernel_flat()) << "a layout 4 file must load as the same model";
    ASSERT_TRUE(o.fallback.has_value());
    EXPECT_EQ(o.fallback->W, surface.fallback->W);
    EXPECT_EQ(o.fallback->kernel_flat_hash, model::fnv1a64_hex(surface.kernel_flat()));
    /* The free path needs the layout that holds it. */
    v4["r_free_path"] = 0.1;
    std::ofstream(old) << v4.dump();
    EXPECT_THROW(model::load_model(old), model::ModelError);
  }
  {
    /* A layout 5 file (no R node frames: the header one float shorter) loads as the same model, free path
     * and fallback tables included. */
    model::YarnModel five = m;
    five.fallback = small_fallback(five);
    nlohmann::json v5 = model::model_to_json(five);
    std::vector<float> f = v5["kernel_flat"].get<std::vector<float>>();
    f = older_layout(f, 5);
    v5["kernel_flat"] = f;
    v5["fallback"]["kernel_flat_fnv1a64"] = model::fnv1a64_hex(f);
    const std::string old = (dir / "v5.json").string();
    std::ofstream(old) << v5.dump();
    const model::YarnModel o = model::load_model(old);
    EXPECT_EQ(o.kernel_flat(), five.kernel_flat()) << "a layout 5 file must load as the same model";
    EXPECT_EQ(o.r_free_path, five.r_free_path);
    ASSERT_TRUE(o.fallback.has_value());
    EXPECT_EQ(o.fallback->kernel_flat_hash, model::fnv1a64_hex(five.kernel_flat()));
    /* Node frames need the layout that holds them. */
    v5["r_surface_frames"] = {{"spread", 0.6}, {"frames", nlohmann::json::array()}};
    std::ofstream(old) << v5.dump();
    EXPECT_THROW(model::load_model(old), model::ModelError);
  }

  auto expect_error = [&](const std::string &name, const std::string &text, const std::string &needle) {
    const std::string path = (dir / name).string();
    std::ofstream(path) << text;
    try {
      model::load_model(path);
      ADD_FAILURE() << name << " was accepted";
    }
    catch (const model::ModelError &e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << name << ": " << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << "the message must name the file";
    }
  };
  const nlohmann::json j = model::model_to_json(m);
  expect_error("truncated.json", j.dump().substr(0, 500), "not valid JSON");
  expect_error("other.json", R"({"format": "something-else"})", "not a neuralyarn model");
  nlohmann::json v = j;
  v["version"] = model::kModelFormatVersionYarn + 1;
  expect_error("version.json", v.dump(),
               "version " + std::to_string(model::kModelFormatVersionYarn + 1) + " is not supported");
  const size_t table = size_t(j["kernel_flat"][ny::kYarnFlatOffset_Cal].get<float>());
  v = j;
  v["kernel_flat"].erase(v["kernel_flat"].size() - 1);
  expect_error("flat_short.json", v.dump(), "size field disagrees");
  v = j;
  v["kernel_flat"][table + 3] = nullptr;
  expect_error("flat_nan.json", v.dump(), "non-number");
  v = j;
  v["kernel_flat"][table + ny::kYarnCalStride] = 1.5; /* a dP_T outside [-1, 1] */
  expect_error("cal_dpt.json", v.dump(), "dP_T in [-1, 1]");
  const size_t az = size_t(j["kernel_flat"][ny::kYarnFlatOffset_Az].get<float>());
  ASSERT_TRUE(j.contains("r_shape"));
  v = j;
  v["kernel_flat"][az + 2] = v["kernel_flat"][az + 2].get<float>() * 1.2f; /* the row no longer integrates to 1 */
  expect_error("az_norm.json", v.dump(), "integrates to");
  v = j;
  v["kernel_flat"][az + 1] = -0.1;
  expect_error("az_negative.json", v.dump(), "negative R azimuth density");
  v = j;
  v["kernel_flat"][az + size_t(m.r_shape.azimuth_bins)] = 1.2; /* a TT share above 1 */
  expect_error("tau.json", v.dump(), "TT share above 1");
  v = j;
  v["r_shape"]["azimuth_bins"] = 5;
  expect_error("az_bins.json", v.dump(), "disagree with the kernel array");
  v = j;
  v["kernel_flat"][ny::kYarnFlatKappa_R] = 0.25; /* consistent by itself, but not with "sampling" */
  expect_error("flat_mismatch.json", v.dump(), "disagrees with the networks");
  v = j;
  v["kernel_flat"][ny::kYarnFlatOffset_M] = 3.0;
  expect_error("flat_offsets.json", v.dump(), "offsets out of order");
  v = j;
  v["networks"]["M"]["kernel_array"][40] = nullptr; /* what a NaN becomes in JSON */
  expect_error("nan.json", v.dump(), "non-number");
  v = j;
  v["networks"]["M"]["kernel_array"].erase(v["networks"]["M"]["kernel_array"].size() - 1);
  expect_error("short.json", v.dump(), "does not match the shape");
  v = j;
  v["networks"]["T"] = v["networks"]["R"]; /* exp head where a sigmoid is required */
  expect_error("arch.json", v.dump(), "network T must map 3 inputs to 1 outputs with a sigmoid head");
  v = j;
  v["sampling"]["kappa_M"] = 1.5;
  expect_error("kappa.json", v.dump(), "kappa_M");
  v = j;
  v["networks"].erase("R");
  expect_error("missing.json", v.dump(), "missing network 'R'");
  v = j;
  v["networks"]["M"]["kernel_array"][10] = 1e39; /* overflows float */
  expect_error("inf.json", v.dump(), "non-finite");
  try {
    model::load_model((dir / "does_not_exist.json").string());
    ADD_FAILURE() << "a missing file was accepted";
  }
  catch (const model::ModelError &e) {
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

namespace {

/* The model file's network evaluated in double from its record (layout of kernel/mlp.h), by a loop of its
 * own: weights input-major, PReLU on hidden layers, the head on the last. */
std::vector<double> network_in_double(const model::NetworkRecord &net, const std::vector<double> &x)
{
  const std::vector<float> &f = net.flat;
  const int L = int(f[0]);
  size_t k = size_t(L) + 3;
  std::vector<double> in = x;
  for (int l = 0; l < L; l++) {
    const int n_in = int(f[size_t(1 + l)]), n_out = int(f[size_t(2 + l)]);
    std::vector<double> z(size_t(n_out), 0.0);
    for (int o = 0; o < n_out; o++) {
      for (int i = 0; i < n_in; i++) {
        z[size_t(o)] += double(f[k + size_t(i) * n_out + size_t(o)]) * in[size_t(i)];
      }
    }
    k += size_t(n_in) * n_out;
    for (int o = 0; o < n_out; o++) {
      z[size_t(o)] += f[k + size_t(o)];
    }
    k += size_t(n_out);
    if (l < L - 1) {
      for (int o = 0; o < n_out; o++) {
        z[size_t(o)] = z[size_t(o)] >= 0.0 ? z[size_t(o)] : double(f[k + size_t(o)]) * z[size_t(o)];
      }
      k += size_t(n_out);
    }
    else if (int(f[size_t(L) + 2]) == ny::kMlpHeadExp) {
      for (double &v : z) {
        v = std::exp(v);
      }
    }
    in = z;
  }
  EXPECT_EQ(k, f.size());
  return in;
}

}  // namespace

/* A yarn model's R node frames survive the file, which must agree with its kernel array; a ply model carries
 * none. */
TEST(ModelFile, RNodeFramesRoundTripAndAreChecked)
{
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "ny_r_frames";
  std::filesystem::create_directories(dir);
  const model::YarnModel m = synthetic_yarn_model("silk", 4);
  const std::string path = (dir / "yarn.json").string();
  model::save_model(m, path);
  const model::YarnModel o = model::load_model(path);
  EXPECT_EQ(o.kernel_flat(), m.kernel_flat());
  EXPECT_EQ(o.r_surface_spread, m.r_surface_spread);
  const nlohmann::json j = model::model_to_json(m);
  auto refused = [&](nlohmann::json bad, const std::string &needle) {
    std::ofstream(path) << bad.dump();
    try {
      model::load_model(path);
      ADD_FAILURE() << needle << ": accepted";
    }
    catch (const model::ModelError &e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  nlohmann::json other = j;
  other["r_surface_frames"]["frames"][1][4] = other["r_surface_frames"]["frames"][1][4].get<double>() + 0.01;
  refused(other, "disagrees");
  nlohmann::json spread = j;
  spread["r_surface_frames"]["spread"] = 0.0;
  refused(spread, "spread");
  nlohmann::json three = j;
  three["r_surface_frames"]["frames"].erase(0);
  refused(three, "frames");
  nlohmann::json ply = model::model_to_json(synthetic_model("silk", 4));
  ply["r_surface_frames"] = j["r_surface_frames"];
  refused(ply, "yarn-level");
}

TEST(YarnBsdf, MChannelKIsTheNetworksOutputKTimesItsScale)
{
  /* Kills the mutant that swaps the M network's red and blue outputs (the calibration table would hide it
   * in every energy test; docs/benchmarks.md, "Test power"). Gabardine: C_TT (0.999, 0.33, 0.354), so the
   * network's channels differ by a factor ~3. */
  const model::YarnModel m = model::load_model(model::builtin_model_path("gabardine"));
  const std::vector<float> flat = m.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const double dirs[][6] = {{0.3, 0.2, 0.93, -0.2, 0.5, 0.84}, {0.1, -0.6, 0.79, 0.4, 0.1, -0.91},
                            {-0.7, 0.1, 0.7, 0.6, -0.3, 0.74}, {0.05, 0.05, 0.997, 0.0, 0.0, -1.0}};
  int distinct = 0;
  for (const auto &d : dirs) {
    const ny::Vec3 wi = ny::normalize(ny::make_vec3(float(d[0]), float(d[1]), float(d[2])));
    const ny::Vec3 wo = ny::normalize(ny::make_vec3(float(d[3]), float(d[4]), float(d[5])));
    const ny::YarnLobes l = ny::yarn_lobes(p, wi);
    float dP_T;
    ny::Rgb c_R, c_M;
    ny::yarn_calibration(p, wi, &dP_T, &c_R, &c_M);
    const double escape = std::max(1.0 - l.P_T, double(ny::kYarnMinEscape));
    const std::vector<double> net = network_in_double(m.M, {wi.x, wi.y, wi.z, wo.x, wo.y, wo.z});
    const ny::Rgb got = ny::yarn_eval_M(p, l, wo);
    const double want[3] = {net[0] * c_M.r * escape, net[1] * c_M.g * escape, net[2] * c_M.b * escape};
    const float g[3] = {got.r, got.g, got.b};
    for (int c = 0; c < 3; c++) {
      EXPECT_NEAR(g[c], want[c], 1e-4 * want[c] + 1e-9) << "channel " << c;
    }
    distinct += std::abs(want[0] - want[2]) > 0.2 * std::max(want[0], want[2]);
  }
  EXPECT_GE(distinct, 2); /* the test can see a swap */
}

/* An RGB R-energy network (3 -> 3, D65): the R lobe's weight in channel k is the network's output k at the energy
 * direction times the channel mean of the Fresnel factor, times the calibration's c_R; a one-output network keeps
 * F's colour (the fiber's C_R). The flat array's check and the model file take 3 -> 1 and 3 -> 3 and refuse 3 -> 2. */
TEST(YarnBsdf, RgbReflectionNetworkCarriesTheColour)
{
  const double dirs[][3] = {{0.3, 0.2, 0.93}, {0.1, -0.6, 0.79}, {-0.7, 0.1, 0.7}, {0.9, 0.3, 0.1}};
  for (const int outputs : {1, 3}) {
    /* Silk: C_R (0.745, 0.008, 0.07), so F's green is ~1/90 of its red until grazing. */
    const model::YarnModel m = synthetic_model("silk", 13, -3.0, -1.0, 3, outputs);
    const std::vector<float> flat = m.kernel_flat();
    ASSERT_EQ(ny::yarn_flat_check(flat.data(), int(flat.size())), nullptr);
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    EXPECT_EQ(p.r_rgb, outputs == 3);
    int off_fresnel = 0;
    for (const auto &d : dirs) {
      const ny::Vec3 wi = ny::normalize(ny::make_vec3(float(d[0]), float(d[1]), float(d[2])));
      const ny::YarnLobes l = ny::yarn_lobes(p, wi);
      float dP_T;
      ny::Rgb c_R, c_M;
      ny::yarn_calibration(p, l.we, &dP_T, &c_R, &c_M);
      const ny::Rgb F = ny::schlick_fresnel(p.fiber.C_R, ny::cos_theta(ny::yarn_to_surface_fiber(p.twist, l.we)));
      const std::vector<double> net = network_in_double(m.R, {l.we.x, l.we.y, l.we.z});
      const double f[3] = {F.r, F.g, F.b}, c[3] = {c_R.r, c_R.g, c_R.b};
      const double mean_F = (f[0] + f[1] + f[2]) / 3.0;
      const float got[3] = {l.weight_R.r, l.weight_R.g, l.weight_R.b};
      for (int k = 0; k < 3; k++) {
        const double want = (outputs == 3 ? net[size_t(k)] * mean_F : net[0] * f[k]) * c[k];
        EXPECT_NEAR(got[k], want, 1e-4 * want + 1e-9) << outputs << " outputs, channel " << k;
      }
      /* The weight's green against red is F's (within the calibration's 0.8-1.2) for one output, the network's for
       * three: the test sees which colour the kernel took. */
      const double ratio = (got[1] / c[1]) / (got[0] / c[0]) / (f[1] / f[0]);
      off_fresnel += std::abs(ratio - 1.0) > 0.5;
    }
    EXPECT_EQ(off_fresnel, outputs == 3 ? 4 : 0) << outputs << " outputs";
  }
  const model::YarnModel two = synthetic_model("silk", 13, -3.0, -1.0, 3, 2);
  const std::vector<float> flat2 = two.kernel_flat();
  const char *why = ny::yarn_flat_check(flat2.data(), int(flat2.size()));
  ASSERT_NE(why, nullptr);
  EXPECT_NE(std::string(why).find("R network"), std::string::npos) << why;
  const fs::path dir = fs::temp_directory_path() / ("ny_rgb_r_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string rgb = (dir / "rgb.json").string(), bad = (dir / "two.json").string();
  const model::YarnModel m3 = synthetic_model("silk", 13, -3.0, -1.0, 3, 3);
  model::save_model(m3, rgb);
  EXPECT_EQ(model::load_model(rgb).kernel_flat(), m3.kernel_flat());
  nlohmann::json j = model::model_to_json(m3);
  j["networks"]["R"] = model::model_to_json(two)["networks"]["R"];
  std::ofstream(bad) << j.dump();
  try {
    model::load_model(bad);
    ADD_FAILURE() << "a 3 -> 2 R network was accepted";
  }
  catch (const model::ModelError &e) {
    EXPECT_NE(std::string(e.what()).find("network R"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

/* A two-sided M network (6 -> 6, D45): exits above the surface read outputs 0-2, exits below it 3-5, each
 * times the lobe's scale; and the flat array's check takes it while a 6 -> 4 network is refused. */
TEST(YarnBsdf, TwoSidedMReadsTheOutputsOfItsExitsSide)
{
  const model::YarnModel m = synthetic_model("fleece", 5, -3.0, -1.0, 6);
  const std::vector<float> flat = m.kernel_flat();
  ASSERT_EQ(ny::yarn_flat_check(flat.data(), int(flat.size())), nullptr);
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  ASSERT_TRUE(p.m_two_sided);
  const ny::Vec3 wi = ny::normalize(ny::make_vec3(0.3f, 0.2f, 0.93f));
  const ny::YarnLobes l = ny::yarn_lobes(p, wi);
  float dP_T;
  ny::Rgb c_R, c_M;
  ny::yarn_calibration(p, wi, &dP_T, &c_R, &c_M);
  const double escape = std::max(1.0 - l.P_T, double(ny::kYarnMinEscape));
  int sides_differ = 0;
  for (const double z : {0.8, 0.05, -0.05, -0.8}) {
    const ny::Vec3 wo = ny::normalize(ny::make_vec3(0.4f, -0.3f, float(z)));
    const std::vector<double> net = network_in_double(m.M, {wi.x, wi.y, wi.z, wo.x, wo.y, wo.z});
    const int k = z >= 0.0 ? 0 : 3;
    const ny::Rgb got = ny::yarn_eval_M(p, l, wo);
    const double want[3] = {net[k] * c_M.r * escape, net[k + 1] * c_M.g * escape, net[k + 2] * c_M.b * escape};
    const float g[3] = {got.r, got.g, got.b};
    for (int c = 0; c < 3; c++) {
      EXPECT_NEAR(g[c], want[c], 1e-4 * want[c] + 1e-9) << "z " << z << " channel " << c;
    }
    sides_differ += std::abs(net[0] - net[3]) > 0.1 * std::max(net[0], net[3]);
  }
  EXPECT_GE(sides_differ, 2); /* the test can tell the sides apart */
  const std::vector<float> flat4 = synthetic_model("fleece", 5, -3.0, -1.0, 4).kernel_flat();
  EXPECT_NE(ny::yarn_flat_check(flat4.data(), int(flat4.size())), nullptr);
}

/* A shadow ray computes P_T alone (yarn_transmission_probability, the Cycles closure's shadow path); it must
 * be the P_T of the full lobes, bit for bit, everywhere: on the calibration table's centres and between them,
 * past its last theta_i centre (the energy direction), at grazing incidence and below the surface. */
TEST(YarnBsdf, ShadowTransmissionIsTheLobesPT)
{
  std::vector<model::YarnModel> models = {synthetic_model("silk", 4), synthetic_yarn_model("cotton", 6)};
  for (const char *preset : {"fleece", "cotton", "gabardine"}) {
    models.push_back(model::load_model(model::builtin_model_path(preset)));
  }
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (const model::YarnModel &m : models) {
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    int positive = 0;
    for (int k = 0; k < 20000; k++) {
      /* theta_i over [0, pi/2 + 0.1]: the last 0.1 rad below the surface; every 8th exactly grazing. */
      const double theta = k % 8 == 0 ? kPi / 2 - 1e-4 * U(rng) : (kPi / 2 + 0.1) * U(rng);
      const ny::Vec3 wi = from_polar(theta, 2 * kPi * U(rng) - kPi);
      const float P_T = ny::yarn_transmission_probability(p, wi);
      ASSERT_EQ(P_T, ny::yarn_lobes(p, wi).P_T) << "theta_i " << theta;
      positive += P_T > 0.0f;
    }
    EXPECT_GT(positive, 4000); /* the comparison is not 0 == 0 (P_T is 0 near the normal of dense plies) */
  }
}

/* The renderer's eval asks for both (yarn_eval_pdf_lobes, angles of w_o computed once): it must be
 * yarn_eval_lobes() and yarn_pdf_lobes() bit for bit, over the whole sphere of w_o, with the TT part active. */
TEST(YarnBsdf, EvalAndPdfTogetherAreEvalAndPdfApart)
{
  std::vector<model::YarnModel> models = {synthetic_model("fleece", 6), synthetic_yarn_model("cotton", 6)};
  for (const char *preset : {"cotton", "gabardine"}) {
    models.push_back(model::load_model(model::builtin_model_path(preset)));
  }
  std::mt19937 rng(29);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (const model::YarnModel &m : models) {
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    int tt = 0;
    for (int k = 0; k < 20000; k++) {
      const ny::Vec3 wi = from_polar((kPi / 2 + 0.05) * U(rng), 2 * kPi * U(rng) - kPi);
      const ny::Vec3 wo = from_polar(kPi * U(rng), 2 * kPi * U(rng) - kPi);
      const ny::YarnLobes l = ny::yarn_lobes(p, wi);
      tt += l.q_TT > 0.0f;
      float pdf;
      const ny::Rgb f = ny::yarn_eval_pdf_lobes(p, l, wo, &pdf);
      const ny::Rgb f_apart = ny::yarn_eval_lobes(p, l, wo);
      ASSERT_TRUE(bit_equal(pdf, ny::yarn_pdf_lobes(p, l, wo)));
      ASSERT_TRUE(bit_equal(f.r, f_apart.r) && bit_equal(f.g, f_apart.g) && bit_equal(f.b, f_apart.b));
    }
    EXPECT_GT(tt, 100);
  }
}

/* The closure runs the R nodes as vector lanes (yarn_R_lanes); the host's quadratures (the R shape fit, the
 * 4D measure, the fallback tables) take each node's factors one at a time (yarn_eval_R_parts,
 * yarn_pdf_R_parts). Both must be the same function to the bit, so that what a bake fits is what Cycles
 * renders: free-path nodes, a yarn's surface frames, a single node, with and without the azimuth table and
 * the TT part, w_o over the whole sphere. */
/* yarn_lobes sets up the kYarnRNodes R nodes as lanes (yarn_r_nodes_setup_lanes, D64) with its own sin, cos, erfc and
 * the normaliser's table; each node must be what the scalar functions give. Given the node's own rotation angle and
 * mean: P_q, M_q, the surface frames' a_q and the mean -theta~_i bit for bit (yarn_to_r_node and theta_of), the free
 * path's cos a_q and sin a_q within 2 ulps or 6e-8 of cosf and sinf (sincos_lanes' accuracy), each truncated normal's
 * bounds bit for bit and its masses within 8 ulps of make_truncated_normal's, each lobe's 1 / (beta G) within 8 ulps
 * of make_longitudinal_lobe's (the table path; a width past the table, TT at 40 degrees here, takes the scalar
 * normaliser and is equal to the bit). Models: the free path's nodes (synthetic fleece, shipped fleece and cotton,
 * both with the TT part), a yarn's surface frames (synthetic cotton), and fleece with its TT part 40 degrees wide.
 * Selecting the wrong tail in truncated_normal_lanes or dropping the twist's fading fails it. */
TEST(YarnBsdf, RNodeSetupLanesAreTheScalarFunctions)
{
  struct Case {
    model::YarnModel m;
    float beta_TT; /* 0: the model's */
  };
  std::vector<Case> cases = {{synthetic_model("fleece", 6), 0.0f}, {synthetic_yarn_model("cotton", 6), 0.0f},
                             {model::load_model(model::builtin_model_path("fleece")), 0.0f},
                             {model::load_model(model::builtin_model_path("cotton")), 0.0f},
                             {model::load_model(model::builtin_model_path("fleece")), float(40.0 * kPi / 180.0)}};
  auto near_ulps = [](float got, float want, double ulps) {
    return std::fabs(double(got) - double(want)) <=
           ulps * std::ldexp(1.0, std::ilogb(std::max(std::fabs(double(want)), 1e-30)) - 23);
  };
  auto same_tn = [&](const ny::TruncatedNormal &got, const ny::TruncatedNormal &want) {
    return bit_equal(got.mu, want.mu) && bit_equal(got.sigma, want.sigma) && bit_equal(got.za, want.za) &&
           bit_equal(got.zb, want.zb) && near_ulps(got.lower, want.lower, 8) && near_ulps(got.upper, want.upper, 8) &&
           near_ulps(got.mass, want.mass, 8);
  };
  std::mt19937 rng(41);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (size_t i = 0; i < cases.size(); i++) {
    const std::vector<float> flat = cases[i].m.kernel_flat();
    ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    if (cases[i].beta_TT > 0.0f) {
      p.fiber.beta_TT = cases[i].beta_TT;
    }
    int with_tt = 0;
    for (int k = 0; k < 5000; k++) {
      const ny::Vec3 wi = from_polar((kPi / 2 + 0.05) * U(rng), 2 * kPi * U(rng) - kPi);
      const ny::YarnLobes l = ny::yarn_lobes(p, wi);
      ASSERT_EQ(l.n_R, ny::kYarnRNodes) << "case " << i;
      const bool tt = ny::average(l.tau) > 0.0f || l.node[0].tn_TT.sigma != l.node[0].tn_R.sigma;
      with_tt += tt;
      for (int q = 0; q < l.n_R; q++) {
        const ny::YarnRNode &n = l.node[q];
        if (p.r_frames) {
          const float *r = p.r_frames + q * ny::kYarnRFrameStride;
          ASSERT_TRUE(bit_equal(n.pre.c, r[0]) && bit_equal(n.pre.s, r[1]) && bit_equal(n.ca, r[2]) &&
                      bit_equal(n.sa, r[3]) && bit_equal(n.twist.c, r[4]) && bit_equal(n.twist.s, r[5]))
              << "case " << i << " node " << q;
        }
        else {
          const float s = p.free_path * ny::yarn_r_node_path(q), a = -wi.y * s;
          ASSERT_TRUE(n.pre.c == 1.0f && n.pre.s == 0.0f) << "case " << i;
          ASSERT_TRUE(std::fabs(n.ca - std::cos(a)) <= std::max(2.0f * std::fabs(std::nextafter(std::cos(a), 2.0f) - std::cos(a)), 6e-8f) &&
                      std::fabs(n.sa - std::sin(a)) <= std::max(2.0f * std::fabs(std::nextafter(std::fabs(std::sin(a)), 2.0f) - std::fabs(std::sin(a))), 6e-8f))
              << "case " << i << " node " << q << " a " << a << ": " << n.ca << " " << n.sa;
          const ny::TwistRotation t = ny::make_twist_rotation(p.alpha * ny::maxf(1.0f - s * wi.z, 0.0f));
          ASSERT_TRUE(bit_equal(n.twist.c, t.c) && bit_equal(n.twist.s, t.s)) << "case " << i << " node " << q;
        }
        const ny::Vec3 wi_q = ny::yarn_to_r_node(n, wi);
        const float mu = -ny::theta_of(wi_q);
        ASSERT_TRUE(bit_equal(n.tn_R.mu, mu) && bit_equal(n.m_R.mu, mu)) << "case " << i << " node " << q;
        ASSERT_TRUE(same_tn(n.tn_R, ny::make_truncated_normal(mu, p.fiber.beta_R, -ny::kHalfPi, ny::kHalfPi)))
            << "case " << i << " node " << q << " k " << k;
        ASSERT_TRUE(near_ulps(n.m_R.inv_beta_G, ny::make_longitudinal_lobe(mu, p.fiber.beta_R).inv_beta_G, 8))
            << "case " << i << " node " << q << ": " << n.m_R.inv_beta_G;
        if (tt) {
          ASSERT_TRUE(same_tn(n.tn_TT, ny::make_truncated_normal(mu, p.fiber.beta_TT, -ny::kHalfPi, ny::kHalfPi)))
              << "case " << i << " node " << q;
          const float G_TT = ny::make_longitudinal_lobe(mu, p.fiber.beta_TT, true).inv_beta_G;
          if (p.fiber.beta_TT > ny::kCos2TableBetaMax) {
            ASSERT_TRUE(bit_equal(n.m_TT.inv_beta_G, G_TT)) << "case " << i << " node " << q;
          }
          else {
            ASSERT_TRUE(near_ulps(n.m_TT.inv_beta_G, G_TT, 8)) << "case " << i << " node " << q;
          }
          const float phi = ny::wrap_angle(ny::phi_of(wi_q) + ny::kPi);
          ASSERT_TRUE(same_tn(n.tn_TT_phi, ny::make_truncated_normal(phi, p.fiber.gamma_TT, -ny::kHalfPi, ny::kHalfPi)))
              << "case " << i << " node " << q;
        }
      }
    }
    EXPECT_GT(with_tt, 1000) << "case " << i; /* the TT part is checked, not skipped */
  }
}

/* The R nodes' Gaussians skip the normaliser's table and the R tails' erfc when no node needs them (yarn_lobes checks
 * every node's mean first): what they then write must be what the full computation gives, to the bit. Means drawn
 * where both skips apply (every lane more than 9 beta_R from the bounds, so the tails are cut and the closed form
 * holds) for the shipped cotton (beta_R 1 degree) and fleece (7.2 degrees) models, TT part included. A skipped
 * mass of 1 - 2^-24 instead of 1 fails it. */
TEST(YarnBsdf, RNodeGaussiansSkipOnlyWhatNoNodeNeeds)
{
  for (const char *preset : {"cotton", "fleece"}) {
    const std::vector<float> flat = model::load_model(model::builtin_model_path(preset)).kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    const ny::Cos2Width w_R = ny::make_cos2_width(p.fiber.beta_R), w_TT = ny::make_cos2_width(p.fiber.beta_TT);
    const float reach = float(kPi / 2) - 9.5f * p.fiber.beta_R;
    ASSERT_GT(reach, 0.3f) << preset;
    std::mt19937 rng(43);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    for (int k = 0; k < 20000; k++) {
      ny::YarnRNodeSetupLanes full{}, skip{};
      for (int q = 0; q < ny::kYarnRNodes; q++) {
        full.mu[q] = skip.mu[q] = reach * U(rng);
        full.phi_TT[q] = skip.phi_TT[q] = float(kPi) * U(rng);
        ASSERT_TRUE(ny::cos2_gaussian_closed_form_holds(float(kPi / 2) - std::fabs(full.mu[q]), p.fiber.beta_R));
        ASSERT_TRUE(ny::truncated_normal_tails_cut((-float(kPi / 2) - full.mu[q]) / p.fiber.beta_R,
                                                   (float(kPi / 2) - full.mu[q]) / p.fiber.beta_R));
      }
      ny::yarn_r_nodes_gaussians_lanes<true, true, true>(p, w_R, w_TT, full);
      ny::yarn_r_nodes_gaussians_lanes<true, false, false>(p, w_R, w_TT, skip);
      ASSERT_EQ(std::memcmp(&full, &skip, sizeof(full)), 0) << preset << " k " << k;
    }
  }
}

TEST(YarnBsdf, RNodeLanesAreTheNodesOneByOne)
{
  std::vector<model::YarnModel> models = {synthetic_model("fleece", 6), synthetic_yarn_model("cotton", 6)};
  model::YarnModel one_node = synthetic_model("polyester", 8);
  one_node.r_free_path = 0.0;
  models.push_back(one_node);
  model::YarnModel no_table = synthetic_model("gabardine", 9);
  no_table.r_shape = model::RShapeTable{};
  models.push_back(no_table);
  for (const char *preset : {"silk", "gabardine"}) {
    models.push_back(model::load_model(model::builtin_model_path(preset)));
  }
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (size_t i = 0; i < models.size(); i++) {
    const std::vector<float> flat = models[i].kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    int nonzero = 0, tt = 0, n_R_seen = 0, tabled = 0;
    for (int k = 0; k < 20000; k++) {
      const ny::Vec3 wi = from_polar((kPi / 2 + 0.05) * U(rng), 2 * kPi * U(rng) - kPi);
      const ny::Vec3 wo = from_polar(kPi * U(rng), 2 * kPi * U(rng) - kPi);
      const ny::YarnLobes l = ny::yarn_lobes(p, wi);
      ny::Rgb sum = ny::make_rgb(0.0f);
      float pdf = 0.0f;
      for (int q = 0; q < l.n_R; q++) {
        const ny::YarnOutgoing o = ny::yarn_outgoing(ny::yarn_to_r_node(l.node[q], wo));
        if (!(o.w.z > 0.0f)) {
          continue;
        }
        ny::Rgb R, TT;
        ny::yarn_eval_R_parts(l, q, o, &R, &TT);
        sum = sum + ((ny::make_rgb(1.0f) - l.tau) * R + l.tau * TT); /* each node's value, then the sum */
        float r, t;
        ny::yarn_pdf_R_parts(l, q, o, &r, &t);
        pdf += (1.0f - l.q_TT) * r + l.q_TT * t;
      }
      sum = sum * (1.0f / float(l.n_R));
      pdf /= float(l.n_R);
      const ny::YarnOutgoing o_base = ny::yarn_outgoing(ny::yarn_to_surface_fiber(p.twist, wo));
      const ny::Rgb f = ny::yarn_eval_R(l, wo, o_base);
      const float pdf_lanes = ny::yarn_pdf_R(l, wo, o_base);
      ASSERT_TRUE(bit_equal(f.r, sum.r) && bit_equal(f.g, sum.g) && bit_equal(f.b, sum.b))
          << "model " << i << " k " << k << ": " << f.r << " " << f.g << " " << f.b << " against " << sum.r << " "
          << sum.g << " " << sum.b;
      ASSERT_TRUE(bit_equal(pdf_lanes, pdf)) << "model " << i << " k " << k << ": " << pdf_lanes << " against " << pdf;
      nonzero += f.g > 0.0f;
      tt += l.q_TT > 0.0f;
      tabled += l.az_bins > 0;
      n_R_seen = std::max(n_R_seen, l.n_R);
    }
    EXPECT_GT(nonzero, 2000) << "model " << i; /* not 0 == 0 */
    if (i == 0 || i == 1) {
      EXPECT_EQ(n_R_seen, ny::kYarnRNodes) << "model " << i;
      EXPECT_GT(tt, 1000) << "model " << i;
    }
    if (i == 2) {
      EXPECT_EQ(n_R_seen, 1);
    }
    if (i == 3) {
      EXPECT_EQ(tabled, 0);
      EXPECT_EQ(tt, 0);
    }
  }
}
