// SPDX-License-Identifier: Apache-2.0
//
// Chi^2 goodness-of-fit of a sampler against its claimed density, in the manner of Mitsuba's
// ChiSquareTest, with one change: the grid adapts to the distribution. A uniform (theta, phi) grid puts a
// 1-degree lobe into a single cell and cannot see it; here the cell edges are quantiles of an independent
// pilot sample (drawn with another seed before the test sample), so every cell carries comparable
// probability whatever the lobe width. The edges are fixed before the test sample is drawn, which is all
// the chi^2 test requires of a partition.
//
// The partition is: a grid of cells covering the box between the pilot's 0.1 % and 99.9 % quantiles in
// each coordinate, plus one cell for the complement of that box. Interior expected counts integrate the
// pdf over each cell in double, by adaptive Gauss-Kronrod in 1D and adaptive 8x8 Gauss-Legendre cubature
// in 2D; the complement's expected count
// is n minus the interior total, i.e. it assumes the pdf has unit mass, which the tests check separately
// by independent quadrature. (Integrating the far tails cell by cell is what fails: a cell of width 3 rad
// whose mass hugs one edge within 1e-3 rad defeats any fixed or adaptive rule.)
//
// Cells with expected count below 5 are pooled (Mitsuba's rule); a sample in an interior cell whose
// integrated pdf is zero fails at once.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <boost/math/special_functions/gamma.hpp>

#include "neuralyarn/kernel/frames.h"
#include "neuralyarn/random.h"

