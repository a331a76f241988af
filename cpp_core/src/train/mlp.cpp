// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/train/mlp.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "neuralyarn/presets.h" /* ParameterError */

namespace neuralyarn::train {

std::vector<int> parse_widths(const std::string &text)
{
  std::vector<int> w;
  size_t pos = 0;
  while (pos <= text.size()) {
    const size_t dash = text.find('-', pos);
    const std::string part = text.substr(pos, dash == std::string::npos ? std::string::npos : dash - pos);
    size_t used = 0;
    int v = 0;
    try {
      v = std::stoi(part, &used);
    }
    catch (const std::exception &) {
      used = 0;
    }
    if (part.empty() || used != part.size()) {
      throw ParameterError("widths", "'" + text + "' is not a list of widths like 6-21-21-3");
    }
    w.push_back(v);
    if (dash == std::string::npos) {
      break;
    }
    pos = dash + 1;
  }
  return w;
}

std::string format_widths(const std::vector<int> &widths)
{
  std::string s;
  for (size_t i = 0; i < widths.size(); i++) {
    s += (i ? "-" : "") + std::to_string(widths[i]);
  }
  return s;
}

namespace {
constexpr double kInitSlope = 0.25;

void validate_shape(const MlpShape &s)
{
  const int L = int(s.widths.size()) - 1;
  if (L < 1 || L > ny::kMlpMaxLayers) {
    throw ParameterError("widths", "an MLP needs 1 to " + std::to_string(ny::kMlpMaxLayers) + " weight layers, got " +
                                       std::to_string(L));
  }
  for (int w : s.widths) {
    if (w < 1 || w > ny::kMlpMaxWidth) {
      throw ParameterError("widths", "MLP widths must be in [1, " + std::to_string(ny::kMlpMaxWidth) + "], got " +
                                         std::to_string(w));
    }
  }
  if (s.head != ny::kMlpHeadIdentity && s.head != ny::kMlpHeadSigmoid && s.head != ny::kMlpHeadExp) {
    throw ParameterError("head", "unknown MLP head " + std::to_string(int(s.head)));
  }
}
}  // namespace

template<class S> Mlp<S>::Mlp(const MlpShape &shape, uint64_t seed) : shape_(shape)
{
  validate_shape(shape);
  std::mt19937_64 rng(seed);
  const int L = int(shape.widths.size()) - 1;
  for (int l = 0; l < L; l++) {
    const int n_in = shape.widths[size_t(l)], n_out = shape.widths[size_t(l) + 1];
    const double slope = shape.activation == Activation::kPrelu ? kInitSlope : 0.0;
    std::normal_distribution<double> normal(0.0, std::sqrt(2.0 / ((1.0 + slope * slope) * n_in)));
    Mat W(n_out, n_in);
    for (int j = 0; j < n_in; j++) {
      for (int i = 0; i < n_out; i++) {
        W(i, j) = S(normal(rng));
      }
    }
    W_.push_back(W);
    b_.push_back(Vec::Zero(n_out));
    if (l < L - 1) {
      a_.push_back(Vec::Constant(n_out, S(slope)));
    }
  }
}

template<class S> Mlp<S> Mlp<S>::from_flat(const std::vector<float> &f)
{
  auto fail = [](const std::string &what) { throw ParameterError("network", "invalid network array: " + what); };
  if (f.size() < 4 || !(f[0] >= 1 && f[0] <= ny::kMlpMaxLayers) || f[0] != std::floor(f[0])) {
    fail("bad layer count");
  }
  const int L = int(f[0]);
  if (f.size() < size_t(L) + 3) {
    fail("truncated header");
  }
  MlpShape shape;
  for (int l = 0; l <= L; l++) {
    const float w = f[size_t(1 + l)];
    if (!(w >= 1 && w <= ny::kMlpMaxWidth) || w != std::floor(w)) {
      fail("bad width at layer " + std::to_string(l));
    }
    shape.widths.push_back(int(w));
  }
  const float head = f[size_t(L) + 2];
  if (!(head == 0.0f || head == 1.0f || head == 2.0f)) {
    fail("bad head");
  }
  shape.head = ny::MlpHead(int(head));
  if (int(f.size()) != ny::mlp_param_count(L, shape.widths.data())) {
    fail("size " + std::to_string(f.size()) + " does not match the shape (" +
         std::to_string(ny::mlp_param_count(L, shape.widths.data())) + ")");
  }
  for (float v : f) {
    if (!std::isfinite(v)) {
      fail("non-finite value");
    }
  }
  /* After the header the array is params() in float: W column-major, b, slopes, layer by layer. */
  Mlp m(shape, 0);
  Vec p(m.num_params());
  for (int i = 0; i < p.size(); i++) {
    p(i) = S(f[size_t(L) + 3 + size_t(i)]);
  }
  m.set_params(p);
  return m;
}

template<class S> std::vector<float> Mlp<S>::to_flat() const
{
  if (shape_.activation == Activation::kElu) {
    throw ParameterError("activation", "the kernel implements PReLU (and ReLU), not ELU");
  }
  std::vector<float> f;
  f.push_back(float(num_layers()));
  for (int w : shape_.widths) {
    f.push_back(float(w));
  }
  f.push_back(float(int(shape_.head)));
  /* params() is already in the kernel's order (W column-major, b, slopes; layer by layer). */
  const Vec p = params();
  for (int i = 0; i < p.size(); i++) {
    f.push_back(float(p(i)));
  }
  return f;
}

namespace {
template<class S> S head_value(int head, S z)
{
  if (head == ny::kMlpHeadSigmoid) {
    return z >= 0 ? S(1) / (S(1) + std::exp(-z)) : std::exp(z) / (S(1) + std::exp(z));
  }
  if (head == ny::kMlpHeadExp) {
    return std::exp(std::min(z, S(ny::kMlpMaxExpArgument)));
  }
  return z;
}
/* d head / dz, given z and y = head(z). */
template<class S> S head_derivative(int head, S z, S y)
{
  if (head == ny::kMlpHeadSigmoid) {
    return y * (S(1) - y);
  }
  if (head == ny::kMlpHeadExp) {
    return z < S(ny::kMlpMaxExpArgument) ? y : S(0);
  }
  return S(1);
}
}  // namespace

template<class S> typename Mlp<S>::Mat Mlp<S>::layer(int l, const Mat &A, Mat *Z) const
{
  /* Whole-matrix expressions (no per-element loops): Eigen vectorises them, which made one training step
   * 2x faster than indexing element by element (docs/benchmarks.md, "Training"). */
  Z->noalias() = W_[size_t(l)] * A;
  Z->colwise() += b_[size_t(l)];
  if (l < num_layers() - 1) {
    if (shape_.activation == Activation::kElu) {
      return Z->unaryExpr([](S z) { return z > 0 ? z : std::expm1(z); });
    }
    /* Channel-wise PReLU: max(z, 0) + a * min(z, 0). */
    const auto zero = S(0);
    return (Z->array().max(zero) + Z->array().min(zero).colwise() * a_[size_t(l)].array()).matrix();
  }
  if (shape_.head == ny::kMlpHeadExp) {
    return Z->array().min(S(ny::kMlpMaxExpArgument)).exp().matrix();
  }
  return Z->unaryExpr([this](S z) { return head_value<S>(int(shape_.head), z); });
}

template<class S> typename Mlp<S>::Mat Mlp<S>::forward(const Mat &X) const
{
  Mat A = X, Z;
  for (int l = 0; l < num_layers(); l++) {
    A = layer(l, A, &Z);
  }
  return A;
}

template<class S> S Mlp<S>::loss_and_gradient(const Mat &X, const Mat &T, Loss loss, S eps, Vec *gradient) const
{
  const int L = num_layers();
  /* Forward, keeping pre-activations Z_l and activations A_l (A_0 = X). */
  std::vector<Mat> Zs, As;
  As.push_back(X);
  for (int l = 0; l < L; l++) {
    Mat Z;
    Mat A = layer(l, As.back(), &Z);
    Zs.push_back(std::move(Z));
    As.push_back(std::move(A));
  }
  const Mat &Y = As.back();
  /* A NaN target is no target: that output of that sample has no loss and no gradient (two-sided M, D45:
   * each sample trains the three outputs of its own hemisphere). The mean runs over the targets there are. */
  const auto has = T.array().isFinite();
  const Mat Tz = has.select(T.array(), S(0)).matrix();
  const S n = std::max(S(1), S(has.count()));
  Mat dY;
  S value;
  if (loss == Loss::kMse) {
    dY = has.select(Y - Tz, S(0)).matrix();
    value = dY.squaredNorm() / n;
    dY *= S(2) / n;
  }
  else if (loss == Loss::kRelativeMse || loss == Loss::kPoissonMse) {
    const Mat w = loss == Loss::kRelativeMse ? Mat((Y.array().square() + eps).inverse().matrix())
                                             : Mat((Y.array() + eps).inverse().matrix());
    dY = has.select(Y - Tz, S(0)).matrix();
    value = (dY.array().square() * w.array()).sum() / n;
    dY = (S(2) / n * dY.array() * w.array()).matrix();
  }
  else {
    const auto Ye = Y.array() + eps;
    const Mat r = has.select(Ye.log() - (Tz.array() + eps).log(), S(0)).matrix();
    value = r.squaredNorm() / n;
    dY = (S(2) / n * r.array() / Ye).matrix();
  }
  if (!gradient) {
    return value;
  }

  /* Backward. */
  std::vector<Mat> dW(static_cast<size_t>(L));
  std::vector<Vec> db(static_cast<size_t>(L)), da(a_.size());
  Mat dZ;
  if (shape_.head == ny::kMlpHeadExp) {
    /* d exp(min(z, zmax)) / dz = y below the clamp, 0 above. */
    dZ = (Zs.back().array() < S(ny::kMlpMaxExpArgument)).select(dY.array() * Y.array(), S(0)).matrix();
  }
  else if (shape_.head == ny::kMlpHeadSigmoid) {
    dZ = (dY.array() * Y.array() * (S(1) - Y.array())).matrix();
  }
  else {
    dZ = dY;
  }
  for (int l = L - 1; l >= 0; l--) {
    dW[size_t(l)].noalias() = dZ * As[size_t(l)].transpose();
    db[size_t(l)] = dZ.rowwise().sum();
    if (l == 0) {
      break;
    }
    Mat dA;
    dA.noalias() = W_[size_t(l)].transpose() * dZ;
    const Mat &Zp = Zs[size_t(l) - 1];
    const Vec &a = a_[size_t(l) - 1];
    if (shape_.activation == Activation::kElu) {
      dZ = (Zp.array() > S(0)).select(dA.array(), dA.array() * Zp.array().exp()).matrix();
      da[size_t(l) - 1] = Vec::Zero(a.size());
    }
    else {
      /* dL/da_i = sum over the batch of dA * min(z, 0); ReLU's slopes are the constant 0: no gradient. */
      da[size_t(l) - 1] = shape_.activation == Activation::kPrelu
                              ? Vec((dA.array() * Zp.array().min(S(0))).rowwise().sum().matrix())
                              : Vec::Zero(a.size());
      dZ = (Zp.array() < S(0)).select(dA.array().colwise() * a.array(), dA.array()).matrix();
    }
  }
  gradient->resize(num_params());
  int k = 0;
  for (int l = 0; l < L; l++) {
    const Mat &g = dW[size_t(l)];
    for (int j = 0; j < g.cols(); j++) {
      for (int i = 0; i < g.rows(); i++) {
        (*gradient)(k++) = g(i, j);
      }
    }
    for (int i = 0; i < db[size_t(l)].size(); i++) {
      (*gradient)(k++) = db[size_t(l)](i);
    }
    if (l < L - 1) {
      for (int i = 0; i < da[size_t(l)].size(); i++) {
        (*gradient)(k++) = da[size_t(l)](i);
      }
    }
  }
  return value;
}

template<class S> int Mlp<S>::num_params() const
{
  int n = 0;
  for (int l = 0; l < num_layers(); l++) {
    n += int(W_[size_t(l)].size() + b_[size_t(l)].size());
    if (l < num_layers() - 1) {
      n += int(a_[size_t(l)].size());
    }
  }
  return n;
}

template<class S> typename Mlp<S>::Vec Mlp<S>::params() const
{
  Vec p(num_params());
  int k = 0;
  for (int l = 0; l < num_layers(); l++) {
    const Mat &W = W_[size_t(l)];
    for (int j = 0; j < W.cols(); j++) {
      for (int i = 0; i < W.rows(); i++) {
        p(k++) = W(i, j);
      }
    }
    for (int i = 0; i < b_[size_t(l)].size(); i++) {
      p(k++) = b_[size_t(l)](i);
    }
    if (l < num_layers() - 1) {
      for (int i = 0; i < a_[size_t(l)].size(); i++) {
        p(k++) = a_[size_t(l)](i);
      }
    }
  }
  return p;
}

template<class S> void Mlp<S>::set_params(const Vec &p)
{
  int k = 0;
  for (int l = 0; l < num_layers(); l++) {
    Mat &W = W_[size_t(l)];
    for (int j = 0; j < W.cols(); j++) {
      for (int i = 0; i < W.rows(); i++) {
        W(i, j) = p(k++);
      }
    }
    for (int i = 0; i < b_[size_t(l)].size(); i++) {
      b_[size_t(l)](i) = p(k++);
    }
    if (l < num_layers() - 1) {
      for (int i = 0; i < a_[size_t(l)].size(); i++) {
        a_[size_t(l)](i) = p(k++);
      }
    }
  }
}

template<class S>
Adam<S>::Adam(int n, S learning_rate, S beta1, S beta2, S epsilon)
    : m_(Vec::Zero(n)), v_(Vec::Zero(n)), lr_(learning_rate), b1_(beta1), b2_(beta2), eps_(epsilon)
{
}

template<class S> void Adam<S>::step(Vec *params, const Vec &g)
{
  t_++;
  m_ = b1_ * m_ + (S(1) - b1_) * g;
  v_ = b2_ * v_ + (S(1) - b2_) * g.cwiseProduct(g);
  const S c1 = S(1) - std::pow(b1_, S(t_)), c2 = S(1) - std::pow(b2_, S(t_));
  for (int i = 0; i < params->size(); i++) {
    (*params)(i) -= lr_ * (m_(i) / c1) / (std::sqrt(v_(i) / c2) + eps_);
  }
}

template class Mlp<float>;
template class Mlp<double>;
template class Adam<float>;
template class Adam<double>;

}  // namespace neuralyarn::train
