// SPDX-License-Identifier: Apache-2.0
//
// Training data from the maps and the trainer: held-out bins are disjoint from training bins, samples are
// uniform in solid angle, the T network learns P(T | w_i) from a gathered map, and training is
// reproducible from its seed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/kernel/frames.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/train/trainer.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

namespace {
const rdm::RdmMaps &fleece_maps()
{
  static const rdm::RdmMaps maps = [] {
    rdm::GatherOptions o;
    o.paths = 22 * 90 * 200;
    o.bins = {22, 90, 4, 4};
    o.threads = 2;
    return rdm::gather(find_preset("fleece"), o);
  }();
  return maps;
}
}  // namespace

TEST(Dataset, TransmissionSamplesAreUnitUniformAndSplit)
{
  const rdm::RdmMaps &maps = fleece_maps();
  const train::Dataset tr = train::sample_transmission(maps, 20000, 1, false);
  const train::Dataset va = train::sample_transmission(maps, 5000, 2, true);
  int held = 0;
  for (int ti = 0; ti < 22; ti++) {
    for (int pi = 0; pi < 90; pi++) {
      held += train::is_validation_bin(maps.bins, ti, pi);
    }
  }
  EXPECT_GT(held, 150);
  EXPECT_LT(held, 250); /* about a tenth of 1980 */
  double mean_z = 0.0;
  for (int j = 0; j < tr.X.cols(); j++) {
    const double x = tr.X(0, j), y = tr.X(1, j), z = tr.X(2, j);
    ASSERT_NEAR(x * x + y * y + z * z, 1.0, 1e-5);
    ASSERT_GE(z, 0.0);
    mean_z += z;
    const int ti = rdm::bin_of(std::acos(z), 0.0, kPi / 2, 22), pi = rdm::bin_of(std::atan2(y, x), -kPi, kPi, 90);
    ASSERT_FALSE(train::is_validation_bin(maps.bins, ti, pi));
    /* Bilinear between bin centres: within the range of the 3 x 3 neighbourhood of the bin. */
    float lo = 1.0f, hi = 0.0f;
    for (int dt = -1; dt <= 1; dt++) {
      for (int dp = -1; dp <= 1; dp++) {
        const float v = maps.p_t[maps.incident_index(std::clamp(ti + dt, 0, 21), (pi + dp + 90) % 90)];
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
    ASSERT_GE(tr.Y(0, j), lo - 1e-6f);
    ASSERT_LE(tr.Y(0, j), hi + 1e-6f);
  }
  /* Uniform in solid angle over the hemisphere: E[cos theta] = 1/2, standard error 0.29/sqrt(n). */
  EXPECT_NEAR(mean_z / tr.X.cols(), 0.5, 5 * 0.29 / std::sqrt(double(tr.X.cols())));
  for (int j = 0; j < va.X.cols(); j++) {
    const int ti = rdm::bin_of(std::acos(double(va.X(2, j))), 0.0, kPi / 2, 22);
    const int pi = rdm::bin_of(std::atan2(double(va.X(1, j)), double(va.X(0, j))), -kPi, kPi, 90);
    ASSERT_TRUE(train::is_validation_bin(maps.bins, ti, pi));
  }
}

/* rho_R's targets (D65): with three channels each channel's R energy over the channel mean of F / 2 (the analytic
 * lobe's, F the Fresnel factor of the fiber's C_R at the bin centre), so that the table times that mean is the
 * map's R energy in every channel; with one channel the channel means' ratio, which is the mean of the three. On
 * silk the maps' colour is not F's (the light through a surface fiber is tinted by C_TT), which the three
 * channels keep. */
TEST(Dataset, ReflectionScaleTargetsCarryTheMapsColour)
{
  rdm::GatherOptions o;
  o.paths = 22 * 90 * 200;
  o.bins = {22, 90, 4, 4};
  o.threads = 2;
  const FiberPreset silk = find_preset("silk");
  const rdm::RdmMaps maps = rdm::gather(silk, o);
  const std::vector<float> one = train::reflection_scale_table(maps, 1), rgb = train::reflection_scale_table(maps, 3);
  ASSERT_EQ(rgb.size(), 3 * one.size());
  const std::vector<double> E = maps.energy(maps.r);
  const ny::TwistRotation twist = ny::make_twist_rotation(float(maps.surface_alpha()));
  int off_fresnel = 0, bins = 0;
  for (int ti = 0; ti < 22; ti++) {
    for (int pi = 0; pi < 90; pi++) {
      const size_t i = maps.incident_index(ti, pi);
      const double theta = (ti + 0.5) * 0.5 * kPi / 22, phi = -kPi + (pi + 0.5) * 2.0 * kPi / 90;
      const ny::Vec3 w = ny::yarn_to_surface_fiber(
          twist, ny::make_vec3(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)),
                               float(std::cos(theta))));
      const ny::Rgb F = ny::schlick_fresnel(maps.preset.fiber_params().C_R, ny::cos_theta(w));
      const double half_F = 0.5 * (double(F.r) + F.g + F.b) / 3.0;
      for (int c = 0; c < 3; c++) {
        EXPECT_NEAR(rgb[i * 3 + size_t(c)] * half_F, E[i * 3 + size_t(c)], 1e-5 * E[i * 3 + size_t(c)] + 1e-12);
      }
      EXPECT_NEAR(one[i], (rgb[i * 3] + rgb[i * 3 + 1] + rgb[i * 3 + 2]) / 3.0, 1e-5 * one[i]);
      if (E[i * 3] > 0.0 && E[i * 3 + 1] > 0.0) {
        bins++;
        off_fresnel += (E[i * 3 + 1] / E[i * 3]) / (double(F.g) / F.r) > 2.0;
      }
    }
  }
  /* The map's green over its red is more than twice F's at a third of the bins (662 of 1968 with this seed; at
   * 200 paths a bin the rest are mostly noise about small ratios): what one output could not carry. */
  EXPECT_GT(off_fresnel, bins / 4) << off_fresnel << " of " << bins;
  EXPECT_THROW(train::reflection_scale_table(maps, 2), ParameterError);
  const train::Dataset d = train::sample_reflection_scale(maps, 1000, 3, false, 3);
  EXPECT_EQ(d.Y.rows(), 3);
}

