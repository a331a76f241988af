// SPDX-License-Identifier: Apache-2.0
//
// The surface level (D44): the walks through a patch of curves (rdm/surface_gather.h) and the stock-closure
// fit (model/surface_fit.h), with its file and the curve a renderer reads.
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "neuralyarn/model/surface_fit.h"
#include "neuralyarn/rdm/surface_gather.h"
#include "neuralyarn/units.h"
#include "synthetic_model.h"

namespace {

using namespace neuralyarn;
namespace cl = model::cycles_lobes;

/* Straight parallel yarns along x in the plane z = 0, `n` of them `spacing` apart in y, radius `r`. */
geometry::CurveSet parallel_yarns(int n, double spacing, double r, double half_length)
{
  geometry::CurveSet c;
  c.offsets.push_back(0);
  for (int j = 0; j < n; j++) {
    const float y = float((j - (n - 1) / 2.0) * spacing);
    c.points.emplace_back(float(-half_length), y, 0.0f);
    c.points.emplace_back(float(half_length), y, 0.0f);
    c.offsets.push_back(int(c.points.size()));
    c.radii.push_back(float(r));
  }
  return c;
}

/* The mean gap fraction of parallel tubes over a view bin: a view tilted by theta_yz in the plane normal to
 * the tubes sees each tube's shadow 2r / cos(theta_yz) wide every `spacing`; midpoint rule over cos theta_v
 * in the bin and the view's azimuth. */
double gap_fraction(double c0, double c1, double spacing, double r)
{
  constexpr int n = 800;
  double sum = 0.0;
  for (int a = 0; a < n; a++) {
    const double c = c0 + (c1 - c0) * (a + 0.5) / n, s = std::sqrt(1.0 - c * c);
    for (int b = 0; b < n; b++) {
      const double phi = 2.0 * kPi * (b + 0.5) / n;
      const double cos_yz = c / std::sqrt(c * c + s * s * std::sin(phi) * std::sin(phi));
      sum += std::max(0.0, 1.0 - 2.0 * r / (spacing * cos_yz));
    }
  }
  return sum / (double(n) * n);
}

rdm::SurfaceGatherOptions options(uint64_t paths, double period)
{
  rdm::SurfaceGatherOptions o;
  o.paths = paths;
  o.view_bins = 8;
  o.period_x = o.period_y = period;
  return o;
}

TEST(SurfaceGather, WhatPassesStraightIsTheGapsBetweenOpaqueYarns)
{
  /* An opaque yarn (P_T ~ 1e-17): only the gaps let light through unscattered, from either face. */
  const model::YarnModel m = neuralyarn::testing::synthetic_model("fleece", 3, -3.0, -40.0);
  const double spacing = 4.0, r = 1.0;
  const rdm::SurfaceMaps maps = rdm::gather_surface(parallel_yarns(81, spacing, r, 2000.0), m, options(320000, spacing));
  const int V = maps.view_bins;
  const double n = double(maps.paths) / (2.0 * V);
  for (int side = 0; side < 2; side++) {
    for (int v = 0; v < V; v++) {
      const double expect = gap_fraction(double(v) / V, double(v + 1) / V, spacing, r);
      /* Binomial: four standard errors of n paths. */
      const double tol = 4.0 * std::sqrt(std::max(expect * (1.0 - expect), 1e-3) / n);
      EXPECT_NEAR(maps.tau[size_t(side * V + v)], expect, tol) << "side " << side << ", view bin " << v;
    }
  }
  /* Near the normal half of the light passes: the measurement is not trivially zero. */
  EXPECT_GT(maps.tau[size_t(V - 1)], 0.4);
}

TEST(SurfaceGather, SameMapsAtAnyThreadCountAndTheirEnergyIsWhatLeaves)
{
  const model::YarnModel m = neuralyarn::testing::synthetic_model("fleece", 5);
  rdm::SurfaceGatherOptions o = options(100000, 3.0);
  o.threads = 1;
  const geometry::CurveSet yarns = parallel_yarns(41, 3.0, 1.0, 1000.0);
  const rdm::SurfaceMaps a = rdm::gather_surface(yarns, m, o);
  o.threads = 2;
  const rdm::SurfaceMaps b = rdm::gather_surface(yarns, m, o);
  EXPECT_EQ(a.D, b.D);
  EXPECT_EQ(a.tau, b.tau);
  /* The maps integrate to the scattered energy of every view; a yarn with P_T > 0 lets some through. */
  const double omega = a.bin_solid_angle();
  for (int side = 0; side < 2; side++) {
    for (int v = 0; v < a.view_bins; v++) {
      for (int c = 0; c < 3; c++) {
        double sum = 0.0;
        for (int h = 0; h < 2; h++) {
          for (int t = 0; t < a.light_theta; t++) {
            for (int p = 0; p < a.light_phi; p++) {
              sum += a.D[a.index(side, v, h, t, p) + size_t(c)] * omega;
            }
          }
        }
        EXPECT_NEAR(sum, a.scattered[size_t((side * a.view_bins + v) * 3 + c)], 1e-9);
      }
    }
  }
  EXPECT_GT(a.tau[0] + a.tau[size_t(a.view_bins - 1)], 0.0);
}

TEST(SurfaceGather, BadOptionsAreRefused)
{
  const model::YarnModel m = neuralyarn::testing::synthetic_model("fleece", 5);
  const geometry::CurveSet yarns = parallel_yarns(5, 3.0, 1.0, 10.0);
  EXPECT_THROW(rdm::gather_surface(yarns, m, options(0, 3.0)), ParameterError);
  EXPECT_THROW(rdm::gather_surface(yarns, m, options(10, 0.0)), ParameterError);
  EXPECT_THROW(rdm::gather_surface(yarns, m, options(10, std::nan(""))), ParameterError);
  EXPECT_THROW(rdm::gather_surface(yarns, m, options(10, 100.0)), ParameterError); /* wider than the patch */
  rdm::SurfaceGatherOptions o = options(10, 3.0);
  o.light_phi = 0;
  EXPECT_THROW(rdm::gather_surface(yarns, m, o), ParameterError);
  EXPECT_THROW(rdm::gather_surface(geometry::CurveSet{}, m, options(10, 3.0)), std::invalid_argument);
}

/* Maps made from known lobe weights: the lobes' means over each bin, finely sampled. */
rdm::SurfaceMaps maps_of(const std::vector<model::SurfaceLobe> &lobes, const std::vector<std::array<double, 3>> &W)
{
  rdm::SurfaceMaps m;
  m.view_bins = 4, m.light_theta = 16, m.light_phi = 24;
  m.D.assign(size_t(2 * m.view_bins * 2 * m.light_theta * m.light_phi * 3), 0.0);
  m.tau.assign(size_t(2 * m.view_bins), 0.1);
  m.scattered.assign(size_t(2 * m.view_bins * 3), 0.0);
  constexpr int S = 6;
  for (int side = 0; side < 2; side++) {
    for (int v = 0; v < m.view_bins; v++) {
      for (int h = 0; h < 2; h++) {
        for (int t = 0; t < m.light_theta; t++) {
          for (int p = 0; p < m.light_phi; p++) {
            double sum[3] = {0, 0, 0};
            for (int a = 0; a < S; a++) {
              const double cv = (v + (a + 0.5) / S) / m.view_bins;
              const cl::Dir view{std::sqrt(1.0 - cv * cv), 0.0, cv};
              for (int b = 0; b < S * S; b++) {
                const double ct = (t + (b / S + 0.5) / S) / m.light_theta;
                const double ph = 2.0 * kPi * (p + (b % S + 0.5) / S) / m.light_phi;
                const double st = std::sqrt(1.0 - ct * ct);
                const cl::Dir l{st * std::cos(ph), st * std::sin(ph), h == 0 ? ct : -ct};
                for (size_t k = 0; k < lobes.size(); k++) {
                  for (int c = 0; c < 3; c++) {
                    sum[c] += W[k][size_t(c)] * model::surface_lobe_eval(lobes[k], view, l);
                  }
                }
              }
            }
            const size_t i = m.index(side, v, h, t, p);
            for (int c = 0; c < 3; c++) {
              m.D[i + size_t(c)] = sum[c] / (S * S * S);
              m.scattered[size_t((side * m.view_bins + v) * 3 + c)] += m.D[i + size_t(c)] * m.bin_solid_angle();
            }
          }
        }
      }
    }
  }
  return m;
}

TEST(SurfaceFit, RecoversTheWeightsOfKnownLobes)
{
  const std::vector<model::SurfaceLobe> lobes = {{"diffuse", 0}, {"translucent", 0}, {"ggx", 0.2}, {"ggx", 0.5},
                                                 {"ggx", 1.0}};
  const std::vector<std::array<double, 3>> W = {{0.30, 0.20, 0.05}, {0.05, 0.10, 0.20}, {0.0, 0.02, 0.0},
                                                {0.10, 0.0, 0.05}, {0.0, 0.08, 0.02}};
  const model::SurfaceBsdf s = model::fit_surface(maps_of(lobes, W));
  ASSERT_EQ(s.lobes.size(), lobes.size());
  for (size_t cell = 0; cell < s.fit_error.size(); cell++) {
    EXPECT_LT(s.fit_error[cell], 0.02) << cell;
    for (size_t k = 0; k < lobes.size(); k++) {
      EXPECT_EQ(s.lobes[k].closure, lobes[k].closure);
      EXPECT_DOUBLE_EQ(s.lobes[k].alpha, lobes[k].alpha);
      for (int c = 0; c < 3; c++) {
        EXPECT_NEAR(s.W[(cell * lobes.size() + k) * 3 + size_t(c)], W[k][size_t(c)], 0.01)
            << "cell " << cell << ", lobe " << k << ", channel " << c;
      }
    }
    EXPECT_FLOAT_EQ(s.transparent[cell], 0.1f);
  }
}

TEST(SurfaceFit, EachHemisphereKeepsItsEnergy)
{
  /* Maps no lobe set can match (all the light in one bin of each hemisphere): the fit's shape is poor, but
   * reflection and transmission each return what the maps hold. */
  rdm::SurfaceMaps m = maps_of({{"diffuse", 0}}, {{0.0, 0.0, 0.0}});
  const double omega = m.bin_solid_angle();
  for (int side = 0; side < 2; side++) {
    for (int v = 0; v < m.view_bins; v++) {
      for (int c = 0; c < 3; c++) {
        m.D[m.index(side, v, 0, 3, 5) + size_t(c)] = 0.4 / omega;
        m.D[m.index(side, v, 1, 12, 20) + size_t(c)] = 0.1 / omega;
      }
    }
  }
  const model::SurfaceBsdf s = model::fit_surface(m);
  /* View bin 2 of 4 (cos theta_v 0.5-0.75): its weights' energy, averaged over the bin's views as the maps
   * average it, by fine quadrature over the light. */
  const int v = 2;
  for (int c = 0; c < 3; c++) {
    double up = 0.0, down = 0.0;
    constexpr int nv = 8, n = 300;
    for (int a = 0; a < nv; a++) {
      const double cv = (v + (a + 0.5) / nv) / s.view_bins;
      const cl::Dir view{std::sqrt(1.0 - cv * cv), 0.0, cv};
      for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
          const double ct = (i + 0.5) / n, ph = 2.0 * kPi * (j + 0.5) / n, st = std::sqrt(1.0 - ct * ct);
          const double dw = 2.0 * kPi / (double(n) * n * nv);
          for (size_t k = 0; k < s.lobes.size(); k++) {
            const double w = s.W[((size_t(v)) * s.lobes.size() + k) * 3 + size_t(c)];
            up += w * model::surface_lobe_eval(s.lobes[k], view, {st * std::cos(ph), st * std::sin(ph), ct}) * dw;
            down += w * model::surface_lobe_eval(s.lobes[k], view, {st * std::cos(ph), st * std::sin(ph), -ct}) * dw;
          }
        }
      }
    }
    /* Within 2 % (the fit holds the lobes' energy as binned over 16 x 24 light bins). */
    EXPECT_NEAR(up, 0.4, 0.008) << c;
    EXPECT_NEAR(down, 0.1, 0.002) << c;
  }
}

