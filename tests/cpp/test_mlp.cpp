// SPDX-License-Identifier: Apache-2.0
//
// The MLP used for T and M: exact gradients (against central finite differences in double), kernel
// inference equal to the trainer's forward pass, the flat array's validation, and that Adam trains.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>

#include "neuralyarn/kernel/mlp.h"
#include "neuralyarn/model/mlp_lanes.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/train/mlp.h"

using namespace neuralyarn;
using train::Loss;
using train::Mlp;
using train::MlpShape;

namespace {

template<class S> typename Mlp<S>::Mat random_matrix(int rows, int cols, std::mt19937_64 &rng, double lo, double hi)
{
  std::uniform_real_distribution<double> U(lo, hi);
  typename Mlp<S>::Mat m(rows, cols);
  for (int j = 0; j < cols; j++) {
    for (int i = 0; i < rows; i++) {
      m(i, j) = S(U(rng));
    }
  }
  return m;
}

/* The He initialisation perturbed everywhere (biases and slopes too), so that both PReLU branches and
 * non-trivial slopes are exercised while outputs stay in a trained network's range. */
template<class S> void randomize(Mlp<S> &m, std::mt19937_64 &rng)
{
  typename Mlp<S>::Vec p = m.params();
  std::normal_distribution<double> N(0.0, 0.3);
  for (int i = 0; i < p.size(); i++) {
    p(i) += S(N(rng));
  }
  m.set_params(p);
}

struct ShapeCase {
  std::vector<int> widths;
  ny::MlpHead head;
};

const ShapeCase kShapes[] = {
    {{3, 7, 7, 1}, ny::kMlpHeadSigmoid},   /* the paper's T network */
    {{6, 21, 21, 3}, ny::kMlpHeadExp},     /* the paper's M network */
    {{6, 21, 21, 21, 3}, ny::kMlpHeadExp}, /* the authors' M network */
    {{2, 5, 4}, ny::kMlpHeadIdentity},
};

}  // namespace

/* (The relative and Poisson losses hold their weights out of the gradient, so central differences of their
 * value are not their gradient: WeightedLossesWeighTheirErrorsAsDocumented checks those. ReLU is PReLU whose
 * slopes are constants, not parameters: their gradient is 0 by definition.) */
TEST(Mlp, GradientMatchesCentralDifferences)
{
  std::mt19937_64 rng(3);
  for (const ShapeCase &sc : kShapes) {
    for (train::Activation act : {train::Activation::kPrelu, train::Activation::kElu}) {
    for (Loss loss : {Loss::kMse, Loss::kLogMse}) {
      Mlp<double> m(MlpShape{sc.widths, sc.head, act}, 11);
      randomize(m, rng);
      /* Not a multiple of the trainer's tile of columns: full tiles and a part-filled one, whose unused
       * columns must add nothing. */
      const int B = 37;
      const auto X = random_matrix<double>(sc.widths.front(), B, rng, -1.5, 1.5);
      const auto T = random_matrix<double>(sc.widths.back(), B, rng, 0.05, 0.95);
      Mlp<double>::Vec g;
      m.loss_and_gradient(X, T, loss, 1e-3, &g);
      const Mlp<double>::Vec p0 = m.params();
      ASSERT_EQ(g.size(), p0.size());
      double worst = 0.0;
      const double g_max = g.cwiseAbs().maxCoeff();
      for (int k = 0; k < p0.size(); k++) {
        const double h = 1e-6 * std::max(1.0, std::abs(p0(k)));
        Mlp<double>::Vec p = p0;
        p(k) += h;
        m.set_params(p);
        const double up = m.loss_and_gradient(X, T, loss, 1e-3, nullptr);
        p(k) -= 2 * h;
        m.set_params(p);
        const double down = m.loss_and_gradient(X, T, loss, 1e-3, nullptr);
        m.set_params(p0);
        const double fd = (up - down) / (2 * h);
        /* Central differences are O(h^2) ~ 1e-12 accurate; cancellation adds ~1e-16 / h ~ 1e-10 of the
         * loss (~1e-9 absolute here), hence the floor of 1e-4 of the largest gradient component. */
        const double err = std::abs(fd - g(k)) / (std::abs(fd) + std::abs(g(k)) + 1e-4 * g_max);
        if (err > worst && std::getenv("NY_TEST_DEBUG")) {
          std::printf("k %d fd %.10g g %.10g gmax %.3g\n", k, fd, g(k), g_max);
        }
        worst = std::max(worst, err);
      }
      EXPECT_LT(worst, 1e-5) << "widths " << sc.widths.size() << " activation " << int(act) << " loss " << int(loss);
    }
    }
  }
}