TEST(Trainer, TNetworkLearnsTransmissionAndIsReproducible)
{
  const rdm::RdmMaps &maps = fleece_maps();
  const train::Dataset tr = train::sample_transmission(maps, 20000, 1, false);
  const train::Dataset va = train::sample_transmission(maps, 4000, 2, true);
  train::TrainOptions o;
  o.steps = 2000;
  o.learning_rate = 1e-2f;
  o.batch = 2048;
  const train::MlpShape shape{{3, 7, 7, 1}, ny::kMlpHeadSigmoid};
  const train::TrainResult a = train::train_network(shape, tr, va, o);
  /* P(T) is ~0 except within ~20 degrees of grazing, where it rises steeply to ~1: the initial network
   * (~0.5 everywhere) has MSE ~0.3. */
  EXPECT_LT(a.train_loss, a.initial_loss / 30.0f);
  EXPECT_LT(a.validation_mse, 0.01f);
  const train::TrainResult b = train::train_network(shape, tr, va, o);
  EXPECT_EQ(a.net.to_flat(), b.net.to_flat()) << "training is not reproducible from its seed";
  /* Gradients are summed in fixed chunks: the same bits on one thread. */
  o.threads = 1;
  const train::TrainResult c = train::train_network(shape, tr, va, o);
  EXPECT_EQ(a.net.to_flat(), c.net.to_flat()) << "training depends on the thread count";
}

TEST(Trainer, DivergenceStopsWithAMessageAndFiniteWeights)
{
  const rdm::RdmMaps &maps = fleece_maps();
  const train::Dataset tr = train::sample_transmission(maps, 4096, 1, false);
  train::TrainOptions o;
  o.steps = 200;
  o.learning_rate = 1e30f; /* absurd: the first step overflows the weights */
  const train::MlpShape shape{{3, 7, 7, 1}, ny::kMlpHeadExp};
  const train::TrainResult r = train::train_network(shape, tr, {}, o);
  EXPECT_TRUE(r.diverged);
  EXPECT_NE(r.message.find("diverged"), std::string::npos);
  EXPECT_LT(r.steps_done, 200);
  for (float v : r.net.to_flat()) {
    ASSERT_TRUE(std::isfinite(v));
  }
}

