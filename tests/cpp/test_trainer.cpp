// SPDX-License-Identifier: Apache-2.0
//
// Training data from the maps and the trainer: held-out bins are disjoint from training bins, samples are
// uniform in solid angle, the T network learns P(T | w_i) from a gathered map, and training is
// reproducible from its seed.
#include <gtest/gtest.h>

#include <cmath>

#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/train/trainer.h"

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
    const int ti = rdm::bin_of(std::acos(z), 0.0, M_PI / 2, 22), pi = rdm::bin_of(std::atan2(y, x), -M_PI, M_PI, 90);
    ASSERT_FALSE(train::is_validation_bin(maps.bins, ti, pi));
    ASSERT_EQ(tr.Y(0, j), maps.p_t[maps.incident_index(ti, pi)]);
  }
  /* Uniform in solid angle over the hemisphere: E[cos theta] = 1/2, standard error 0.29/sqrt(n). */
  EXPECT_NEAR(mean_z / tr.X.cols(), 0.5, 5 * 0.29 / std::sqrt(double(tr.X.cols())));
  for (int j = 0; j < va.X.cols(); j++) {
    const int ti = rdm::bin_of(std::acos(double(va.X(2, j))), 0.0, M_PI / 2, 22);
    const int pi = rdm::bin_of(std::atan2(double(va.X(1, j)), double(va.X(0, j))), -M_PI, M_PI, 90);
    ASSERT_TRUE(train::is_validation_bin(maps.bins, ti, pi));
  }
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
}