/* A mini-batch read in place (its columns listed, or a range) is the same batch gathered into matrices of its
 * own: the same loss and gradient to the bit. */
TEST(Mlp, AMiniBatchReadInPlaceIsTheGatheredBatch)
{
  std::mt19937_64 rng(8);
  Mlp<float> m(MlpShape{{6, 21, 21, 3}, ny::kMlpHeadExp}, 3);
  randomize(m, rng);
  const auto X = random_matrix<float>(6, 200, rng, -1.5, 1.5);
  const auto T = random_matrix<float>(3, 200, rng, 0.05, 2.0);
  std::vector<long> index(45);
  for (long &k : index) {
    k = long(rng() % 200);
  }
  Mlp<float>::Mat Xg(6, 40), Tg(3, 40);
  for (int j = 0; j < 40; j++) {
    Xg.col(j) = X.col(index[size_t(j) + 5]);
    Tg.col(j) = T.col(index[size_t(j) + 5]);
  }
  for (Loss loss : {Loss::kMse, Loss::kLogMse, Loss::kRelativeMse, Loss::kPoissonMse}) {
    Mlp<float>::Vec g_listed, g_gathered, g_range, g_copy;
    EXPECT_EQ(m.loss_and_gradient(X, T, Mlp<float>::Columns{5, 40, index.data()}, loss, 1e-3f, &g_listed),
              m.loss_and_gradient(Xg, Tg, loss, 1e-3f, &g_gathered));
    EXPECT_EQ(g_listed, g_gathered);
    const Mlp<float>::Mat Xr = X.middleCols(17, 53), Tr = T.middleCols(17, 53);
    EXPECT_EQ(m.loss_and_gradient(X, T, Mlp<float>::Columns{17, 53}, loss, 1e-3f, &g_range),
              m.loss_and_gradient(Xr, Tr, loss, 1e-3f, &g_copy));
    EXPECT_EQ(g_range, g_copy);
  }
}

TEST(Mlp, KernelInferenceEqualsTrainerForward)
{
  std::mt19937_64 rng(5);
  for (const ShapeCase &sc : kShapes) {
    Mlp<float> m(MlpShape{sc.widths, sc.head}, 7);
    randomize(m, rng);
    const std::vector<float> flat = m.to_flat();
    EXPECT_EQ(int(flat.size()), ny::mlp_param_count(int(sc.widths.size()) - 1, sc.widths.data()));
    const auto X = random_matrix<float>(sc.widths.front(), 1000, rng, -2.0, 2.0);
    const auto Y = m.forward(X);
    for (int j = 0; j < X.cols(); j++) {
      float in[ny::kMlpMaxWidth], out[ny::kMlpMaxWidth];
      for (int i = 0; i < X.rows(); i++) {
        in[i] = X(i, j);
      }
      ny::mlp_forward(flat.data(), in, out);
      for (int i = 0; i < Y.rows(); i++) {
        /* The same float operations in the same order (each sum over the inputs in order): what is trained
         * is what renders, to the bit. */
        ASSERT_EQ(out[i], Y(i, j)) << "sample " << j;
      }
    }
  }
}

/* mlp_forward_io() runs the trainer's shapes with compile-time widths; that path must give exactly what the
 * generic loop gives (same operations in the same order), on every shape it takes and on inputs that reach
 * both PReLU branches and the heads' extremes, and a shape it does not take must still go through. */
