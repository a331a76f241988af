// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/train/trainer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "neuralyarn/presets.h" /* ParameterError */

namespace neuralyarn::train {

namespace {
/* Columns per chunk: enough to pay for a task, few enough to give both cores work for batches of a few
 * thousand. Fixed, so the summation order never depends on threads. */
constexpr long kChunk = 512;
}  // namespace

float dataset_loss(const Mlp<float> &net, const Mlp<float>::Mat &X, const Mlp<float>::Mat &T, Loss loss, float eps,
                   Mlp<float>::Vec *gradient, Mlp<float>::Columns columns)
{
  const long n = columns.count < 0 ? X.cols() : columns.count;
  const long chunks = std::max<long>(1, (n + kChunk - 1) / kChunk);
  std::vector<double> values(size_t(chunks), 0.0);
  std::vector<Mlp<float>::Vec> grads(gradient ? size_t(chunks) : 0);
  tbb::parallel_for(long(0), chunks, [&](long c) {
    const long begin = c * kChunk, count = std::min(kChunk, n - begin);
    const float v = net.loss_and_gradient(X, T, Mlp<float>::Columns{columns.begin + begin, count, columns.index}, loss,
                                          eps, gradient ? &grads[size_t(c)] : nullptr);
    /* Each chunk's loss and gradient are means over its columns: weigh them by their share. */
    const double w = double(count) / double(n);
    values[size_t(c)] = double(v) * w;
    if (gradient) {
      grads[size_t(c)] *= float(w);
    }
  });
  double total = 0.0;
  for (double v : values) {
    total += v;
  }
  if (gradient) {
    *gradient = grads[0];
    for (long c = 1; c < chunks; c++) {
      *gradient += grads[size_t(c)];
    }
  }
  return float(total);
}

TrainResult train_network(const MlpShape &shape, const Dataset &train, const Dataset &validation,
                          const TrainOptions &o)
{
  if (train.X.cols() == 0 || train.X.cols() != train.Y.cols() || validation.X.cols() != validation.Y.cols()) {
    throw ParameterError("dataset", "training data must be non-empty with one target column per input column");
  }
  if (train.X.rows() != shape.widths.front() || train.Y.rows() != shape.widths.back()) {
    throw ParameterError("dataset", "training data does not match the network's input/output widths");
  }
  if (o.steps < 0 || !(o.learning_rate > 0.0f) || !(o.final_learning_rate_fraction > 0.0f) || o.batch < 0) {
    throw ParameterError("training", "steps and batch must be >= 0, the learning rate and its final fraction > 0");
  }
  std::unique_ptr<tbb::global_control> limit;
  if (o.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(o.threads));
  }
  const auto t0 = std::chrono::steady_clock::now();
  TrainResult r{o.initial ? *o.initial : Mlp<float>(shape, o.seed), 0, 0, 0, 0, 0, {}, 0, false, {}, 0.0};
  if (r.net.shape().widths != shape.widths) {
    throw ParameterError("initial", "the initial network's widths differ from the shape to train");
  }
  Adam<float> adam(r.net.num_params(), o.learning_rate);
  std::mt19937_64 rng(o.seed ^ 0x5bd1e995u);
  const long n = train.X.cols();
  const bool mini = o.batch > 0 && o.batch < n;
  std::vector<long> order(static_cast<size_t>(n));
  std::iota(order.begin(), order.end(), 0L);
  long cursor = n; /* forces a shuffle before the first mini-batch */
  std::vector<long> batch(mini ? size_t(o.batch) : 0);
  r.initial_loss = dataset_loss(r.net, train.X, train.Y, o.loss, o.log_eps, nullptr);
  const double decay = o.steps > 1 ? std::log(double(o.final_learning_rate_fraction)) / double(o.steps - 1) : 0.0;
  Mlp<float>::Vec g;
  Mlp<float>::Vec p = r.net.params();
  for (int step = 0; step < o.steps; step++) {
    float loss;
    if (mini) {
      for (int j = 0; j < o.batch; j++) {
        if (cursor == n) {
          std::shuffle(order.begin(), order.end(), rng);
          cursor = 0;
        }
        batch[size_t(j)] = order[size_t(cursor++)];
      }
      loss = dataset_loss(r.net, train.X, train.Y, o.loss, o.log_eps, &g, {0, o.batch, batch.data()});
    }
    else {
      loss = dataset_loss(r.net, train.X, train.Y, o.loss, o.log_eps, &g);
    }
    if (!std::isfinite(loss) || !g.allFinite()) {
      r.diverged = true;
      r.message = "training diverged at step " + std::to_string(step) +
                  " (non-finite loss or gradient); kept the last finite weights — lower the learning rate";
      break;
    }
    adam.set_learning_rate(float(double(o.learning_rate) * std::exp(decay * step)));
    Mlp<float>::Vec next = p;
    adam.step(&next, g);
    if (!next.allFinite()) {
      r.diverged = true;
      r.message = "training diverged at step " + std::to_string(step) + " (non-finite weights); kept the last "
                  "finite weights — lower the learning rate";
      break;
    }
    p = next;
    r.net.set_params(p);
    r.steps_done = step + 1;
    if (o.record_every > 0 && step % o.record_every == 0) {
      r.curve.push_back(loss);
      if (o.progress) {
        o.progress(step, o.steps, loss);
      }
    }
  }
  r.train_loss = dataset_loss(r.net, train.X, train.Y, o.loss, o.log_eps, nullptr);
  r.train_mse = dataset_loss(r.net, train.X, train.Y, Loss::kMse, 0.0f, nullptr);
  if (validation.X.cols() > 0) {
    r.validation_loss = dataset_loss(r.net, validation.X, validation.Y, o.loss, o.log_eps, nullptr);
    r.validation_mse = dataset_loss(r.net, validation.X, validation.Y, Loss::kMse, 0.0f, nullptr);
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace neuralyarn::train
