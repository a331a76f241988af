// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/nnls.h"

#include <vector>

#include <Eigen/Dense>

namespace neuralyarn::model {

Eigen::VectorXd nnls_small(const Eigen::MatrixXd &G, const Eigen::VectorXd &b)
{
  const int K = int(b.size());
  Eigen::VectorXd best = Eigen::VectorXd::Zero(K);
  double best_obj = 0.0; /* w = 0 */
  for (int mask = 1; mask < (1 << K); mask++) {
    std::vector<int> idx;
    for (int k = 0; k < K; k++) {
      if (mask >> k & 1) {
        idx.push_back(k);
      }
    }
    const int n = int(idx.size());
    Eigen::MatrixXd Gs(n, n);
    Eigen::VectorXd bs(n);
    for (int x = 0; x < n; x++) {
      bs[x] = b[idx[size_t(x)]];
      for (int y = 0; y < n; y++) {
        Gs(x, y) = G(idx[size_t(x)], idx[size_t(y)]);
      }
    }
    const Eigen::VectorXd ws = Gs.ldlt().solve(bs);
    if (!ws.allFinite() || (ws.array() < 0.0).any()) {
      continue;
    }
    Eigen::VectorXd w = Eigen::VectorXd::Zero(K);
    for (int x = 0; x < n; x++) {
      w[idx[size_t(x)]] = ws[x];
    }
    const double obj = w.dot(G * w) - 2.0 * w.dot(b);
    if (obj < best_obj) {
      best_obj = obj;
      best = w;
    }
  }
  return best;
}

}  // namespace neuralyarn::model