TEST(Mlp, SizedShapesAreBitIdenticalToTheGenericLoop)
{
  const ShapeCase cases[] = {
      {{3, 7, 7, 1}, ny::kMlpHeadSigmoid}, {{3, 7, 7, 1}, ny::kMlpHeadExp}, {{6, 21, 21, 3}, ny::kMlpHeadExp},
      {{6, 32, 32, 3}, ny::kMlpHeadExp},   {{6, 20, 20, 3}, ny::kMlpHeadExp}, {{6, 21, 21, 21, 3}, ny::kMlpHeadExp},
      {{6, 21, 21, 6}, ny::kMlpHeadExp},   {{6, 32, 32, 6}, ny::kMlpHeadExp}, {{6, 20, 20, 6}, ny::kMlpHeadExp},
  };
  std::mt19937_64 rng(11);
  for (const ShapeCase &sc : cases) {
    Mlp<float> m(MlpShape{sc.widths, sc.head}, 3);
    randomize(m, rng);
    const std::vector<float> flat = m.to_flat();
    const auto X = random_matrix<float>(sc.widths.front(), 4000, rng, -8.0, 8.0);
    int differ_from_zero = 0;
    for (int j = 0; j < X.cols(); j++) {
      float in[ny::kMlpMaxWidth], a[ny::kMlpMaxWidth], b[ny::kMlpMaxWidth];
      for (int i = 0; i < X.rows(); i++) {
        in[i] = X(i, j);
      }
      if (sc.widths.front() == 3) {
        ny::mlp_forward_io<3, 1>(flat.data(), in, a);
      }
      else if (sc.widths.back() == 6) {
        ny::mlp_forward_io<6, 6>(flat.data(), in, a);
      }
      else {
        ny::mlp_forward_io<6, 3>(flat.data(), in, a);
      }
      ny::mlp_forward(flat.data(), in, b);
      for (int i = 0; i < sc.widths.back(); i++) {
        ASSERT_EQ(std::memcmp(&a[i], &b[i], sizeof(float)), 0)
            << "shape " << sc.widths[1] << " sample " << j << ": " << a[i] << " vs " << b[i];
        differ_from_zero += a[i] != 0.0f;
      }
    }
    EXPECT_GT(differ_from_zero, 1000);
  }
}

/* The host's quadratures run L inputs at once (model/mlp_lanes.h): each lane must be exactly what
 * mlp_forward_io gives for its input alone, on the shapes vectorised over lanes and on one that is not; and so
 * when the M network's first three inputs (w_i in a quadrature over exits) are shared by every lane and added to
 * the first layer's bias once. */
TEST(Mlp, LanesAreBitIdenticalToOneInputAtATime)
{
  const ShapeCase cases[] = {
      {{3, 7, 7, 1}, ny::kMlpHeadSigmoid}, {{6, 21, 21, 3}, ny::kMlpHeadExp}, {{6, 32, 32, 3}, ny::kMlpHeadExp},
      {{6, 20, 20, 3}, ny::kMlpHeadExp},   {{6, 21, 21, 6}, ny::kMlpHeadExp}, {{6, 32, 32, 6}, ny::kMlpHeadExp},
  };
  constexpr int L = 16;
  std::mt19937_64 rng(12);
  for (const ShapeCase &sc : cases) {
    Mlp<float> m(MlpShape{sc.widths, sc.head}, 3);
    randomize(m, rng);
    const std::vector<float> flat = m.to_flat();
    const int I = sc.widths.front(), O = sc.widths.back();
    for (const int S : {0, 3}) {
      if (S > 0 && I != 6) {
        continue;
      }
      auto X = random_matrix<float>(I, 50 * L, rng, -8.0, 8.0);
      for (int j = 0; j < X.cols(); j++) {
        for (int i = 0; i < S; i++) {
          X(i, j) = X(i, j - j % L); /* the same on every lane of a block */
        }
      }
      int nonzero = 0;
      for (int j0 = 0; j0 < X.cols(); j0 += L) {
        const float shared[3] = {X(0, j0), X(1, j0), X(2, j0)};
        float in[6 * L], out[6 * L];
        for (int i = S; i < I; i++) {
          for (int l = 0; l < L; l++) {
            in[(i - S) * L + l] = X(i, j0 + l);
          }
        }
        if (I == 3) {
          model::mlp_forward_io_lanes<3, 1, L>(flat.data(), in, out);
        }
        else if (S == 3 && O == 6) {
          model::mlp_forward_io_lanes<6, 6, L, 3>(flat.data(), shared, in, out);
        }
        else if (S == 3) {
          model::mlp_forward_io_lanes<6, 3, L, 3>(flat.data(), shared, in, out);
        }
        else if (O == 6) {
          model::mlp_forward_io_lanes<6, 6, L>(flat.data(), in, out);
        }
        else {
          model::mlp_forward_io_lanes<6, 3, L>(flat.data(), in, out);
        }
        for (int l = 0; l < L; l++) {
          float x[6], y[6];
          for (int i = 0; i < I; i++) {
            x[i] = X(i, j0 + l);
          }
          if (I == 3) {
            ny::mlp_forward_io<3, 1>(flat.data(), x, y);
          }
          else if (O == 6) {
            ny::mlp_forward_io<6, 6>(flat.data(), x, y);
          }
          else {
            ny::mlp_forward_io<6, 3>(flat.data(), x, y);
          }
          for (int o = 0; o < O; o++) {
            ASSERT_EQ(std::memcmp(&out[o * L + l], &y[o], sizeof(float)), 0)
                << "shape " << sc.widths[1] << ", " << S << " shared inputs, input " << j0 + l << ": "
                << out[o * L + l] << " vs " << y[o];
            nonzero += y[o] != 0.0f;
          }
        }
      }
      EXPECT_GT(nonzero, 500);
    }
  }
}

