// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/geometry/ply.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <utility>

#include "neuralyarn/presets.h" /* ParameterError */
#include "neuralyarn/random.h"
#include "neuralyarn/units.h"

namespace neuralyarn::geometry {

namespace {

/* Pairs are pushed to 2 r (1 + kSeparationMargin) so that the final check d >= 2 r holds despite
 * rounding. */
constexpr double kSeparationMargin = 1e-7;
constexpr int kMaxSweeps = 20000;

double uniform_double(Rng &rng) { return double(rng() >> 11) * (1.0 / 9007199254740992.0); }

std::string num(double v)
{
  std::ostringstream s;
  s << v;
  return s.str();
}

void validate(const PlyParams &p)
{
  if (p.N < 1 || p.N > kMaxFibers) {
    throw ParameterError("N", "parameter 'N' (fibers per ply) must be an integer in [1, " +
                                  std::to_string(kMaxFibers) + "], got " + std::to_string(p.N));
  }
  if (!(std::isfinite(p.rho) && p.rho > 0.0 && p.rho < 1.0)) {
    throw ParameterError("rho", "parameter 'rho' (fiber density) must be a finite number in (0, 1), got " + num(p.rho));
  }
  if (!(std::isfinite(p.alpha) && p.alpha >= 0.0)) {
    throw ParameterError("alpha", "parameter 'alpha' (twist) must be a finite number >= 0, got " + num(p.alpha));
  }
  if (!(std::isfinite(p.R) && p.R > 0.0)) {
    throw ParameterError("R", "parameter 'R' (ply radius) must be a finite number > 0, got " + num(p.R));
  }
}

/* Uniform grid over [-R, R]^2 with cells of side >= 2 r: overlapping pairs are in the same or adjacent
 * cells. Rebuilt every sweep (counting sort, O(N)). */
class Grid {
 public:
  Grid(double R, double cell) : R_(R), inv_cell_(1.0 / cell), n_(std::max(1, int(std::ceil(2.0 * R / cell)))) {}

  void build(const std::vector<Eigen::Vector2d> &pts)
  {
    start_.assign(size_t(n_) * n_ + 1, 0);
    cell_of_.resize(pts.size());
    for (size_t i = 0; i < pts.size(); i++) {
      cell_of_[i] = index(pts[i]);
      start_[cell_of_[i] + 1]++;
    }
    for (size_t c = 1; c < start_.size(); c++) {
      start_[c] += start_[c - 1];
    }
    items_.resize(pts.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < pts.size(); i++) {
      items_[fill[cell_of_[i]]++] = int(i);
    }
  }

  /* Calls f(i, j) once for every pair i < j in the same or neighbouring cells, in a fixed order. */
  template<class F> void for_each_near_pair(F f) const
  {
    for (int cy = 0; cy < n_; cy++) {
      for (int cx = 0; cx < n_; cx++) {
        const int c = cy * n_ + cx;
        for (int a = start_[c]; a < start_[c + 1]; a++) {
          const int i = items_[a];
          for (int dy = -1; dy <= 1; dy++) {
            for (int dx = -1; dx <= 1; dx++) {
              const int nx = cx + dx, ny = cy + dy;
              if (nx < 0 || ny < 0 || nx >= n_ || ny >= n_) {
                continue;
              }
              const int d = ny * n_ + nx;
              for (int b = start_[d]; b < start_[d + 1]; b++) {
                const int j = items_[b];
                if (j > i) {
                  f(i, j);
                }
              }
            }
          }
        }
      }
    }
  }