model::SurfaceBsdf two_bin_surface()
{
  model::SurfaceBsdf s;
  s.view_bins = 2;
  s.lobes = {{"diffuse", 0}};
  s.transparent = {0.1f, 0.3f, 0.2f, 0.6f}; /* front 0.25, 0.75; back 0.25, 0.75 */
  s.W = {0.5f, 0.4f, 0.3f, 0.1f, 0.2f, 0.3f, 0.9f, 0.8f, 0.7f, 0.3f, 0.3f, 0.3f};
  s.albedo = std::vector<float>(12, 0.5f);
  s.fit_error = {0.1f, 0.1f, 0.1f, 0.1f};
  return s;
}

TEST(SurfaceFit, TheCurveHoldsBothFacesAtTheirViewCosines)
{
  const model::SurfaceBsdf s = two_bin_surface();
  /* Between the centres linear, beyond them extrapolated linearly and clamped to the stored ranges. */
  EXPECT_NEAR(model::surface_at(s, 0, 0.5).transparent, 0.2, 1e-7);
  EXPECT_NEAR(model::surface_at(s, 0, 1.0).transparent, 0.4, 1e-7);
  EXPECT_NEAR(model::surface_at(s, 1, 0.0).transparent, 0.0, 1e-7); /* 0.2 - 0.2, clamped at 0 */
  EXPECT_NEAR(model::surface_at(s, 0, 1.0).W[0][0], 0.0, 1e-7);     /* 0.1 - 0.2, clamped at 0 */
  EXPECT_NEAR(model::surface_at(s, 1, 0.5).W[0][1], 0.55, 1e-7);
  constexpr int N = 1001;
  const auto t = model::surface_curve(s, -1, N), w = model::surface_curve(s, 0, N);
  for (const double cv : {0.0, 0.3, 0.5, 0.8, 1.0}) {
    for (int side = 0; side < 2; side++) {
      const double x = (side ? model::kSurfaceBackStart : 0.0) + model::kSurfaceFront * cv;
      const size_t i = size_t(std::lround(x * (N - 1)));
      ASSERT_NEAR(double(i) / (N - 1), x, 1e-9); /* these x fall on samples */
      const model::SurfaceAt at = model::surface_at(s, side, cv);
      EXPECT_NEAR(t[i][0], at.transparent, 1e-9) << side << " " << cv;
      for (int c = 0; c < 3; c++) {
        EXPECT_NEAR(w[i][size_t(c)], at.W[0][size_t(c)], 1e-9) << side << " " << cv;
      }
    }
  }
}