TEST(Mlp, FlatArrayRoundTripsAndIsValidated)
{
  Mlp<float> m(MlpShape{{6, 21, 21, 3}, ny::kMlpHeadExp}, 9);
  const std::vector<float> flat = m.to_flat();
  EXPECT_EQ(Mlp<float>::from_flat(flat).to_flat(), flat);
  std::vector<float> bad = flat;
  bad.pop_back();
  EXPECT_THROW(Mlp<float>::from_flat(bad), ParameterError);
  bad = flat;
  bad[20] = NAN;
  EXPECT_THROW(Mlp<float>::from_flat(bad), ParameterError);
  bad = flat;
  bad[5] = 3.0f; /* head */
  EXPECT_THROW(Mlp<float>::from_flat(bad), ParameterError);
  bad = flat;
  bad[1] = 0.0f; /* width */
  EXPECT_THROW(Mlp<float>::from_flat(bad), ParameterError);
  EXPECT_THROW(Mlp<float>(MlpShape{{6, 100, 3}, ny::kMlpHeadExp}, 1), ParameterError);
  EXPECT_THROW(Mlp<float>(MlpShape{{6}, ny::kMlpHeadExp}, 1), ParameterError);
}

TEST(Mlp, HeadsStayFinite)
{
  for (float z : {-1e30f, -100.0f, -1.0f, 0.0f, 1.0f, 100.0f, 1e30f}) {
    const float s = ny::mlp_apply_head(ny::kMlpHeadSigmoid, z), e = ny::mlp_apply_head(ny::kMlpHeadExp, z);
    EXPECT_TRUE(std::isfinite(s) && s >= 0.0f && s <= 1.0f) << z;
    EXPECT_TRUE(std::isfinite(e) && e >= 0.0f) << z;
  }
}

/* Adam on the T shape fits a smooth probability-like target: the loss falls by 50x. */
TEST(Mlp, AdamTrainsTheTShape)
{
  std::mt19937_64 rng(21);
  const int B = 2048;
  const auto X = random_matrix<float>(3, B, rng, -1.0, 1.0);
  Mlp<float>::Mat T(1, B);
  for (int j = 0; j < B; j++) {
    const float z = 2.0f * std::sin(2.0f * X(0, j)) + X(1, j) * X(2, j) - 0.5f * X(2, j);
    T(0, j) = 1.0f / (1.0f + std::exp(-z));
  }
  Mlp<float> m(MlpShape{{3, 7, 7, 1}, ny::kMlpHeadSigmoid}, 4);
  train::Adam<float> adam(m.num_params(), 1e-2f);
  Mlp<float>::Vec g;
  const float initial = m.loss_and_gradient(X, T, Loss::kMse, 0.0f, nullptr);
  for (int it = 0; it < 3000; it++) {
    m.loss_and_gradient(X, T, Loss::kMse, 0.0f, &g);
    Mlp<float>::Vec p = m.params();
    adam.step(&p, g);
    m.set_params(p);
  }
  const float final_loss = m.loss_and_gradient(X, T, Loss::kMse, 0.0f, nullptr);
  EXPECT_LT(final_loss, initial / 50.0f) << "initial " << initial << " final " << final_loss;
}

/* The weighted losses weigh each error by what they say: with outputs fixed at y (a one-layer identity
 * network, zero weights, biases y), the value is the mean of (y - t)^2 w with w = 1 / (y^2 + eps) for the
 * relative and w = 1 / (y + eps) for the Poisson loss, and the gradient in a bias is the mean of
 * 2 (y - t) w over its row (w held fixed: no gradient through the weight). */
