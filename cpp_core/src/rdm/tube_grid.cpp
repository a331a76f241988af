// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/tube_grid.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>

#include <Eigen/Geometry>

#include "neuralyarn/units.h"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace neuralyarn::rdm {

using ny::Vec3;
using ny::make_vec3;

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kWidth = 4 * kTubeLanes;
typedef float LanesF __attribute__((vector_size(kWidth)));
typedef int32_t LanesI __attribute__((vector_size(kWidth)));

/* x in every lane (exact, signed zeros included); for F = float, x itself. */
template<class F> inline F splat(float x);
template<> inline float splat<float>(float x) { return x; }
template<> inline LanesF splat<LanesF>(float x)
{
  LanesF v;
  for (int k = 0; k < kTubeLanes; k++) {
    v[k] = x;
  }
  return v;
}

inline float root(float v) { return std::sqrt(v); }
inline LanesF root(LanesF v)
{
#if defined(__SSE2__)
  static_assert(kWidth == 16);
  return _mm_sqrt_ps(v);
#else
  for (int k = 0; k < kTubeLanes; k++) {
    v[k] = std::sqrt(v[k]);
  }
  return v;
#endif
}

inline bool any_lane(LanesI m)
{
  int32_t a = 0;
  for (int k = 0; k < kTubeLanes; k++) {
    a |= m[k];
  }
  return a != 0;
}

/* Loads by memcpy: one vector move, no aliasing of float arrays through vector types. */
template<typename V, typename T> inline V load(const T *p)
{
  V v;
  std::memcpy(&v, p, sizeof(V));
  return v;
}

/* Entry distance of the ray o + t d (d unit) into the round tube of radius r about the line a + s u (u unit), from
 * w = o - a; +inf where the ray moves away from the axis or along it (B >= 0), starts inside (C <= 0) or misses
 * (disc < 0). |w_perp + t d_perp| = r needs only five dot products:
 *   A = 1 - (d.u)^2,  B = w.d - (w.u)(d.u),  C = w.w - (w.u)^2 - r^2,
 * and the entry root is taken in the cancellation-free form C / (-B + sqrt(disc)). (w spans at most a slab
 * length, so C keeps ~1e-5 r of accuracy in float.) F is float or a vector of lanes: each lane does the float's
 * operations in the same order, so the grid's blocks and a single tube give the same distance to the bit. */
template<class F>
inline F tube_entry_lanes(F wx, F wy, F wz, F ux, F uy, F uz, F dx, F dy, F dz, F r2)
{
  const F wa = wx * ux + wy * uy + wz * uz;
  const F da = dx * ux + dy * uy + dz * uz;
  const F B = (wx * dx + wy * dy + wz * dz) - wa * da;
  const F C = (wx * wx + wy * wy + wz * wz) - wa * wa - r2;
  const F A = splat<F>(1.0f) - da * da;
  const F disc = B * B - A * C;
  const F zero = splat<F>(0.0f);
  const auto valid = (B < zero) & (C > zero) & (disc >= zero);
  return valid ? C / (-B + root(valid ? disc : zero)) : splat<F>(kInf);
}
}  // namespace

Chord make_chord(int fiber, const double p0[3], const double p1[3], double r, double scale)
{
  double u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const double len = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  for (double &c : u) {
    c /= len;
  }
  Chord c;
  c.fiber = fiber;
  c.a = make_vec3(float(p0[0]), float(p0[1]), float(p0[2]));
  c.axis = make_vec3(float(u[0]), float(u[1]), float(u[2]));
  c.y0 = p0[1], c.z0 = p0[2], c.y1 = p1[1], c.z1 = p1[2];
  c.capsule_radius = r / std::max(std::abs(u[0]), 1e-6) * 1.001 + 1e-6 * scale;
  return c;
}

double clipped_tube_reach(const Chord &c, double r, double x0, double x1, int steps)
{
  const Eigen::Vector3d A(c.a.x, c.a.y, c.a.z), D(c.axis.x, c.axis.y, c.axis.z);
  /* Basis of the plane perpendicular to the axis. */
  const Eigen::Vector3d e1 = D.unitOrthogonal(), e2 = D.cross(e1);
  double reach = 0.0;
  for (int k = 0; k <= steps; k++) {
    const double x = x0 - 2.0 * r + (x1 - x0 + 4.0 * r) * k / double(steps);
    const Eigen::Vector3d centre = A + D * ((x - A.x()) / D.x());
    for (int j = 0; j < 64; j++) {
      const double t = 2.0 * kPi * j / 64.0;
      const Eigen::Vector3d q = centre + r * (std::cos(t) * e1 + std::sin(t) * e2);
      if (q.x() >= x0 && q.x() <= x1) {
        reach = std::max(reach, std::hypot(q.y(), q.z()));
      }
    }
  }
  return reach;
}