namespace nytest {

struct Chi2Result {
  double chi2 = 0.0;
  int dof = 0;
  double p_value = 1.0;
  double interior_mass = 0.0; /* integral of the pdf over the interior box */
  double interior_fraction = 0.0; /* fraction of test samples that fell in it */
  std::string failure; /* non-empty: a structural failure (sample where pdf = 0, ...) */
};

/* Per-test significance for `n_tests` tests at family-wise level alpha (Sidak). */
inline double sidak_alpha(double alpha, int n_tests) { return 1.0 - std::pow(1.0 - alpha, 1.0 / n_tests); }

namespace detail {

constexpr double kTailLevel = 1e-3;

/* 1D adaptive Gauss-Kronrod. Relative tolerance 1e-6: the integrands are float functions (rounding noise
 * ~1e-7, a tighter tolerance only drives the refinement to its depth limit), and an expected count needs
 * far less than its ~1/sqrt(count) statistical resolution. */
inline double integrate(const std::function<double(double)> &f, double a, double b)
{
  return boost::math::quadrature::gauss_kronrod<double, 15>::integrate(f, a, b, 10, 1e-6);
}

/* 8-point Gauss-Legendre tensor rule on [x0, x1] x [y0, y1]. */
inline double gl8x8(const std::function<double(double, double)> &f, double x0, double x1, double y0, double y1)
{
  static const double x[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
                              0.1834346424956498,  0.5255324099163290,  0.7966664774136267,  0.9602898564975363};
  static const double w[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873, 0.3626837833783620,
                              0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};
  const double hx = 0.5 * (x1 - x0), mx = 0.5 * (x1 + x0), hy = 0.5 * (y1 - y0), my = 0.5 * (y1 + y0);
  double s = 0.0;
  for (int a = 0; a < 8; a++) {
    for (int b = 0; b < 8; b++) {
      s += w[a] * w[b] * f(mx + hx * x[a], my + hy * x[b]);
    }
  }
  return s * hx * hy;
}

/* Adaptive 2D cubature: accept the 2x2-split estimate when it agrees with the unsplit one to tol (or 1e-5
 * relative), otherwise recurse into the four quarters. Nested 1D adaptive
 * quadrature is not used because the outer level reads the inner level's own error on these float
 * integrands as roughness and refines to its depth limit everywhere (measured: 3e8 pdf calls for one
 * 20 x 40 grid). */
inline double cubature_split(const std::function<double(double, double)> &f, double x0, double x1, double y0,
                             double y1, double whole, double tol, int depth)
{
  const double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
  const double q[4] = {gl8x8(f, x0, xm, y0, ym), gl8x8(f, xm, x1, y0, ym), gl8x8(f, x0, xm, ym, y1),
                       gl8x8(f, xm, x1, ym, y1)};
  const double split = q[0] + q[1] + q[2] + q[3];
  /* The relative term (1e-5, a hundred times the float noise of the integrand) stops the refinement
   * where the absolute target would be below what float evaluation can resolve. */
  if (std::fabs(split - whole) <= std::max(tol, 1e-5 * std::fabs(split)) || depth >= 7) {
    return split;
  }
  return cubature_split(f, x0, xm, y0, ym, q[0], 0.5 * tol, depth + 1) +
         cubature_split(f, xm, x1, y0, ym, q[1], 0.5 * tol, depth + 1) +
         cubature_split(f, x0, xm, ym, y1, q[2], 0.5 * tol, depth + 1) +
         cubature_split(f, xm, x1, ym, y1, q[3], 0.5 * tol, depth + 1);
}

inline double cubature(const std::function<double(double, double)> &f, double x0, double x1, double y0, double y1,
                       double tol, int depth)
{
  return cubature_split(f, x0, x1, y0, y1, gl8x8(f, x0, x1, y0, y1), tol, depth);
}

/* n_bins + 1 strictly increasing edges between the pilot's tail quantiles. */
inline std::vector<double> quantile_edges(std::vector<double> values, int n_bins)
{
  std::sort(values.begin(), values.end());
  auto q = [&](double level) { return values[size_t(level * double(values.size() - 1))]; };
  const double lo = q(kTailLevel), hi = q(1.0 - kTailLevel);
  std::vector<double> edges = {lo};
  for (int i = 1; i < n_bins; i++) {
    const double e = q(kTailLevel + (1.0 - 2.0 * kTailLevel) * double(i) / n_bins);
    if (e > edges.back() + 1e-9 && e < hi - 1e-9) {
      edges.push_back(e);
    }
  }
  edges.push_back(hi);
  return edges;
}

/* Bin index, or -1 outside [edges.front(), edges.back()). */
inline int find_bin(const std::vector<double> &edges, double v)
{
  if (!(v >= edges.front() && v < edges.back())) {
    return -1;
  }
  const auto it = std::upper_bound(edges.begin(), edges.end(), v);
  return std::clamp(int(it - edges.begin()) - 1, 0, int(edges.size()) - 2);
}

/* Fewest cells a partition may have: a sampler whose pilot sample collapses onto a few values (the
 * symptom of a broken sampler) must fail, not pass with zero degrees of freedom. */
constexpr int kMinCells = 20;

/* expected/observed: interior cells, then the complement cell last. */
inline Chi2Result finish(std::vector<double> expected, std::vector<long long> observed, long long n)
{
  Chi2Result r;
  if (int(expected.size()) < kMinCells) {
    r.failure = "degenerate partition: the pilot sample spans only " + std::to_string(expected.size()) +
                " cells (a sampler that collapses onto a few values?)";
    return r;
  }
  for (size_t i = 0; i < expected.size(); i++) {
    r.interior_mass += expected[i] / double(n);
    if (expected[i] <= 1e-12 * double(n) && observed[i] > 0) {
      r.failure = "a sample fell into cell " + std::to_string(i) + " where the pdf integrates to " +
                  std::to_string(expected[i] / double(n));
      return r;
    }
  }
  long long inside = 0;
  for (long long o : observed) {
    inside += o;
  }
  r.interior_fraction = double(inside) / double(n);
  expected.push_back(std::max(0.0, double(n) * (1.0 - r.interior_mass)));
  observed.push_back(n - inside);

  std::vector<size_t> order(expected.size());
  for (size_t i = 0; i < order.size(); i++) {
    order[i] = i;
  }
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  double pooled_e = 0.0, pooled_o = 0.0;
  int cells = 0;
  for (size_t k : order) {
    double e = expected[k], o = double(observed[k]);
    if (e < 5.0) {
      pooled_e += e;
      pooled_o += o;
      continue;
    }
    if (pooled_e > 0.0 && pooled_e < 5.0) {
      /* Fold a still-small pool into the smallest regular cell. */
      e += pooled_e;
      o += pooled_o;
      pooled_e = pooled_o = 0.0;
    }
    r.chi2 += (o - e) * (o - e) / e;
    cells++;
  }
  if (pooled_e >= 5.0) {
    r.chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
    cells++;
  }
  r.dof = cells - 1;
  r.p_value = r.dof > 0 ? boost::math::gamma_q(0.5 * r.dof, 0.5 * r.chi2) : 1.0;
  return r;
}

}  // namespace detail

/* 1D test. `sample` draws one value; `pdf` is its density (unit mass over the sampler's support). */
inline Chi2Result chi2_1d(const std::function<double(neuralyarn::Rng &)> &sample,
                          const std::function<double(double)> &pdf, int n_samples, int n_bins, uint64_t seed)
{
  neuralyarn::Rng pilot_rng(seed ^ 0xA5A5A5A5DEADBEEFull);
  std::vector<double> pilot(std::max(200 * n_bins, n_samples / 5));
  for (auto &v : pilot) {
    v = sample(pilot_rng);
  }
  const std::vector<double> edges = detail::quantile_edges(pilot, n_bins);
  const int nb = int(edges.size()) - 1;
  std::vector<long long> obs(nb, 0);
  neuralyarn::Rng rng(seed);
  for (int i = 0; i < n_samples; i++) {
    const int b = detail::find_bin(edges, sample(rng));
    if (b >= 0) {
      obs[b]++;
    }
  }
  std::vector<double> expected(nb, 0.0);
  for (int b = 0; b < nb; b++) {
    expected[b] = detail::integrate(pdf, edges[b], edges[b + 1]) * n_samples;
  }
  return detail::finish(expected, obs, n_samples);
}

/* Test over the sphere in the Marschner angles of frames.h: theta in [-pi/2, pi/2], phi in [-pi, pi].
 * `sample` returns false for a failed sample (it then counts in the complement cell); `pdf` is per
 * solid angle. */
inline Chi2Result chi2_sphere(const std::function<bool(neuralyarn::Rng &, ny::Vec3 &)> &sample,
                              const std::function<double(ny::Vec3)> &pdf, int n_samples, int n_theta, int n_phi,
                              uint64_t seed)
{
  neuralyarn::Rng pilot_rng(seed ^ 0xA5A5A5A5DEADBEEFull);
  const int n_pilot = std::max(200 * n_theta * n_phi / 10, n_samples / 5);
  std::vector<double> pth, pph;
  for (int i = 0; i < n_pilot; i++) {
    ny::Vec3 w;
    if (sample(pilot_rng, w)) {
      pth.push_back(ny::theta_of(w));
      pph.push_back(ny::phi_of(w));
    }
  }
  if (pth.size() < 1000) {
    Chi2Result r;
    r.failure = "the sampler produced almost no samples";
    return r;
  }
  const auto te = detail::quantile_edges(pth, n_theta);
  const auto pe = detail::quantile_edges(pph, n_phi);
  const int nt = int(te.size()) - 1, np = int(pe.size()) - 1;

  std::vector<long long> obs(size_t(nt) * np, 0);
  neuralyarn::Rng rng(seed);
  for (int i = 0; i < n_samples; i++) {
    ny::Vec3 w;
    if (!sample(rng, w)) {
      continue;
    }
    const int bt = detail::find_bin(te, ny::theta_of(w)), bp = detail::find_bin(pe, ny::phi_of(w));
    if (bt >= 0 && bp >= 0) {
      obs[size_t(bt) * np + bp]++;
    }
  }
  const auto integrand = [&](double th, double ph) {
    return pdf(ny::direction_from_angles(float(th), float(ph))) * std::cos(th);
  };
  /* Absolute target per cell: 1e-3 of one expected count. */
  const double abs_tol = 1e-3 / double(n_samples);
  std::vector<double> expected(obs.size(), 0.0);
  for (int i = 0; i < nt; i++) {
    for (int j = 0; j < np; j++) {
      expected[size_t(i) * np + j] =
          detail::cubature(integrand, te[i], te[i + 1], pe[j], pe[j + 1], abs_tol, 0) * n_samples;
    }
  }
  return detail::finish(expected, obs, n_samples);
}

}  // namespace nytest
