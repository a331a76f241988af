// SPDX-License-Identifier: Apache-2.0
//
// The R shape fit (model/r_shape.h) recovers a known azimuthal density and TT share: maps whose R lobe is
// a model's own lobe with a non-uniform table, fitted from the same model with a uniform azimuth and no TT.
#include <gtest/gtest.h>

#include <cmath>

#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/r_shape.h"
#include "neuralyarn/units.h"
#include "synthetic_model.h"

using namespace neuralyarn;

namespace {

/* The R map of `truth`: its lobe integrated over every map bin (cells = map bins). */
rdm::RdmMaps r_maps_of(const model::YarnModel &truth, const rdm::MapResolution &bins)
{
  model::LobePooling per_bin;
  per_bin.cell_deg = 0.5;
  const model::LobeGrid g = model::model_lobe_grid(truth, bins, model::Lobe::kR, per_bin);
  EXPECT_EQ(g.cells_per_group(), bins.outgoing());
  rdm::RdmMaps maps;
  maps.bins = bins;
  maps.preset = truth.preset;
  maps.r.assign(g.cells.size(), 0.0f);
  for (size_t i = 0; i < g.cells.size(); i++) {
    const int to = int((i / 3 / size_t(bins.phi_o)) % size_t(bins.theta_o));
    maps.r[i] = float(g.cells[i] / maps.outgoing_solid_angle(to));
  }
  return maps;
}

/* Fits the table of a truth whose azimuth density is a ramp (0.2 to 1.8 times the mean, rows alike, so that
 * the table's bilinear blend over w_i and its linear interpolation in phi~ reproduce it inside every bin)
 * and whose TT share is `tau` in every row; checks what the fit recovers. */
void expect_fit_recovers(const float tau[3])
{
  model::YarnModel truth = neuralyarn::testing::synthetic_model("silk", 7);
  const int na = truth.r_shape.azimuth_bins, stride = truth.r_shape.stride();
  for (size_t i = 0; i < truth.r_shape.values.size(); i++) {
    const int k = int(i % size_t(stride));
    truth.r_shape.values[i] =
        k < na ? float((1.0 + 0.8 * (k - 0.5 * (na - 1)) / (0.5 * (na - 1))) / kPi) : tau[k - na];
  }
  const rdm::MapResolution bins{6, 12, 45, 90};
  const rdm::RdmMaps maps = r_maps_of(truth, bins);
  model::RShapeOptions o;
  o.theta_bins = truth.r_shape.theta_bins;
  o.phi_bins = truth.r_shape.phi_bins;
  o.azimuth_bins = truth.r_shape.azimuth_bins;
  model::YarnModel fitted = truth;
  fitted.r_shape = model::fit_r_shape(truth, maps, o); /* ignores truth's own table */
  ASSERT_EQ(fitted.r_shape.values.size(), truth.r_shape.values.size());
  double err_fit = 0, err_uniform = 0, tau_err = 0;
  const float uniform = float(1.0 / kPi);
  for (size_t i = 0; i < fitted.r_shape.values.size(); i++) {
    const int k = int(i % size_t(stride));
    if (k < na) {
      err_fit += std::abs(fitted.r_shape.values[i] - truth.r_shape.values[i]) / truth.r_shape.values[i];
      err_uniform += std::abs(uniform - truth.r_shape.values[i]) / truth.r_shape.values[i];
    }
    else {
      tau_err = std::max(tau_err, double(std::abs(fitted.r_shape.values[i] - tau[k - na])));
    }
  }
  const double n_nu = double(fitted.r_shape.values.size() / size_t(stride) * size_t(na));
  err_fit /= n_nu;
  err_uniform /= n_nu;
  /* The grazing row's lobe against the truth's, per map bin, and that of a fit without the TT part. */
  model::LobePooling per_bin;
  per_bin.cell_deg = 0.5;
  const model::LobeGrid gt = model::pool_map_lobe(maps, model::Lobe::kR, per_bin);
  const double l1 = model::compare_lobes(model::model_lobe_grid(fitted, bins, model::Lobe::kR, per_bin), gt).l1.back();
  std::printf("tau %.2f %.2f %.2f: mean relative deviation from the true density: fitted %.3f, uniform %.3f; "
              "worst TT share error %.3f; grazing lobe L1 %.3f\n",
              tau[0], tau[1], tau[2], err_fit, err_uniform, tau_err, l1);
  /* The fit sees the pieces by the 30-degree azimuth bin their samples fall in, the density is linear
   * between bin centres: close, not exact (0.04-0.05 here). */
  EXPECT_LT(err_fit, 0.07);
  EXPECT_LT(err_fit, 0.1 * err_uniform);
  EXPECT_LT(tau_err, 0.02);
  EXPECT_LT(l1, 0.03);
  if (tau[0] > 0.0f) {
    /* Without the TT part the same maps are far off (0.4 here). */
    o.fit_tt = false;
    model::YarnModel no_tt = truth;
    no_tt.r_shape = model::fit_r_shape(truth, maps, o);
    const double l1_no_tt =
        model::compare_lobes(model::model_lobe_grid(no_tt, bins, model::Lobe::kR, per_bin), gt).l1.back();
    EXPECT_GT(l1_no_tt, 10 * l1);
  }
  /* Every fitted row integrates to 1. */
  for (size_t r = 0; r < fitted.r_shape.values.size() / size_t(stride); r++) {
    double s = 0;
    for (int k = 0; k < o.azimuth_bins; k++) {
      s += fitted.r_shape.values[r * size_t(stride) + size_t(k)] * kPi / o.azimuth_bins;
    }
    EXPECT_NEAR(s, 1.0, 1e-5);
  }
}

}  // namespace

TEST(RShape, FitRecoversAKnownDensityAndTTShare)
{
  const float tau[3] = {0.15f, 0.35f, 0.55f};
  expect_fit_recovers(tau);
}

TEST(RShape, FitFindsNoTTShareWhereThereIsNone)
{
  const float tau[3] = {0.0f, 0.0f, 0.0f};
  expect_fit_recovers(tau);
}

TEST(RShape, NonNegativeLeastSquaresMatchesAKnownSolution)
{
  /* y = A x with x = (2, 0, 1) and a column that the unconstrained solution would weigh negatively. */
  Eigen::MatrixXd A(5, 3);
  A << 1, 0.9, 0, 0, 1, 1, 1, 0.5, 2, 2, 2.1, 0, 0, 0, 1;
  const Eigen::Vector3d x_true(2, 0, 1);
  Eigen::VectorXd y = A * x_true;
  y[1] -= 0.5; /* pushes the middle weight below zero unconstrained */
  const Eigen::VectorXd x = model::nonnegative_least_squares(A.transpose() * A, A.transpose() * y);
  const Eigen::VectorXd free = (A.transpose() * A).ldlt().solve(A.transpose() * y);
  ASSERT_LT(free[1], 0.0);
  EXPECT_GE(x.minCoeff(), 0.0);
  EXPECT_EQ(x[1], 0.0);
  /* The constrained optimum: least squares over the two remaining columns. */
  Eigen::MatrixXd A2(5, 2);
  A2 << A.col(0), A.col(2);
  const Eigen::VectorXd x2 = (A2.transpose() * A2).ldlt().solve(A2.transpose() * y);
  EXPECT_NEAR(x[0], x2[0], 1e-9);
  EXPECT_NEAR(x[2], x2[1], 1e-9);
}