float tube_entry(const Chord &c, Vec3 o, Vec3 d, float r2)
{
  const Vec3 w = o - c.a;
  return tube_entry_lanes(w.x, w.y, w.z, c.axis.x, c.axis.y, c.axis.z, d.x, d.y, d.z, r2);
}

TubeGrid::TubeGrid(const std::vector<Chord> &chords, float r, float bound, float x0, float x1, double cell)
    : TubeGrid(chords, r, bound, x0, x1, cell, x0)
{
}

TubeGrid::TubeGrid(const std::vector<Chord> &chords, float r, float bound, float x0, float x1, double cell, float anchor)
    : r_(r), bound_(bound), x0_(x0), x1_(x1), anchor_(anchor)
{
  cell_ = float(cell);
  n_ = std::max(1, int(std::ceil(2.0 * double(bound_) / double(cell_))));
  cell_ = float(2.0 * double(bound_) / n_);
  inv_cell_ = 1.0f / cell_;
  auto cell_index = [&](float v) { return std::clamp(int(std::floor((v + bound_) * inv_cell_)), 0, n_ - 1); };
  std::vector<uint32_t> count(size_t(n_) * size_t(n_) + 1, 0);
  for (int pass = 0; pass < 2; pass++) {
    std::vector<uint32_t> fill; /* the next free lane of each cell, counted from its first block */
    if (pass == 1) {
      start_.assign(count.size(), 0);
      for (size_t c = 1; c < count.size(); c++) {
        start_[c] = start_[c - 1] + (count[c - 1] + kTubeLanes - 1) / kTubeLanes;
      }
      TubeBlock empty{};
      std::fill(std::begin(empty.fiber), std::end(empty.fiber), -1);
      blocks_.assign(start_.back(), empty);
      fill.assign(count.size() - 1, 0);
      entries_ = std::accumulate(count.begin(), count.end(), size_t(0));
    }
    for (const Chord &ch : chords) {
      if (!(ch.a.x == anchor)) {
        throw std::invalid_argument("TubeGrid: a chord does not start on its slab's anchor plane");
      }
      const double rp = ch.capsule_radius;
      const int y0 = cell_index(float(std::min(ch.y0, ch.y1) - rp)), y1 = cell_index(float(std::max(ch.y0, ch.y1) + rp));
      const int z0 = cell_index(float(std::min(ch.z0, ch.z1) - rp)), z1 = cell_index(float(std::max(ch.z0, ch.z1) + rp));
      const double sy = ch.y1 - ch.y0, sz = ch.z1 - ch.z0;
      const double len2 = sy * sy + sz * sz;
      const double half_diagonal = 0.5 * std::sqrt(2.0) * double(cell_);
      for (int iz = z0; iz <= z1; iz++) {
        for (int iy = y0; iy <= y1; iy++) {
          /* Only cells the capsule can touch: centre within capsule radius + half the cell diagonal of the
           * projected chord (conservative). */
          const double cy = (iy + 0.5) * double(cell_) - double(bound_), cz = (iz + 0.5) * double(cell_) - double(bound_);
          const double t = len2 > 0.0 ? std::clamp(((cy - ch.y0) * sy + (cz - ch.z0) * sz) / len2, 0.0, 1.0) : 0.0;
          const double ey = cy - (ch.y0 + t * sy), ez = cz - (ch.z0 + t * sz);
          if (std::sqrt(ey * ey + ez * ez) > rp + half_diagonal) {
            continue;
          }
          const size_t c = size_t(iz) * size_t(n_) + size_t(iy);
          if (pass == 0) {
            count[c]++;
          }
          else {
            /* Lanes in the order the chords come, as the scalar test visited them: the first of equal
             * distances wins either way. */
            TubeBlock &b = blocks_[start_[c] + fill[c] / kTubeLanes];
            const int lane = int(fill[c] % kTubeLanes);
            b.ay[lane] = ch.a.y, b.az[lane] = ch.a.z;
            b.ux[lane] = ch.axis.x, b.uy[lane] = ch.axis.y, b.uz[lane] = ch.axis.z;
            b.fiber[lane] = ch.fiber;
            fill[c]++;
          }
        }
      }
    }
  }
}

