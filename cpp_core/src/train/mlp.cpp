// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/train/mlp.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <type_traits>
#include <string>

#include "neuralyarn/kernel/platform.h" /* NY_SIMD_LOOP */
#include "neuralyarn/presets.h"         /* ParameterError */

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
/* Columns a pass carries through the network together (one AVX-512 register of floats, two AVX2 ones; 8 and
 * 32 were slower): every layer of a tile is computed before the next tile starts, so its activations and the
 * gradient's lane-wise sums stay in the first-level cache. Fixed, so the order of every sum is the same on
 * every machine and at every thread count (docs/decisions.md D46). */
constexpr int kLanes = 16;
template<class S> using Lanes = Eigen::Array<S, kLanes, 1>;
template<class S> using LanesAt = Eigen::Map<Lanes<S>>;
template<class S> using LanesOf = Eigen::Map<const Lanes<S>>;

/* y_r = init_r + sum_k M(r, k) x_k for r < R, each x_k and y_r kLanes wide, M(r, k) = m[r rs + k ks], summed
 * over k in order (the kernel's order for the forward pass); init null: 0. Four rows at a time, so four
 * independent sums are in flight instead of one waiting on the last addition. */
template<class S>
void lanes_matvec(int R, int K, const S *m, long rs, long ks, const S *init, const S *x, S *y)
{
  int r = 0;
  for (; r + 4 <= R; r += 4) {
    Lanes<S> y0 = Lanes<S>::Constant(init ? init[r] : S(0)), y1 = Lanes<S>::Constant(init ? init[r + 1] : S(0)),
             y2 = Lanes<S>::Constant(init ? init[r + 2] : S(0)), y3 = Lanes<S>::Constant(init ? init[r + 3] : S(0));
    const S *mr = m + r * rs;
    for (int k = 0; k < K; k++) {
      const LanesOf<S> xk(x + k * kLanes);
      const S *mk = mr + k * ks;
      y0 += mk[0] * xk;
      y1 += mk[rs] * xk;
      y2 += mk[2 * rs] * xk;
      y3 += mk[3 * rs] * xk;
    }
    LanesAt<S>(y + r * kLanes) = y0;
    LanesAt<S>(y + (r + 1) * kLanes) = y1;
    LanesAt<S>(y + (r + 2) * kLanes) = y2;
    LanesAt<S>(y + (r + 3) * kLanes) = y3;
  }
  for (; r < R; r++) {
    Lanes<S> yr = Lanes<S>::Constant(init ? init[r] : S(0));
    for (int k = 0; k < K; k++) {
      yr += m[r * rs + k * ks] * LanesOf<S>(x + k * kLanes);
    }
    LanesAt<S>(y + r * kLanes) = yr;
  }
}

template<class S> S head_value(int head, S z)
{
  if constexpr (std::is_same_v<S, float>) {
    return ny::mlp_apply_head(head, z); /* the kernel's head (its fast_exp): what is trained is what renders */
  }
  if (head == ny::kMlpHeadSigmoid) {
    return z >= 0 ? S(1) / (S(1) + std::exp(-z)) : std::exp(z) / (S(1) + std::exp(z));
  }
  if (head == ny::kMlpHeadExp) {
    return std::exp(std::min(z, S(ny::kMlpMaxExpArgument)));
  }
  return z;
}

