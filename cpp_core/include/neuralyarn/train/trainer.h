// SPDX-License-Identifier: Apache-2.0
//
// Fits an MLP to a dataset with Adam: mini-batches drawn epoch by epoch from a seeded permutation (or the
// full batch), an exponentially decaying learning rate, the training and validation loss recorded along
// the way. Each batch's gradient is computed in fixed chunks of columns in parallel and summed in chunk
// order, so a run is bit-for-bit reproducible from its seed at any thread count.
//
// A non-finite loss or gradient stops training with `diverged` set; the network keeps the last weights
// whose loss was finite.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "neuralyarn/train/dataset.h"
#include "neuralyarn/train/mlp.h"

namespace neuralyarn::train {

struct TrainOptions {
  int steps = 5000;
  float learning_rate = 5e-3f;
  float final_learning_rate_fraction = 1.0f; /* lr decays geometrically to lr * this at the last step */
  int batch = 0;           /* 0 (or >= the dataset size): full batch */
  Loss loss = Loss::kMse;
  float log_eps = 1e-3f;   /* offset of the log loss */
  uint64_t seed = 1;       /* initial weights and mini-batches */
  int record_every = 100;  /* loss curve resolution, in steps */
  int threads = 0;         /* 0: all cores */
  const Mlp<float> *initial = nullptr; /* start from these weights instead of a seeded initialisation */
  /* Called every record_every steps with the step, the number of steps and the last batch loss. */
  std::function<void(int step, int steps, float loss)> progress;
};

struct TrainResult {
  Mlp<float> net;
  float initial_loss = 0, train_loss = 0, validation_loss = 0; /* in the options' loss */
  float train_mse = 0, validation_mse = 0;                      /* plain MSE, whatever the loss */
  std::vector<float> curve;                                     /* batch loss every record_every steps */
  int steps_done = 0;
  bool diverged = false;
  std::string message; /* why training stopped early */
  double seconds = 0;
};

/* Loss (and gradient, unless null) of the columns `columns` of a dataset (all of them by default), computed
 * in parallel chunks (see above). */
float dataset_loss(const Mlp<float> &net, const Mlp<float>::Mat &X, const Mlp<float>::Mat &T, Loss loss, float eps,
                   Mlp<float>::Vec *gradient, Mlp<float>::Columns columns = {});

TrainResult train_network(const MlpShape &shape, const Dataset &train, const Dataset &validation,
                          const TrainOptions &options);

}  // namespace neuralyarn::train