float TubeGrid::nearest(Vec3 o, Vec3 d, float t_end, int exclude, float travelled, float exclude_distance,
                        int *fiber) const
{
  float best = std::min(t_end, kInf);
  int best_fiber = -1;
  int iy = std::clamp(int((o.y + bound_) * inv_cell_), 0, n_ - 1); /* >= 0 up to rounding: cast = floor */
  int iz = std::clamp(int((o.z + bound_) * inv_cell_), 0, n_ - 1);
  const int step_y = d.y > 0.0f ? 1 : -1;
  const int step_z = d.z > 0.0f ? 1 : -1;
  const float inv_dy = d.y != 0.0f ? 1.0f / d.y : kInf;
  const float inv_dz = d.z != 0.0f ? 1.0f / d.z : kInf;
  float next_y = d.y != 0.0f ? ((float(iy + (step_y > 0)) * cell_ - bound_) - o.y) * inv_dy : kInf;
  float next_z = d.z != 0.0f ? ((float(iz + (step_z > 0)) * cell_ - bound_) - o.z) * inv_dz : kInf;
  const float delta_y = std::abs(cell_ * inv_dy);
  const float delta_z = std::abs(cell_ * inv_dz);
  const LanesF ox = splat<LanesF>(o.x), oy = splat<LanesF>(o.y), oz = splat<LanesF>(o.z);
  /* Every chord starts on the anchor plane (the constructor checks it): w.x = o.x - anchor for all lanes. */
  const LanesF wx = splat<LanesF>(o.x - anchor_);
  const LanesF dx = splat<LanesF>(d.x), dy = splat<LanesF>(d.y), dz = splat<LanesF>(d.z);
  const LanesF r2 = splat<LanesF>(r_ * r_), inf = splat<LanesF>(kInf);
  const LanesF slab_start = splat<LanesF>(x0_), slab_end = splat<LanesF>(x1_);
  const LanesF travelled_lanes = splat<LanesF>(travelled), exclude_lanes_distance = splat<LanesF>(exclude_distance);
  LanesI exclude_lanes;
  for (int k = 0; k < kTubeLanes; k++) {
    exclude_lanes[k] = exclude;
  }
  for (;;) {
    const size_t c = size_t(iz) * size_t(n_) + size_t(iy);
    for (uint32_t k = start_[c]; k < start_[c + 1]; k++) {
      /* tube_entry on a block of tubes; +inf in the padding lanes. */
      const TubeBlock &b = blocks_[k];
      const LanesI lane_fiber = load<LanesI>(b.fiber);
      const LanesF t = lane_fiber >= 0 ? tube_entry_lanes(wx, oy - load<LanesF>(b.ay),
                                                          oz - load<LanesF>(b.az), load<LanesF>(b.ux),
                                                          load<LanesF>(b.uy), load<LanesF>(b.uz), dx, dy, dz, r2)
                                       : inf;
      /* A lane counts if it is nearer than the best so far, not the excluded fiber within its distance, and
       * in this slab's x range (beyond it the tube belongs to the neighbouring slab's chord). Decided for all
       * lanes at once: one branch per block instead of three per lane. */
      const LanesF x = ox + t * dx;
      const LanesI nearer = t < splat<LanesF>(best);
      const LanesI excluded = (lane_fiber == exclude_lanes) & (travelled_lanes + t < exclude_lanes_distance);
      const LanesI valid = nearer & ~excluded & ~(x < slab_start) & ~(x > slab_end);
      if (!any_lane(valid)) {
        continue;
      }
      /* The nearest valid lane, the first of equal ones (as a scan in lane order that takes only a strictly
       * nearer tube would). */
      const LanesF tv = valid ? t : inf;
      float nearest = tv[0];
      for (int lane = 1; lane < kTubeLanes; lane++) {
        nearest = std::min(nearest, tv[lane]);
      }
      int lane = 0;
      while (!(tv[lane] == nearest)) {
        lane++;
      }
      best = nearest;
      best_fiber = lane_fiber[lane];
    }
    const float t_cell_exit = std::min(next_y, next_z);
    if (best <= t_cell_exit || t_cell_exit >= t_end) {
      break;
    }
    if (next_y < next_z) {
      iy += step_y;
      next_y += delta_y;
      if (iy < 0 || iy >= n_) {
        break;
      }
    }
    else {
      iz += step_z;
      next_z += delta_z;
      if (iz < 0 || iz >= n_) {
        break;
      }
    }
  }
  *fiber = best_fiber;
  return best;
}

}  // namespace neuralyarn::rdm
