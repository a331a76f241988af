// SPDX-License-Identifier: Apache-2.0
//
// Fits an MLP to a dataset with Adam: full batch or random mini-batches (drawn from a seeded generator,
// so a run is reproducible), the training and validation loss recorded along the way.
#pragma once

#include <functional>
#include <vector>

#include "neuralyarn/train/dataset.h"
#include "neuralyarn/train/mlp.h"

namespace neuralyarn::train {

struct TrainOptions {
  int steps = 5000;
  float learning_rate = 5e-3f;
  int batch = 0;          /* 0: full batch */
  Loss loss = Loss::kMse;
  float log_eps = 1e-3f;  /* offset of the log loss */
  uint64_t seed = 1;      /* initial weights and mini-batches */
  int record_every = 100; /* loss curve resolution, in steps */
  std::function<void(int step, int steps, float loss)> progress;
};

struct TrainResult {
  Mlp<float> net;
  float initial_loss = 0, train_loss = 0, validation_loss = 0; /* in the options' loss */
  float validation_mse = 0;                                     /* plain MSE, whatever the loss */
  std::vector<float> curve;                                     /* training loss every record_every steps */
  double seconds = 0;
};

TrainResult train_network(const MlpShape &shape, const Dataset &train, const Dataset &validation,
                          const TrainOptions &options);

}  // namespace neuralyarn::train
