// SPDX-License-Identifier: Apache-2.0
//
// The R azimuth fit (model/r_azimuth.h) recovers a known azimuthal density: maps whose R lobe is a model's
// own lobe with a non-uniform table, fitted from the same model with a uniform azimuth.
#include <gtest/gtest.h>

#include <cmath>

#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/r_azimuth.h"
#include "synthetic_model.h"

using namespace neuralyarn;

TEST(RAzimuth, FitRecoversAKnownDensity)
{
  /* A density that varies across phi~ (a ramp from 0.2 to 1.8 times the mean, rows alike, so that the
   * table's bilinear blend over w_i and its linear interpolation in phi~ reproduce it inside every bin). */
  model::YarnModel truth = neuralyarn::testing::synthetic_model("silk", 7);
  const int na = truth.r_azimuth.azimuth_bins;
  for (size_t i = 0; i < truth.r_azimuth.values.size(); i++) {
    const int k = int(i % size_t(na));
    truth.r_azimuth.values[i] = float((1.0 + 0.8 * (k - 0.5 * (na - 1)) / (0.5 * (na - 1))) / 3.14159265358979323846);
  }
  const rdm::MapResolution bins{6, 12, 45, 90};
  /* The R map of the truth: its lobe integrated over every map bin (cells = map bins). */
  model::LobePooling per_bin;
  per_bin.cell_deg = 0.5;
  const model::LobeGrid g = model::model_lobe_grid(truth, bins, model::Lobe::kR, per_bin);
  ASSERT_EQ(g.cells_per_group(), bins.outgoing());
  rdm::RdmMaps maps;
  maps.bins = bins;
  maps.preset = truth.preset;
  maps.r.assign(g.cells.size(), 0.0f);
  for (size_t i = 0; i < g.cells.size(); i++) {
    const int to = int((i / 3 / size_t(bins.phi_o)) % size_t(bins.theta_o));
    maps.r[i] = float(g.cells[i] / maps.outgoing_solid_angle(to));
  }
  model::RAzimuthOptions o;
  o.theta_bins = truth.r_azimuth.theta_bins;
  o.phi_bins = truth.r_azimuth.phi_bins;
  o.azimuth_bins = truth.r_azimuth.azimuth_bins;
  const model::RAzimuthTable fit = model::fit_r_azimuth(truth, maps, o); /* ignores truth's own table */
  ASSERT_EQ(fit.values.size(), truth.r_azimuth.values.size());
  double err_fit = 0, err_uniform = 0;
  const float uniform = float(1.0 / 3.14159265358979323846);
  for (size_t k = 0; k < fit.values.size(); k++) {
    err_fit += std::abs(fit.values[k] - truth.r_azimuth.values[k]) / truth.r_azimuth.values[k];
    err_uniform += std::abs(uniform - truth.r_azimuth.values[k]) / truth.r_azimuth.values[k];
  }
  err_fit /= double(fit.values.size());
  err_uniform /= double(fit.values.size());
  std::printf("mean relative deviation from the true density: fitted %.3f, uniform %.3f\n", err_fit, err_uniform);
  /* The fit sees the map bins' centres, 4-degree bins against 30-degree azimuth bins: close, not exact. */
  EXPECT_LT(err_fit, 0.05);
  EXPECT_LT(err_fit, 0.1 * err_uniform);
  /* Every fitted row integrates to 1. */
  for (size_t r = 0; r < fit.values.size() / size_t(o.azimuth_bins); r++) {
    double s = 0;
    for (int k = 0; k < o.azimuth_bins; k++) {
      s += fit.values[r * size_t(o.azimuth_bins) + size_t(k)] * 3.14159265358979323846 / o.azimuth_bins;
    }
    EXPECT_NEAR(s, 1.0, 1e-5);
  }
}
