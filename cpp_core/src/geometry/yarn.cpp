// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/geometry/yarn.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include <Eigen/Geometry> /* cross() */

#include "neuralyarn/presets.h" /* ParameterError, kMaxFibers */
#include "neuralyarn/units.h"

namespace neuralyarn::geometry {

namespace {

constexpr int kMaxPlies = 64;

double twist_rate(double d, double R_ply, double alpha_yarn) { return kPi * alpha_yarn / (d + R_ply); }

/* The smallest f(x) over [lo, lo + width]: f at n + 1 evenly spaced points, then the best point's bracket
 * narrowed by `iterations` steps of golden-section search. */
template<typename F> double scan_then_golden(const F &f, double lo, double width, int n, int iterations)
{
  int i_best = 0;
  double f_best = INFINITY;
  for (int i = 0; i <= n; i++) {
    const double v = f(lo + width * i / n);
    if (v < f_best) {
      f_best = v;
      i_best = i;
    }
  }
  double a = lo + width * std::max(0, i_best - 1) / n, b = lo + width * std::min(n, i_best + 1) / n;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  for (int it = 0; it < iterations; it++) {
    const double x1 = b - g * (b - a), x2 = a + g * (b - a);
    if (f(x1) < f(x2)) {
      b = x2;
    }
    else {
      a = x1;
    }
  }
  return std::min(f_best, f(0.5 * (a + b)));
}

/* Squared distance from ply 0's centre at x = 0, (0, d, 0), to ply k's centre at x. */
double dist2(double x, double d, double phi_k, double w)
{
  return x * x + 2.0 * d * d * (1.0 - std::cos(phi_k - w * x));
}

}  // namespace

double neighbour_ply_distance(int K, double d, double R_ply, double alpha_yarn)
{
  if (K < 2) {
    return INFINITY;
  }
  const double w = twist_rate(d, R_ply, alpha_yarn);
  double best = INFINITY;
  for (int k = 1; k < K; k++) {
    const double phi = 2.0 * kPi * k / K;
    /* f(x) >= x^2, so only |x| < sqrt(f(0)) can beat x = 0: scan that interval, then refine the best
     * bracket by golden-section search. */
    const double X = std::sqrt(dist2(0.0, d, phi, w));
    best = std::min(best, scan_then_golden([&](double x) { return dist2(x, d, phi, w); }, -X, 2.0 * X, 2000, 100));
  }
  return std::sqrt(best);
}

double ply_center_distance(int K, double R_ply, double alpha_yarn)
{
  if (K < 1 || K > kMaxPlies) {
    throw ParameterError("K", "parameter 'K' (plies per yarn) must be an integer in [1, " + std::to_string(kMaxPlies) +
                                  "], got " + std::to_string(K));
  }
  if (!(std::isfinite(R_ply) && R_ply > 0.0)) {
    std::ostringstream s;
    s << R_ply;
    throw ParameterError("R", "parameter 'R' (ply radius) must be a finite number > 0, got " + s.str());
  }
  if (!(std::isfinite(alpha_yarn) && alpha_yarn >= 0.0)) {
    std::ostringstream s;
    s << alpha_yarn;
    throw ParameterError("alpha_yarn", "parameter 'alpha_yarn' (ply twist) must be a finite number >= 0, got " + s.str());
  }
  if (K == 1) {
    return 0.0;
  }
  double lo = R_ply / std::sin(kPi / K), hi = lo;
  while (neighbour_ply_distance(K, hi, R_ply, alpha_yarn) < 2.0 * R_ply) {
    hi *= 1.5;
  }
  for (int it = 0; it < 200 && hi - lo > 1e-13 * hi; it++) {
    const double mid = 0.5 * (lo + hi);
    (neighbour_ply_distance(K, mid, R_ply, alpha_yarn) < 2.0 * R_ply ? lo : hi) = mid;
  }
  return hi;
}

Yarn::Yarn(const YarnParams &params, uint64_t seed) : params_(params)
{
  /* First: it validates K and alpha_yarn before the packing's work. */
  d_ = ply_center_distance(params.K, params.ply.R, params.alpha_yarn);
  for (int k = 0; k < params.K; k++) {
    sections_.push_back(pack_cross_section(params.ply, seed + uint64_t(k)));
  }
  const double R = params.ply.R;
  /* A single ply lies on the axis: there is nothing to twist around, and its radial frame is undefined,
   * so alpha_yarn has no effect (the yarn is exactly the ply of ply.h). */
  w_ = params.K > 1 ? twist_rate(d_, R, params.alpha_yarn) : 0.0;
  arc_per_x_ = std::sqrt(1.0 + d_ * d_ * w_ * w_);
  const double torsion = w_ / (1.0 + d_ * d_ * w_ * w_);
  fiber_rate_ = kPi * params.ply.alpha / R + torsion;
}

Eigen::Vector3d Yarn::ply_center(int ply, double x) const
{
  const double th = 2.0 * kPi * ply / params_.K - w_ * x;
  return Eigen::Vector3d(x, d_ * std::cos(th), d_ * std::sin(th));
}

Eigen::Vector3d Yarn::ply_tangent(int ply, double x) const
{
  const double th = 2.0 * kPi * ply / params_.K - w_ * x;
  return Eigen::Vector3d(1.0, d_ * w_ * std::sin(th), -d_ * w_ * std::cos(th)).normalized();
}

Eigen::Vector3d Yarn::fiber_point(int ply, int fiber, double x) const
{
  const Eigen::Vector2d &c = sections_[ply].centers[fiber];
  return ply_point(ply, c.norm(), std::atan2(c.y(), c.x()), x);
}

Eigen::Vector3d Yarn::ply_point(int ply, double rho, double psi0, double x) const
{
  const double th = 2.0 * kPi * ply / params_.K - w_ * x;
  const Eigen::Vector3d e_r(0.0, std::cos(th), std::sin(th)); /* normal to the helix (and to the axis) */
  const Eigen::Vector3d e_b = ply_tangent(ply, x).cross(e_r);
  const double psi = psi0 + fiber_rate_ * arc_per_x_ * x;
  return ply_center(ply, x) + rho * (std::cos(psi) * e_r + std::sin(psi) * e_b);
}

YarnParams yarn_params(const FiberPreset &preset, const YarnStructure &structure)
{
  YarnParams yp;
  yp.K = structure.plies;
  yp.alpha_yarn = structure.ply_twist;
  yp.ply = PlyParams{preset.N, preset.rho, preset.alpha, 1.0};
  return yp;
}

double surface_twist(const Yarn &yarn)
{
  const YarnParams &p = yarn.params();
  const double R = yarn.yarn_radius();
  const double length = yarn.sampling_length();
  const int samples = 64;
  const double h = 1e-4 * p.ply.R;
  double sum = 0.0;
  long count = 0;
  for (int k = 0; k < p.K; k++) {
    const PlyCrossSection &cs = yarn.cross_section(k);
    const double shell = R - 3.0 * cs.r;
    for (int i = 0; i < int(cs.centers.size()); i++) {
      for (int s = 0; s < samples; s++) {
        const double x = length * (s + 0.5) / samples;
        const Eigen::Vector3d q = yarn.fiber_point(k, i, x);
        const double rho = std::hypot(q.y(), q.z());
        if (rho < shell) {
          continue;
        }
        const Eigen::Vector3d e_r = Eigen::Vector3d(0.0, q.y(), q.z()) / rho;
        const Eigen::Vector3d t = yarn.fiber_point(k, i, x + h) - yarn.fiber_point(k, i, x - h);
        const Eigen::Vector3d e_phi = Eigen::Vector3d::UnitX().cross(e_r);
        sum += t.dot(e_phi) / t.x();
        count++;
      }
    }
  }
  return count > 0 ? sum / count / kPi : 0.0;
}

namespace {

/* Whether q lies inside a ply other than `self` (its distance to that ply's centreline below R_ply): the
 * squared distance to a helix is scanned over one yarn radius either side of q's x, where the nearest point
 * of a centreline at most d + R_ply from q must lie, then refined by golden-section search. */
bool inside_another_ply(const Yarn &yarn, int self, const Eigen::Vector3d &q)
{
  const double R = yarn.params().ply.R, reach = yarn.yarn_radius() + R;
  for (int k = 0; k < yarn.num_plies(); k++) {
    if (k == self) {
      continue;
    }
    auto d2 = [&](double x) { return (yarn.ply_center(k, x) - q).squaredNorm(); };
    if (scan_then_golden(d2, q.x() - reach, 2.0 * reach, 64, 60) < R * R) {
      return true;
    }
  }
  return false;
}

}  // namespace

std::vector<SurfaceFrame> visible_surface_frames(const Yarn &yarn, int nodes, double spread)
{
  if (nodes < 1) {
    throw ParameterError("nodes", "the number of surface frames must be at least 1, got " + std::to_string(nodes));
  }
  if (!(spread > 0.0 && spread <= 1.0)) {
    std::ostringstream s;
    s << spread;
    throw ParameterError("spread", "the share of the visible surface must be in (0, 1], got " + s.str());
  }
  const double R = yarn.params().ply.R, h = 1e-5 * R;
  const int samples = 360;
  std::vector<SurfaceFrame> visible;
  for (int i = 0; i < samples; i++) {
    const double psi0 = -kPi + 2.0 * kPi * i / samples;
    const Eigen::Vector3d p = yarn.ply_point(0, R, psi0, 0.0);
    const Eigen::Vector3d n = (p - yarn.ply_center(0, 0.0)) / R; /* the tube's normal: the cross-section's radial */
    const Eigen::Vector3d t = (yarn.ply_point(0, R, psi0, h) - yarn.ply_point(0, R, psi0, -h)).normalized();
    const double rho = std::hypot(p.y(), p.z());
    if (!(rho > 0.0)) {
      continue;
    }
    const Eigen::Vector3d z(0.0, p.y() / rho, p.z() / rho), y = z.cross(Eigen::Vector3d::UnitX());
    SurfaceFrame f;
    f.T = Eigen::Vector3d(t.x(), t.dot(y), t.dot(z));
    f.N = Eigen::Vector3d(n.x(), n.dot(y), n.dot(z));
    f.N = (f.N - f.T * f.T.dot(f.N)).normalized(); /* the tangent of a screw line on the tube lies in its surface */
    f.weight = f.N.z();
    if (!(f.weight > 0.0)) {
      continue;
    }
    bool hidden = false;
    for (double s = 0.02 * R; s < 3.0 * R && !hidden; s += 0.03 * R) {
      hidden = inside_another_ply(yarn, 0, p + s * z);
    }
    if (hidden) {
      continue;
    }
    f.turn = std::atan2(-f.N.y(), f.N.z());
    visible.push_back(f);
  }
  std::sort(visible.begin(), visible.end(),
            [](const SurfaceFrame &a, const SurfaceFrame &b) { return a.turn < b.turn; });
  double total = 0.0;
  for (const SurfaceFrame &f : visible) {
    total += f.weight;
  }
  std::vector<SurfaceFrame> frames;
  size_t i = 0;
  double cdf = visible.empty() ? 0.0 : visible[0].weight / total;
  for (int q = 0; q < nodes; q++) {
    const double u = 0.5 + ((q + 0.5) / nodes - 0.5) * spread;
    while (i + 1 < visible.size() && cdf < u) {
      cdf += visible[++i].weight / total;
    }
    frames.push_back(visible[i]);
  }
  return frames;
}

CurveSet export_fibers(const Yarn &yarn, double x0, double x1, int segments_per_turn)
{
  const YarnParams &p = yarn.params();
  const int n = int(yarn.cross_section(0).centers.size()); /* every ply has N fibers */
  /* Enough segments for both twists together, and at least one per ply radius. */
  const double turns = p.ply.alpha * (x1 - x0) / (2.0 * p.ply.R) + p.alpha_yarn * (x1 - x0) / (2.0 * yarn.yarn_radius());
  return tessellate_curves(
      yarn.num_plies() * n, [&](int c, double x) { return yarn.fiber_point(c / n, c % n, x); },
      [&](int c) { return float(yarn.cross_section(c / n).r); }, x0, x1, turns, segments_per_turn, p.ply.R);
}

}  // namespace neuralyarn::geometry