/* head_value on a block of lanes; the float exp head (M's outputs) in a loop that vectorises. */
template<class S> void head_lanes(int head, const S *z, S *out)
{
  if constexpr (std::is_same_v<S, float>) {
    if (head == ny::kMlpHeadExp) {
      NY_SIMD_LOOP
      for (int t = 0; t < kLanes; t++) {
        out[t] = ny::mlp_exp_head(z[t]);
      }
      return;
    }
  }
  for (int t = 0; t < kLanes; t++) {
    out[t] = head_value<S>(head, z[t]);
  }
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

template<class S> typename Mlp<S>::Mat Mlp<S>::forward(const Mat &X) const
{
  Mat Y(shape_.widths.back(), X.cols());
  pass(X, nullptr, Columns{0, X.cols()}, Loss::kMse, S(0), nullptr, &Y);
  return Y;
}

template<class S> S Mlp<S>::loss_and_gradient(const Mat &X, const Mat &T, Loss loss, S eps, Vec *gradient) const
{
  return pass(X, &T, Columns{0, X.cols()}, loss, eps, gradient, nullptr);
}

template<class S>
S Mlp<S>::loss_and_gradient(const Mat &X, const Mat &T, const Columns &columns, Loss loss, S eps,
                            Vec *gradient) const
{
  return pass(X, &T, columns, loss, eps, gradient, nullptr);
}

template<class S>
S Mlp<S>::pass(const Mat &X, const Mat *T, const Columns &columns, Loss loss, S eps, Vec *gradient, Mat *Y) const
{
  const int L = num_layers();
  const std::vector<int> &w = shape_.widths;
  const long count = columns.count < 0 ? X.cols() - columns.begin : columns.count;
  auto column = [&](long k) { return columns.index ? columns.index[columns.begin + k] : columns.begin + k; };

  /* One tile's buffers, [unit][lane]: the activations A_0 (the inputs) .. A_L (the outputs), the
   * pre-activations Z_0 .. Z_{L-1}, and two of the widest layer for dL/dZ going backward. */
  std::vector<size_t> at_A(size_t(L) + 1), at_Z(static_cast<size_t>(L));
  size_t size = 0;
  int widest = 0;
  for (int l = 0; l <= L; l++) {
    at_A[size_t(l)] = size;
    size += size_t(w[size_t(l)]) * kLanes;
    widest = std::max(widest, w[size_t(l)]);
  }
  for (int l = 0; l < L; l++) {
    at_Z[size_t(l)] = size;
    size += size_t(w[size_t(l) + 1]) * kLanes;
  }
  std::vector<S> buffer(size + 2 * size_t(widest) * kLanes);
  S *const dZ0 = buffer.data() + size, *const dZ1 = dZ0 + size_t(widest) * kLanes;
  /* The gradient, lane by lane, in the order of params(); where layer l's parameters start in it. */
  std::vector<S> acc(gradient ? size_t(num_params()) * kLanes : 0, S(0));
  std::vector<size_t> at_W(static_cast<size_t>(L));
  for (int l = 0, k = 0; l < L; l++) {
    at_W[size_t(l)] = size_t(k) * kLanes;
    k += w[size_t(l) + 1] * (w[size_t(l)] + 1) + (l < L - 1 ? w[size_t(l) + 1] : 0);
  }

  /* A NaN target is no target: that output of that sample has no loss and no gradient (two-sided M, D45:
   * each sample trains the three outputs of its own hemisphere). The mean runs over the targets there are,
   * counted on the way: the sums are divided by their number at the end. */
  long finite = 0;
  const int head = int(shape_.head);
  S value = S(0);
  for (long t0 = 0; t0 < count; t0 += kLanes) {
    const int m = int(std::min<long>(kLanes, count - t0)); /* lanes past m compute zeros and carry no loss */
    /* A mini-batch's columns are scattered over the dataset: ask for the next tile's while this one runs
     * (a copy of each epoch in its shuffled order instead cost more than the waiting). */
    for (long k = t0 + kLanes; columns.index && k < std::min(count, t0 + 2 * kLanes); k++) {
      __builtin_prefetch(X.data() + column(k) * X.rows());
      if (T) {
        __builtin_prefetch(T->data() + column(k) * T->rows());
      }
    }
    S *A0 = buffer.data() + at_A[0];
    for (int t = 0; t < kLanes; t++) {
      const long c = t < m ? column(t0 + t) : -1;
      for (int j = 0; j < w[0]; j++) {
        A0[j * kLanes + t] = c >= 0 ? X(j, c) : S(0);
      }
    }
    /* Forward: z = b + sum_j W_ij a_j, summed over the inputs in order (kernel/mlp.h's order); PReLU, ELU
     * or the head. */
    for (int l = 0; l < L; l++) {
      const int n_in = w[size_t(l)], n_out = w[size_t(l) + 1];
      const bool hidden = l < L - 1;
      const S *A = buffer.data() + at_A[size_t(l)];
      S *Z = buffer.data() + at_Z[size_t(l)], *An = buffer.data() + at_A[size_t(l) + 1];
      lanes_matvec<S>(n_out, n_in, W_[size_t(l)].data(), 1, n_out, b_[size_t(l)].data(), A, Z);
      for (int i = 0; i < n_out; i++) {
        const S *z = Z + i * kLanes;
        S *out = An + i * kLanes;
        if (!hidden) {
          head_lanes<S>(head, z, out);
        }
        else if (shape_.activation == Activation::kElu) {
          for (int t = 0; t < kLanes; t++) {
            out[t] = z[t] > S(0) ? z[t] : std::expm1(z[t]);
          }
        }
        else {
          /* Channel-wise PReLU (ReLU: its slopes are the constant 0). */
          const S slope = a_[size_t(l)](i);
          NY_SIMD_LOOP
          for (int t = 0; t < kLanes; t++) {
            out[t] = z[t] < S(0) ? slope * z[t] : z[t];
          }
        }
      }
    }
    const S *Yt = buffer.data() + at_A[size_t(L)];
    if (Y) {
      for (int t = 0; t < m; t++) {
        for (int r = 0; r < w.back(); r++) {
          (*Y)(r, t0 + t) = Yt[r * kLanes + t];
        }
      }
    }
    if (!T) {
      continue;
    }

    /* The loss and dL/dY, then dL/dZ of the output layer through the head. */
    S *dZ = dZ0;
    const S *ZL = buffer.data() + at_Z[size_t(L) - 1];
    for (int r = 0; r < w.back(); r++) {
      for (int t = 0; t < kLanes; t++) {
        S d = S(0);
        const S target = t < m ? (*T)(r, column(t0 + t)) : S(NAN);
        if (std::isfinite(target)) {
          const S y = Yt[r * kLanes + t];
          if (loss == Loss::kLogMse) {
            const S res = std::log(y + eps) - std::log(target + eps);
            value += res * res;
            d = S(2) * res / (y + eps);
          }
          else {
            const S weight = loss == Loss::kRelativeMse ? S(1) / (y * y + eps)
                             : loss == Loss::kPoissonMse ? S(1) / (y + eps)
                                                         : S(1);
            const S e = y - target;
            value += e * e * weight;
            d = S(2) * e * weight;
          }
          finite++;
          d *= head_derivative<S>(head, ZL[r * kLanes + t], y);
        }
        dZ[r * kLanes + t] = d;
      }
    }
    if (!gradient) {
      continue;
    }

    /* Backward, adding each parameter's gradient into its lanes. */
    S *dA = dZ1;
    for (int l = L - 1; l >= 0; l--) {
      const int n_in = w[size_t(l)], n_out = w[size_t(l) + 1];
      const S *A = buffer.data() + at_A[size_t(l)];
      S *gW = acc.data() + at_W[size_t(l)], *gb = gW + size_t(n_out) * n_in * kLanes;
      for (int j = 0; j < n_in; j++) {
        const Lanes<S> a = LanesOf<S>(A + j * kLanes);
        for (int i = 0; i < n_out; i++) {
          LanesAt<S>(gW + (size_t(j) * n_out + i) * kLanes) += LanesOf<S>(dZ + i * kLanes) * a;
        }
      }
      for (int i = 0; i < n_out; i++) {
        LanesAt<S>(gb + size_t(i) * kLanes) += LanesOf<S>(dZ + i * kLanes);
      }
      if (l == 0) {
        break;
      }
      /* dL/dA_l = W^T dL/dZ_l, then through layer l - 1's activation. */
      const S *W = W_[size_t(l)].data();
      const S *Zp = buffer.data() + at_Z[size_t(l) - 1];
      S *ga = acc.data() + at_W[size_t(l) - 1] + size_t(n_in) * (w[size_t(l) - 1] + 1) * kLanes;
      lanes_matvec<S>(n_in, n_out, W, n_out, 1, nullptr, dZ, dA);
      for (int j = 0; j < n_in; j++) {
        const S *zp = Zp + j * kLanes;
        S *d = dA + j * kLanes;
        if (shape_.activation == Activation::kElu) {
          for (int t = 0; t < kLanes; t++) {
            d[t] = zp[t] > S(0) ? d[t] : d[t] * std::exp(zp[t]);
          }
          continue;
        }
        /* dL/da_j = sum over the batch of dL/dA * min(z, 0); ReLU's slopes are the constant 0: no gradient. */
        if (shape_.activation == Activation::kPrelu) {
          S *g = ga + size_t(j) * kLanes;
          NY_SIMD_LOOP
          for (int t = 0; t < kLanes; t++) {
            g[t] += d[t] * std::min(zp[t], S(0));
          }
        }
        const S slope = a_[size_t(l) - 1](j);
        NY_SIMD_LOOP
        for (int t = 0; t < kLanes; t++) {
          d[t] = zp[t] < S(0) ? slope * d[t] : d[t];
        }
      }
      std::swap(dZ, dA);
    }
  }
  const S n = std::max(S(1), S(finite));
  if (gradient) {
    gradient->resize(num_params());
    for (int k = 0; k < num_params(); k++) {
      S g = S(0);
      for (int t = 0; t < kLanes; t++) {
        g += acc[size_t(k) * kLanes + size_t(t)];
      }
      (*gradient)(k) = g / n;
    }
  }
  return value / n;
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
