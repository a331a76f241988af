// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/train/trainer.h"

#include <chrono>
#include <random>

#include "neuralyarn/presets.h" /* ParameterError */

namespace neuralyarn::train {

TrainResult train_network(const MlpShape &shape, const Dataset &train, const Dataset &validation,
                          const TrainOptions &o)
{
  if (train.X.cols() == 0 || train.X.cols() != train.Y.cols() || validation.X.cols() != validation.Y.cols()) {
    throw ParameterError("dataset", "training data must be non-empty with one target column per input column");
  }
  if (train.X.rows() != shape.widths.front() || train.Y.rows() != shape.widths.back()) {
    throw ParameterError("dataset", "training data does not match the network's input/output widths");
  }
  if (o.steps < 0 || !(o.learning_rate > 0.0f)) {
    throw ParameterError("training", "steps must be >= 0 and the learning rate > 0");
  }
  const auto t0 = std::chrono::steady_clock::now();
  TrainResult r{Mlp<float>(shape, o.seed), 0.0f, 0.0f, 0.0f, 0.0f, {}, 0.0};
  Adam<float> adam(r.net.num_params(), o.learning_rate);
  std::mt19937_64 rng(o.seed ^ 0x5bd1e995u);
  const long n = train.X.cols();
  const bool mini = o.batch > 0 && o.batch < n;
  Mlp<float>::Mat Xb, Yb;
  if (mini) {
    Xb.resize(train.X.rows(), o.batch);
    Yb.resize(train.Y.rows(), o.batch);
  }
  r.initial_loss = r.net.loss_and_gradient(train.X, train.Y, o.loss, o.log_eps, nullptr);
  Mlp<float>::Vec g;
  for (int step = 0; step < o.steps; step++) {
    float loss;
    if (mini) {
      std::uniform_int_distribution<long> pick(0, n - 1);
      for (int j = 0; j < o.batch; j++) {
        const long c = pick(rng);
        Xb.col(j) = train.X.col(c);
        Yb.col(j) = train.Y.col(c);
      }
      loss = r.net.loss_and_gradient(Xb, Yb, o.loss, o.log_eps, &g);
    }
    else {
      loss = r.net.loss_and_gradient(train.X, train.Y, o.loss, o.log_eps, &g);
    }
    Mlp<float>::Vec p = r.net.params();
    adam.step(&p, g);
    r.net.set_params(p);
    if (o.record_every > 0 && step % o.record_every == 0) {
      r.curve.push_back(loss);
      if (o.progress) {
        o.progress(step, o.steps, loss);
      }
    }
  }
  r.train_loss = r.net.loss_and_gradient(train.X, train.Y, o.loss, o.log_eps, nullptr);
  if (validation.X.cols() > 0) {
    r.validation_loss = r.net.loss_and_gradient(validation.X, validation.Y, o.loss, o.log_eps, nullptr);
    r.validation_mse = r.net.loss_and_gradient(validation.X, validation.Y, Loss::kMse, 0.0f, nullptr);
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace neuralyarn::train
