// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/normal_ziggurat.h"

namespace neuralyarn::rdm {

/* Each layer's right edge from the one below: f(x_{i+1}) = f(x_i) + v / x_i. With Marsaglia & Tsang's r and v
 * the top layer [0, x_127] x [f(x_127), 1] then has area v to ~1e-9 (tests/cpp/test_sampling.cpp checks every layer). */
NormalZiggurat::NormalZiggurat()
{
  const double f_r = std::exp(-0.5 * kR * kR);
  x[0] = kArea / f_r;
  f[0] = f_r; /* layer 0's height: its rectangle has height f(r), not f(x_0) */
  x[1] = kR;
  f[1] = f_r;
  for (int i = 1; i < kLayers - 1; i++) {
    f[i + 1] = f[i] + kArea / x[i];
    x[i + 1] = std::sqrt(-2.0 * std::log(f[i + 1]));
  }
  x[kLayers] = 0.0;
  f[kLayers] = 1.0;
}

const NormalZiggurat &NormalZiggurat::get()
{
  static const NormalZiggurat tables;
  return tables;
}

}  // namespace neuralyarn::rdm