TEST(Dataset, MultipleScatteringSamplesCarryTheirBinsValue)
{
  const rdm::RdmMaps &maps = fleece_maps();
  const train::Dataset d = train::sample_multiple_scattering(maps, 20000, 4, false);
  ASSERT_EQ(d.X.rows(), 6);
  ASSERT_EQ(d.Y.rows(), 3);
  double mean_zo = 0.0;
  for (int j = 0; j < d.X.cols(); j++) {
    const double zi = d.X(2, j), zo = d.X(5, j);
    ASSERT_GE(zi, 0.0);
    mean_zo += zo;
    const int ti = rdm::bin_of(std::acos(zi), 0.0, kPi / 2, 22);
    const int pi = rdm::bin_of(std::atan2(double(d.X(1, j)), double(d.X(0, j))), -kPi, kPi, 90);
    const int to = rdm::bin_of(std::acos(zo), 0.0, kPi, 4);
    const int po = rdm::bin_of(std::atan2(double(d.X(4, j)), double(d.X(3, j))), -kPi, kPi, 4);
    ASSERT_EQ(d.Y(1, j), maps.m[maps.map_index(ti, pi, to, po) + 1]);
  }
  /* w_o uniform on the whole sphere: E[cos theta_o] = 0, standard deviation 1/sqrt(3). */
  EXPECT_NEAR(mean_zo / d.X.cols(), 0.0, 5 * 0.577 / std::sqrt(double(d.X.cols())));
}

/* Two-sided (D45): the bin's value in the three rows of w_o's side (the kernel's choice: z >= 0 the first three),
 * NaN in the other three; the same inputs and values as the one-sided dataset of the same seed. */
TEST(Dataset, TwoSidedMultipleScatteringSamplesFillTheirSidesRows)
{
  const rdm::RdmMaps &maps = fleece_maps();
  const train::Dataset one = train::sample_multiple_scattering(maps, 4000, 4, false);
  const train::Dataset two = train::sample_multiple_scattering(maps, 4000, 4, false, true);
  ASSERT_EQ(two.Y.rows(), 6);
  ASSERT_EQ(two.X, one.X);
  int down = 0;
  for (int j = 0; j < two.X.cols(); j++) {
    const int side = two.X(5, j) < 0.0f ? 3 : 0;
    down += side == 3;
    for (int c = 0; c < 3; c++) {
      ASSERT_EQ(two.Y(side + c, j), one.Y(c, j)) << j;
      ASSERT_TRUE(std::isnan(two.Y(3 - side + c, j))) << j;
    }
  }
  EXPECT_GT(down, 1800);
  EXPECT_LT(down, 2200);
}

TEST(Trainer, RelativeLossIsUnbiasedForSparseNoisyTargets)
{
  /* Monte Carlo bins of few paths: a target that is 0 nine times in ten and 10 otherwise (mean 1). The
   * relative and Poisson losses (weights from the prediction, not the target) converge to the mean; the
   * log loss to far below it (its optimum is the geometric mean of t + eps, minus eps). */
  const int n = 20000;
  train::Dataset d;
  d.X = train::Mlp<float>::Mat::Constant(1, n, 0.5f);
  d.Y.resize(1, n);
  for (int j = 0; j < n; j++) {
    d.Y(0, j) = j % 10 == 3 ? 10.0f : 0.0f;
  }
  auto fit = [&](train::Loss loss) {
    train::TrainOptions o;
    o.steps = 3000;
    o.learning_rate = 1e-2f;
    o.final_learning_rate_fraction = 0.05f;
    o.batch = 2000;
    o.loss = loss;
    o.log_eps = 1e-3f;
    o.seed = 4;
    o.threads = 1;
    const train::TrainResult r = train::train_network(train::MlpShape{{1, 4, 1}, ny::kMlpHeadExp}, d, d, o);
    return r.net.forward(d.X.leftCols(1))(0, 0);
  };
  const float rel = fit(train::Loss::kRelativeMse), log = fit(train::Loss::kLogMse), mse = fit(train::Loss::kMse),
              poisson = fit(train::Loss::kPoissonMse);
  std::printf("mean 1: relative %.4f, poisson %.4f, log %.4f, mse %.4f\n", rel, poisson, log, mse);
  EXPECT_NEAR(rel, 1.0f, 0.05f);
  EXPECT_NEAR(poisson, 1.0f, 0.05f);
  EXPECT_NEAR(mse, 1.0f, 0.05f);
  EXPECT_LT(log, 0.1f);
}
