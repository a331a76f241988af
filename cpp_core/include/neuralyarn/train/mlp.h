// SPDX-License-Identifier: Apache-2.0
//
// Training-side MLP: the same networks as kernel/mlp.h (channel-wise PReLU hidden layers, identity /
// sigmoid / exp head), run over a batch a few columns at a time through every layer (forward and exact
// backpropagation fused, no temporaries), and Adam. `to_flat()` writes the kernel's array layout, so what
// is trained is bit-for-bit what renders.
//
// Scalar is float for training and double for the finite-difference gradient tests.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "neuralyarn/kernel/mlp.h"

namespace neuralyarn::train {

/* Hidden-layer activation. Only PReLU (and ReLU, its slope-0 case) exist in the kernel; ELU and ReLU are
 * here for the paper's ablation (docs/benchmarks.md). */
enum class Activation { kPrelu, kRelu, kElu };

struct MlpShape {
  std::vector<int> widths; /* w_0 (inputs) .. w_L (outputs) */
  ny::MlpHead head = ny::kMlpHeadIdentity;
  Activation activation = Activation::kPrelu;
};

/* "6-21-21-3" -> {6, 21, 21, 3}; ParameterError on anything else. */
std::vector<int> parse_widths(const std::string &text);
std::string format_widths(const std::vector<int> &widths);

enum class Loss {
  kMse,    /* mean of (y - t)^2 over all outputs (the paper's) */
  kLogMse, /* mean of (log(y + eps) - log(t + eps))^2: relative errors, for targets spanning decades */
  /* mean of (y - t)^2 / (sg(y)^2 + eps), sg = no gradient through it: relative errors like the log loss,
   * but unbiased for noisy targets (the weight depends on the prediction, not on the target), so sparse
   * Monte Carlo bins do not pull the fit down (Mueller et al. 2021, neural radiance caching). */
  kRelativeMse,
  /* mean of (y - t)^2 / (sg(y) + eps): least squares weighted by 1 / variance for Monte Carlo bins whose
   * variance grows with their mean (sparse path counts), between the MSE (weight 1) and the relative MSE
   * (weight 1 / y^2); unbiased for noisy targets like the relative MSE. With the exp head its gradient in
   * the pre-activation is y - t, the Poisson deviance's. */
  kPoissonMse,
};

template<class S> class Mlp {
 public:
  using Mat = Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic>;
  using Vec = Eigen::Matrix<S, Eigen::Dynamic, 1>;

  /* He-initialised weights for PReLU slope 0.25 (PyTorch's default), zero biases, slopes 0.25 (ReLU and
   * ELU: no slopes; ReLU exports as PReLU with slopes 0). Throws
   * ParameterError for widths outside [1, kMlpMaxWidth] or more than kMlpMaxLayers layers. */
  Mlp(const MlpShape &shape, uint64_t seed);

  /* From / to the kernel's flat array (kernel/mlp.h). from_flat validates the header and the size;
   * to_flat throws ParameterError for ELU, which the kernel does not implement. */
  static Mlp from_flat(const std::vector<float> &flat);
  std::vector<float> to_flat() const;

  const MlpShape &shape() const { return shape_; }
  int num_layers() const { return int(W_.size()); }

  /* Y = f(X) for a batch: X is w_0 x B, Y is w_L x B. */
  Mat forward(const Mat &X) const;

  /* Loss of the batch against targets T (w_L x B) and its gradient with respect to every parameter,
   * in the order of params(). `eps` is the log loss's offset. A NaN target is none: that output of that
   * column adds no loss and no gradient, and the mean runs over the finite targets. */
  S loss_and_gradient(const Mat &X, const Mat &T, Loss loss, S eps, Vec *gradient) const;

  /* The columns of X and T a loss runs over, read in place: `count` of them from `begin` (all: count < 0),
   * or with `index` the columns index[begin .. begin + count) (a mini-batch). */
  struct Columns {
    long begin = 0, count = -1;
    const long *index = nullptr;
  };
  S loss_and_gradient(const Mat &X, const Mat &T, const Columns &columns, Loss loss, S eps, Vec *gradient) const;

  /* All parameters as one vector (W_0, b_0, a_0, W_1, ...; W column-major) and back. */
  Vec params() const;
  void set_params(const Vec &p);
  int num_params() const;

 private:
  /* The network over `columns` of X: the outputs into *Y (if not null); with targets T, the loss, and its
   * gradient into *gradient (if not null). */
  S pass(const Mat &X, const Mat *T, const Columns &columns, Loss loss, S eps, Vec *gradient, Mat *Y) const;

  MlpShape shape_;
  std::vector<Mat> W_; /* w_{l+1} x w_l */
  std::vector<Vec> b_; /* w_{l+1}       */
  std::vector<Vec> a_; /* w_{l+1}, hidden layers only */
};

/* Adam (Kingma & Ba 2015) with bias correction. */
template<class S> class Adam {
 public:
  using Vec = typename Mlp<S>::Vec;
  Adam(int n, S learning_rate, S beta1 = S(0.9), S beta2 = S(0.999), S epsilon = S(1e-8));
  void step(Vec *params, const Vec &gradient);
  void set_learning_rate(S lr) { lr_ = lr; }

 private:
  Vec m_, v_;
  S lr_, b1_, b2_, eps_;
  long t_ = 0;
};

extern template class Mlp<float>;
extern template class Mlp<double>;
extern template class Adam<float>;
extern template class Adam<double>;

}  // namespace neuralyarn::train
