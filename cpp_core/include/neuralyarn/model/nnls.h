// SPDX-License-Identifier: Apache-2.0
//
// Non-negative least squares for the few lobe weights of a stock-closure fit (model/fallback.h per view of
// a ply, model/surface_fit.h per view of a cloth surface).
#pragma once

#include <Eigen/Core>

namespace neuralyarn::model {

/* min w^T G w - 2 b^T w over w >= 0 (G symmetric positive semi-definite, K = b.size() <= 8): every subset of
 * free variables solved exactly (2^K - 1 small systems), the best feasible one kept. Exact and deterministic. */
Eigen::VectorXd nnls_small(const Eigen::MatrixXd &G, const Eigen::VectorXd &b);

}  // namespace neuralyarn::model