TEST(SurfaceFile, RoundTripsAndRefusesBadTables)
{
  const model::SurfaceBsdf s = two_bin_surface();
  const nlohmann::json j = model::surface_to_json(s);
  const model::SurfaceBsdf r = model::surface_from_json(j, "test");
  EXPECT_EQ(r.W, s.W);
  EXPECT_EQ(r.transparent, s.transparent);
  EXPECT_EQ(r.lobes.size(), 1u);
  const auto refused = [&](const char *key, const nlohmann::json &value) {
    nlohmann::json b = j;
    b[key] = value;
    try {
      model::surface_from_json(b, "test");
    }
    catch (const std::runtime_error &e) {
      return std::string(e.what()).find(std::string("'") + key + "'") != std::string::npos ||
             std::string(key) == "format";
    }
    return false;
  };
  EXPECT_TRUE(refused("format", "neuralyarn-surface 2"));
  EXPECT_TRUE(refused("view_bins", 0));
  EXPECT_TRUE(refused("W", nlohmann::json::array({0.5, 0.4})));
  nlohmann::json w = j["W"];
  w[3] = -0.1;
  EXPECT_TRUE(refused("W", w));
  w[3] = "x";
  EXPECT_TRUE(refused("W", w));
  EXPECT_TRUE(refused("transparent", nlohmann::json::array({0.1, 0.3, 0.2, 1.5})));
  EXPECT_TRUE(refused("lobes", nlohmann::json::array({{{"closure", "sheen"}}})));
  EXPECT_TRUE(refused("lobes", nlohmann::json::array({{{"closure", "ggx"}, {"alpha", 0}}})));
}

}  // namespace