TEST(Mlp, WeightedLossesWeighTheirErrorsAsDocumented)
{
  const double y[3] = {0.5, 2.0, 8.0}, eps = 1e-3;
  Mlp<double> m(MlpShape{{1, 3}, ny::kMlpHeadIdentity}, 1);
  Mlp<double>::Vec p = Mlp<double>::Vec::Zero(m.num_params());
  for (int k = 0; k < 3; k++) {
    p(3 + k) = y[k]; /* W_0 (3 x 1), then b_0 */
  }
  m.set_params(p);
  const int B = 4;
  const Mlp<double>::Mat X = Mlp<double>::Mat::Zero(1, B);
  Mlp<double>::Mat T(3, B);
  T << 0.0, 1.0, 0.2, 0.7, 3.0, 0.0, 2.5, 1.0, 20.0, 0.0, 4.0, 9.0;
  for (Loss loss : {Loss::kRelativeMse, Loss::kPoissonMse}) {
    double value = 0.0, grad_b[3] = {0.0, 0.0, 0.0};
    for (int k = 0; k < 3; k++) {
      const double w = loss == Loss::kRelativeMse ? 1.0 / (y[k] * y[k] + eps) : 1.0 / (y[k] + eps);
      for (int j = 0; j < B; j++) {
        value += (y[k] - T(k, j)) * (y[k] - T(k, j)) * w / (3 * B);
        grad_b[k] += 2.0 * (y[k] - T(k, j)) * w / (3 * B);
      }
    }
    Mlp<double>::Vec g;
    EXPECT_NEAR(m.loss_and_gradient(X, T, loss, eps, &g), value, 1e-12 * value) << int(loss);
    for (int k = 0; k < 3; k++) {
      EXPECT_NEAR(g(3 + k), grad_b[k], 1e-12 * std::abs(grad_b[k]) + 1e-15) << int(loss) << " bias " << k;
    }
  }
}

/* A NaN target is none (a two-sided M's other side, D45): for every loss, the value is the mean over the
 * finite targets and an output with no target gets no gradient, so the same data with the NaN entries
 * replaced by anything gives the same loss over the finite ones. */
TEST(Mlp, NanTargetsAreNoTargets)
{
  Mlp<double> m(MlpShape{{2, 5, 2}, ny::kMlpHeadExp}, 4);
  std::mt19937_64 rng(5);
  const auto X = random_matrix<double>(2, 64, rng, -1.0, 1.0);
  Mlp<double>::Mat T = random_matrix<double>(2, 64, rng, 0.1, 2.0);
  Mlp<double>::Mat Tn = T;
  for (int j = 0; j < T.cols(); j++) {
    Tn(j % 2, j) = std::numeric_limits<double>::quiet_NaN(); /* each column keeps one of its two targets */
  }
  for (Loss loss : {Loss::kMse, Loss::kLogMse, Loss::kRelativeMse, Loss::kPoissonMse}) {
    Mlp<double>::Vec g;
    const double value = m.loss_and_gradient(X, Tn, loss, 1e-3, &g);
    ASSERT_TRUE(std::isfinite(value)) << int(loss);
    ASSERT_TRUE(g.allFinite()) << int(loss);
    /* The mean over the kept targets, computed column by column with one output each. */
    const Mlp<double>::Mat Y = m.forward(X);
    double want = 0.0;
    for (int j = 0; j < T.cols(); j++) {
      const int k = 1 - j % 2;
      const double y = Y(k, j), t = T(k, j), e = 1e-3;
      want += loss == Loss::kMse           ? (y - t) * (y - t)
              : loss == Loss::kRelativeMse ? (y - t) * (y - t) / (y * y + e)
              : loss == Loss::kPoissonMse  ? (y - t) * (y - t) / (y + e)
                                           : std::pow(std::log(y + e) - std::log(t + e), 2);
    }
    EXPECT_NEAR(value, want / T.cols(), 1e-12 * want) << int(loss);
    /* Changing a NaN-masked column's value to another finite target changes the loss; NaN does not count. */
    Mlp<double>::Mat Tm = T;
    for (int j = 0; j < T.cols(); j++) {
      Tm(j % 2, j) = 1e6;
    }
    EXPECT_GT(m.loss_and_gradient(X, Tm, loss, 1e-3, nullptr), 2 * value) << int(loss);
  }
  /* An output row with no target at all has no gradient in its bias (the last two parameters). */
  Mlp<double>::Mat Tr = T;
  Tr.row(1).setConstant(std::numeric_limits<double>::quiet_NaN());
  Mlp<double>::Vec g;
  m.loss_and_gradient(X, Tr, Loss::kRelativeMse, 1e-3, &g);
  EXPECT_EQ(g(g.size() - 1), 0.0);
  EXPECT_NE(g(g.size() - 2), 0.0);
}
