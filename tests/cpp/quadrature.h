// SPDX-License-Identifier: Apache-2.0
//
// Independent reference quadrature for the tests, in double, over panels whose breakpoints the caller
// places at a lobe's centre and shoulders so that narrow peaks are never stepped over:
//   integrate_panels        adaptive Gauss-Kronrod (Boost.Math), for 1D integrals;
//   integrate_panels_fixed  30-point Gauss-Legendre per panel, for the nested 2D sphere integrals where
//                           adaptivity in both dimensions would cost minutes. With panels no wider than
//                           1.5 lobe widths the rule is exact to ~1e-12 for these smooth integrands.
// Shares no code with the kernel's own normalisers or samplers.
#pragma once

#include <algorithm>
#include <array>
#include <utility>
#include <functional>
#include <vector>

#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/gauss_kronrod.hpp>

namespace nytest {

/* Sorted, de-duplicated breakpoints inside [lo, hi], with lo and hi included. */
inline std::vector<double> breakpoints(std::vector<double> pts, double lo, double hi, double max_width = 0.0)
{
  std::vector<double> out = {lo, hi};
  for (double p : pts) {
    if (p > lo && p < hi) {
      out.push_back(p);
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end(), [](double a, double b) { return b - a < 1e-12; }), out.end());
  if (max_width > 0.0) {
    std::vector<double> split = {out.front()};
    for (size_t i = 1; i < out.size(); i++) {
      const int n = int(std::ceil((out[i] - out[i - 1]) / max_width));
      for (int k = 1; k <= n; k++) {
        split.push_back(out[i - 1] + (out[i] - out[i - 1]) * k / n);
      }
    }
    out = split;
  }
  return out;
}

inline double integrate_panels(const std::function<double(double)> &f, const std::vector<double> &pts,
                               double tol = 1e-10)
{
  double sum = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); i++) {
    sum += boost::math::quadrature::gauss_kronrod<double, 31>::integrate(f, pts[i], pts[i + 1], 12, tol);
  }
  return sum;
}

inline double integrate_panels_fixed(const std::function<double(double)> &f, const std::vector<double> &pts)
{
  double sum = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); i++) {
    sum += boost::math::quadrature::gauss<double, 30>::integrate(f, pts[i], pts[i + 1]);
  }
  return sum;
}

/* The 30-point Gauss-Legendre rule on [-1, 1] as (node, weight) pairs, from Boost's tables. */
inline const std::vector<std::pair<double, double>> &gauss30()
{
  static const std::vector<std::pair<double, double>> rule = [] {
    using G = boost::math::quadrature::gauss<double, 30>;
    std::vector<std::pair<double, double>> r;
    for (size_t i = 0; i < G::abscissa().size(); i++) {
      r.push_back({G::abscissa()[i], G::weights()[i]});
      r.push_back({-G::abscissa()[i], G::weights()[i]});
    }
    return r;
  }();
  return rule;
}

/* Nested fixed-rule integral of a vector-valued f(x, y) over panels in x and y. */
template<size_t N>
std::array<double, N> integrate_2d_fixed(const std::function<std::array<double, N>(double, double)> &f,
                                         const std::vector<double> &xs, const std::vector<double> &ys)
{
  std::array<double, N> sum{};
  for (size_t i = 0; i + 1 < xs.size(); i++) {
    const double hx = 0.5 * (xs[i + 1] - xs[i]), mx = 0.5 * (xs[i + 1] + xs[i]);
    for (const auto &[nx, wx] : gauss30()) {
      for (size_t j = 0; j + 1 < ys.size(); j++) {
        const double hy = 0.5 * (ys[j + 1] - ys[j]), my = 0.5 * (ys[j + 1] + ys[j]);
        for (const auto &[ny_, wy] : gauss30()) {
          const auto v = f(mx + hx * nx, my + hy * ny_);
          for (size_t k = 0; k < N; k++) {
            sum[k] += wx * hx * wy * hy * v[k];
          }
        }
      }
    }
  }
  return sum;
}

}  // namespace nytest