 private:
  int index(const Eigen::Vector2d &p) const
  {
    const int x = std::clamp(int((p.x() + R_) * inv_cell_), 0, n_ - 1);
    const int y = std::clamp(int((p.y() + R_) * inv_cell_), 0, n_ - 1);
    return y * n_ + x;
  }
  double R_, inv_cell_;
  int n_;
  std::vector<int> start_, cell_of_, items_;
};

}  // namespace

PlyCrossSection pack_cross_section(const PlyParams &params, uint64_t seed)
{
  validate(params);
  PlyCrossSection cs;
  cs.R = params.R;
  cs.r = params.R * std::sqrt(params.rho / params.N);
  const double r_in = params.R - cs.r; /* centres stay here so fibers lie inside the ply */
  const double two_r = 2.0 * cs.r;

  Rng rng(seed);
  cs.centers.resize(params.N);
  for (auto &c : cs.centers) {
    const double rad = r_in * std::sqrt(uniform_double(rng));
    const double ang = 2.0 * kPi * uniform_double(rng);
    c = Eigen::Vector2d(rad * std::cos(ang), rad * std::sin(ang));
  }

  /* Separation is measured perpendicular to the fibers, not in the slice. Two neighbouring helices at mean
   * radius d are nearly parallel, tilted by atan(w d) (w = pi alpha / R) toward the tangential direction;
   * a slice offset s = (s_r, s_t) (radial, tangential) separates their axes by
   *     |s|_perp = sqrt(s_r^2 + s_t^2 / (1 + w^2 d^2)),
   * so round tubes of radius r are disjoint in 3D iff |s|_perp >= 2 r. (Packing with the slice metric
   * instead, as the paper's Eq. 1 suggests, lets the outer tubes of a twisted ply interpenetrate, and a
   * random walk's queries then start inside neighbouring fibers.) For alpha = 0
   * this is the Euclidean distance. docs/decisions.md D8. */
  const double w = kPi * params.alpha / params.R;
  auto perp_scale = [&](const Eigen::Vector2d &a, const Eigen::Vector2d &b, Eigen::Vector2d *e_r) {
    const Eigen::Vector2d mid = 0.5 * (a + b);
    const double d = mid.norm();
    *e_r = d > 1e-12 ? Eigen::Vector2d(mid / d) : Eigen::Vector2d(1.0, 0.0);
    return 1.0 / (1.0 + w * w * d * d); /* k: |s|_perp^2 = s_r^2 + k s_t^2 */
  };
  auto perp_distance = [&](const Eigen::Vector2d &a, const Eigen::Vector2d &b) {
    Eigen::Vector2d e_r;
    const double k = perp_scale(a, b, &e_r);
    const Eigen::Vector2d s = a - b;
    const double s_r = s.dot(e_r), s_t = s.x() * -e_r.y() + s.y() * e_r.x();
    return std::sqrt(s_r * s_r + k * s_t * s_t);
  };

  /* Jacobi relaxation: every overlapping pair is pushed apart symmetrically to the target separation (its
   * slice offset scaled up, which scales |s|_perp by the same factor), all displacements of a sweep are
   * applied together (so the result does not depend on visiting order), and centres that left the disk
   * are projected back onto it. Grid cells cover the largest slice offset that can still overlap. */
  const double reach = two_r * std::sqrt(1.0 + w * w * params.R * params.R);
  Grid grid(params.R, reach);
  std::vector<Eigen::Vector2d> disp(params.N);
  const double target = two_r * (1.0 + kSeparationMargin);
  int sweep = 0;
  for (; sweep < kMaxSweeps; sweep++) {
    grid.build(cs.centers);
    std::fill(disp.begin(), disp.end(), Eigen::Vector2d::Zero());
    bool overlap = false;
    grid.for_each_near_pair([&](int i, int j) {
      Eigen::Vector2d s = cs.centers[i] - cs.centers[j];
      const double len = perp_distance(cs.centers[i], cs.centers[j]);
      if (len >= two_r) {
        return;
      }
      overlap = true;
      if (len < 1e-12 * two_r) {
        /* Coincident centres: separate along a direction fixed by the pair's indices. */
        const double a = 2.0 * kPi * double((i * 7919 + j * 104729) % 1000) / 1000.0;
        const Eigen::Vector2d d(std::cos(a), std::sin(a));
        disp[i] += 0.5 * target * d;
        disp[j] -= 0.5 * target * d;
        return;
      }
      const Eigen::Vector2d push = 0.5 * (target / len - 1.0) * s;
      disp[i] += push;
      disp[j] -= push;
    });
    if (!overlap) {
      break;
    }
    for (int i = 0; i < params.N; i++) {
      cs.centers[i] += disp[i];
      const double len = cs.centers[i].norm();
      if (len > r_in) {
        cs.centers[i] *= r_in / len;
      }
    }
  }
  if (sweep == kMaxSweeps) {
    throw ParameterError("rho", "cannot pack N = " + std::to_string(params.N) + " fibers at density rho = " +
                                    num(params.rho) + " and twist alpha = " + num(params.alpha) +
                                    " without overlap (gave up after " + std::to_string(kMaxSweeps) +
                                    " relaxation sweeps); lower 'rho'");
  }

  /* Smallest perpendicular distance among grid neighbours (any pair closer than 2 r is among them). */
  cs.stats.iterations = sweep;
  cs.stats.min_distance = std::numeric_limits<double>::infinity();
  grid.build(cs.centers);
  grid.for_each_near_pair([&](int i, int j) {
    cs.stats.min_distance = std::min(cs.stats.min_distance, perp_distance(cs.centers[i], cs.centers[j]));
  });
  return cs;
}

PlyCrossSection mirrored(const PlyCrossSection &cs)
{
  PlyCrossSection m = cs;
  for (auto &c : m.centers) {
    c.x() = -c.x(); /* centres are stored as (y, z) */
  }
  return m;
}

Ply::Ply(const PlyParams &params, PlyCrossSection cross_section)
    : params_(params), cs_(std::move(cross_section)), twist_rate_(kPi * params.alpha / params.R)
{
  validate(params);
}

double Ply::pitch() const
{
  return params_.alpha > 0.0 ? 2.0 * params_.R / params_.alpha : std::numeric_limits<double>::infinity();
}

Eigen::Vector3d Ply::fiber_point(int i, double x) const
{
  const Eigen::Vector2d &c = cs_.centers[i];
  const double d = c.norm(), psi = std::atan2(c.y(), c.x()) + twist_rate_ * x;
  return Eigen::Vector3d(x, d * std::cos(psi), d * std::sin(psi));
}

Eigen::Vector3d Ply::fiber_tangent(int i, double x) const
{
  const Eigen::Vector2d &c = cs_.centers[i];
  const double d = c.norm(), psi = std::atan2(c.y(), c.x()) + twist_rate_ * x;
  const double s = d * twist_rate_;
  return Eigen::Vector3d(1.0, -s * std::sin(psi), s * std::cos(psi)).normalized();
}

CurveSet tessellate_curves(int num_curves, const std::function<Eigen::Vector3d(int, double)> &point,
                           const std::function<float(int)> &radius, double x0, double x1, double turns,
                           int segments_per_turn, double min_segment_length)
{
  if (!(std::isfinite(x0) && std::isfinite(x1) && x1 > x0)) {
    throw ParameterError("x", "fiber export needs a finite range x0 < x1, got [" + num(x0) + ", " + num(x1) + "]");
  }
  if (segments_per_turn < 3) {
    throw ParameterError("segments_per_turn", "segments_per_turn must be >= 3, got " + std::to_string(segments_per_turn));
  }
  const double length = x1 - x0;
  const int segments = std::max({1, int(std::ceil(turns * segments_per_turn)),
                                 int(std::ceil(length / min_segment_length))});
  CurveSet out;
  out.points.reserve(size_t(num_curves) * (segments + 1));
  for (int c = 0; c < num_curves; c++) {
    out.offsets.push_back(int(out.points.size()));
    for (int k = 0; k <= segments; k++) {
      out.points.push_back(point(c, x0 + length * k / segments).cast<float>());
    }
    out.radii.push_back(radius(c));
  }
  out.offsets.push_back(int(out.points.size()));
  return out;
}

CurveSet export_fibers(const Ply &ply, double x0, double x1, int segments_per_turn)
{
  const double turns = std::isfinite(ply.pitch()) ? (x1 - x0) / ply.pitch() : 0.0;
  return tessellate_curves(
      ply.num_fibers(), [&](int i, double x) { return ply.fiber_point(i, x); },
      [&](int) { return float(ply.fiber_radius()); }, x0, x1, turns, segments_per_turn, ply.params().R);
}

}  // namespace neuralyarn::geometry
