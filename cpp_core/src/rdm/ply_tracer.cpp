// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/ply_tracer.h"
#include "neuralyarn/units.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include <Eigen/Geometry>

namespace neuralyarn::rdm {

using ny::Vec3;
using ny::make_vec3;

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}

PlyTracer::PlyTracer(const geometry::Ply &ply, const TracerOptions &options)
{
  R_ = float(ply.params().R);
  r_ = float(ply.fiber_radius());
  w_ = ply.twist_rate();
  const double R = ply.params().R;
  const double r = ply.fiber_radius();
  if (w_ > 0.0) {
    const double kappa_max = w_ * w_ * R / (1.0 + w_ * w_ * R * R);
    L_ = float(std::min(std::sqrt(8.0 * options.sagitta * r / kappa_max), ply.pitch()));
  }
  else {
    /* Straight fibers: any slab length is exact; a few radii keeps slab crossings rare and the
     * canonical x small. */
    L_ = float(4.0 * R);
  }
  rot_c_ = float(std::cos(w_ * double(L_)));
  rot_s_ = float(std::sin(w_ * double(L_)));

  /* Chords in double, then stored in float. */
  const int N = ply.num_fibers();
  fibers_.resize(size_t(N));
  std::vector<Eigen::Vector4d> capsule(static_cast<size_t>(N)); /* projected chord (y0, z0, y1, z1) */
  std::vector<double> capsule_radius(static_cast<size_t>(N));
  std::vector<float> ymin(static_cast<size_t>(N)), ymax(static_cast<size_t>(N)), zmin(static_cast<size_t>(N)),
      zmax(static_cast<size_t>(N));
  for (int i = 0; i < N; i++) {
    const Eigen::Vector3d p0 = ply.fiber_point(i, 0.0);
    const Eigen::Vector3d p1 = ply.fiber_point(i, double(L_));
    const Eigen::Vector3d axis = (p1 - p0).normalized();
    fibers_[size_t(i)].a = make_vec3(float(p0.x()), float(p0.y()), float(p0.z()));
    fibers_[size_t(i)].axis = make_vec3(float(axis.x()), float(axis.y()), float(axis.z()));
    /* Projected tube: capsule around the projected chord with radius r / cos(tilt). Slightly inflated so
     * that float rounding in the DDA can never lose a candidate. */
    const double rp = r / std::max(std::abs(axis.x()), 1e-6) * 1.001 + 1e-6 * R;
    capsule[size_t(i)] = Eigen::Vector4d(p0.y(), p0.z(), p1.y(), p1.z());
    capsule_radius[size_t(i)] = rp;
    ymin[size_t(i)] = float(std::min(p0.y(), p1.y()) - rp);
    ymax[size_t(i)] = float(std::max(p0.y(), p1.y()) + rp);
    zmin[size_t(i)] = float(std::min(p0.z(), p1.z()) - rp);
    zmax[size_t(i)] = float(std::max(p0.z(), p1.z()) + rp);
  }

  /* Bounding radius: the largest distance from the axis that any clipped chord tube reaches (its x-slices
   * are ellipses stretched along the projected chord, which can poke a hair beyond R for fibers touching
   * the ply surface), sampled densely, plus a margin. Entry points then never start inside a tube. */
  double bound = R;
  for (int i = 0; i < N; i++) {
    const Vec3 a = fibers_[size_t(i)].a, ax = fibers_[size_t(i)].axis;
    const Eigen::Vector3d A(a.x, a.y, a.z), D(ax.x, ax.y, ax.z);
    /* Basis of the plane perpendicular to the axis. */
    const Eigen::Vector3d e1 = D.unitOrthogonal(), e2 = D.cross(e1);
    /* Perpendicular circles centred on the axis from x = -2r to L + 2r; the points with x in [0, L] belong
     * to the clipped tube. */
    for (int k = 0; k <= 32; k++) {
      const double x = -2.0 * r + (double(L_) + 4.0 * r) * k / 32.0;
      const Eigen::Vector3d c = A + D * (x / D.x());
      for (int j = 0; j < 64; j++) {
        const double t = 2.0 * kPi * j / 64.0;
        const Eigen::Vector3d q = c + r * (std::cos(t) * e1 + std::sin(t) * e2);
        if (q.x() >= 0.0 && q.x() <= double(L_)) {
          bound = std::max(bound, std::hypot(q.y(), q.z()));
        }
      }
    }
  }
  /* The sampling above can miss the true maximum by r (1 - cos(pi / 64)) ~ 1.2e-3 r; 1 % of r covers it. */
  bound_ = float(bound + 1e-2 * r);

  cell_ = float(std::max(options.cell_size * r, 1e-6 * R));
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
    for (int i = 0; i < N; i++) {
      const int y0 = cell_index(ymin[size_t(i)]), y1 = cell_index(ymax[size_t(i)]);
      const int z0 = cell_index(zmin[size_t(i)]), z1 = cell_index(zmax[size_t(i)]);
      const Eigen::Vector4d &cap = capsule[size_t(i)];
      const Eigen::Vector2d s0(cap[0], cap[1]), s1(cap[2], cap[3]);
      const double half_diagonal = 0.5 * std::sqrt(2.0) * double(cell_);
      for (int iz = z0; iz <= z1; iz++) {
        for (int iy = y0; iy <= y1; iy++) {
          /* Only cells the capsule can touch: centre within capsule radius + half the cell diagonal of the
           * projected chord (conservative). */
          const Eigen::Vector2d centre((iy + 0.5) * double(cell_) - double(bound_), (iz + 0.5) * double(cell_) - double(bound_));
          const Eigen::Vector2d seg = s1 - s0;
          const double len2 = seg.squaredNorm();
          const double t = len2 > 0.0 ? std::clamp((centre - s0).dot(seg) / len2, 0.0, 1.0) : 0.0;
          if ((centre - (s0 + t * seg)).norm() > capsule_radius[size_t(i)] + half_diagonal) {
            continue;
          }
          const size_t c = size_t(iz) * size_t(n_) + size_t(iy);
          if (pass == 0) {
            count[c]++;
          }
          else {
            /* Lanes in the order the fibers come, as the scalar test visited them: the first of equal
             * distances wins either way. */
            TubeBlock &b = blocks_[start_[c] + fill[c] / kTubeLanes];
            const int lane = int(fill[c] % kTubeLanes);
            const Tube &f = fibers_[size_t(i)];
            b.ax[lane] = f.a.x, b.ay[lane] = f.a.y, b.az[lane] = f.a.z;
            b.ux[lane] = f.axis.x, b.uy[lane] = f.axis.y, b.uz[lane] = f.axis.z;
            b.fiber[lane] = i;
            fill[c]++;
          }
        }
      }
    }
  }
}

void PlyTracer::rotate_yz(Vec3 *v, float c, float s) const
{
  const float y = c * v->y - s * v->z;
  const float z = s * v->y + c * v->z;
  v->y = y;
  v->z = z;
}

void PlyTracer::canonicalize(SlabRay *ray) const
{
  if (ray->o.x >= 0.0f && ray->o.x <= L_) {
    return;
  }
  const double k = std::floor(double(ray->o.x) / double(L_));
  ray->o.x = float(double(ray->o.x) - k * double(L_));
  ray->o.x = std::clamp(ray->o.x, 0.0f, L_);
  const double angle = -w_ * double(L_) * k;
  const float c = float(std::cos(angle)), s = float(std::sin(angle));
  rotate_yz(&ray->o, c, s);
  rotate_yz(&ray->d, c, s);
  ray->slab += int64_t(k);
}

Vec3 PlyTracer::to_world_point(Vec3 p, int64_t slab) const
{
  const double X = double(slab) * double(L_);
  const double angle = std::fmod(w_ * X, 2.0 * kPi);
  const double c = std::cos(angle), s = std::sin(angle);
  return make_vec3(float(double(p.x) + X), float(c * p.y - s * p.z), float(s * p.y + c * p.z));
}

Vec3 PlyTracer::to_world_dir(Vec3 d, int64_t slab) const
{
  const double angle = std::fmod(w_ * double(slab) * double(L_), 2.0 * kPi);
  const double c = std::cos(angle), s = std::sin(angle);
  return make_vec3(d.x, float(c * d.y - s * d.z), float(s * d.y + c * d.z));
}

namespace {
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
inline F tube_entry(F wx, F wy, F wz, F ux, F uy, F uz, F dx, F dy, F dz, F r2)
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

float PlyTracer::intersect_tube(const Tube &f, Vec3 o, Vec3 d) const
{
  const Vec3 w = o - f.a;
  return tube_entry(w.x, w.y, w.z, f.axis.x, f.axis.y, f.axis.z, d.x, d.y, d.z, r_ * r_);
}

void PlyTracer::leave_fiber(const TubeHit &hit, Vec3 d, SlabRay *ray) const
{
  ray->o = hit.point;
  ray->d = d;
  canonicalize(ray);
}

float PlyTracer::nearest_in_slab(Vec3 o, Vec3 d, float t_end, int exclude, float travelled, float exclude_distance,
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
  const LanesF dx = splat<LanesF>(d.x), dy = splat<LanesF>(d.y), dz = splat<LanesF>(d.z);
  const LanesF r2 = splat<LanesF>(r_ * r_), inf = splat<LanesF>(kInf);
  const LanesF zero = splat<LanesF>(0.0f), slab_end = splat<LanesF>(L_);
  const LanesF travelled_lanes = splat<LanesF>(travelled), exclude_lanes_distance = splat<LanesF>(exclude_distance);
  LanesI exclude_lanes;
  for (int k = 0; k < kTubeLanes; k++) {
    exclude_lanes[k] = exclude;
  }
  for (;;) {
    const size_t c = size_t(iz) * size_t(n_) + size_t(iy);
    for (uint32_t k = start_[c]; k < start_[c + 1]; k++) {
      /* intersect_tube on a block of tubes; +inf in the padding lanes. */
      const TubeBlock &b = blocks_[k];
      const LanesI lane_fiber = load<LanesI>(b.fiber);
      const LanesF t = lane_fiber >= 0 ? tube_entry(ox - load<LanesF>(b.ax), oy - load<LanesF>(b.ay),
                                                    oz - load<LanesF>(b.az), load<LanesF>(b.ux), load<LanesF>(b.uy),
                                                    load<LanesF>(b.uz), dx, dy, dz, r2)
                                       : inf;
      /* A lane counts if it is nearer than the best so far, not the excluded fiber within its distance, and
       * in this slab's x range (beyond it the tube belongs to the neighbouring slab's chord). Decided for all
       * lanes at once: one branch per block instead of three per lane. */
      const LanesF x = ox + t * dx;
      const LanesI nearer = t < splat<LanesF>(best);
      const LanesI excluded = (lane_fiber == exclude_lanes) & (travelled_lanes + t < exclude_lanes_distance);
      const LanesI valid = nearer & ~excluded & ~(x < zero) & ~(x > slab_end);
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

void PlyTracer::cross_slab(SlabRay *ray, float t_slab) const
{
  Vec3 p = ray->o + ray->d * t_slab;
  if (ray->d.x > 0.0f) {
    p.x = 0.0f;
    rotate_yz(&p, rot_c_, -rot_s_);
    rotate_yz(&ray->d, rot_c_, -rot_s_);
    ray->slab += 1;
  }
  else {
    p.x = L_;
    rotate_yz(&p, rot_c_, rot_s_);
    rotate_yz(&ray->d, rot_c_, rot_s_);
    ray->slab -= 1;
  }
  /* Keep the direction unit length over thousands of float rotations. */
  ray->d = ny::normalize(ray->d);
  ray->o = p;
}

bool PlyTracer::trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const
{
  float travelled = 0.0f;
  /* Leaving the bounding cylinder (the origin is inside or on it): the far root. Slab crossings rotate the
   * ray about the axis, which keeps its distance to the cylinder: computed once, counted down. */
  float t_cyl = cylinder_exit(ray->o, ray->d, bound_);
  for (;;) {
    const Vec3 o = ray->o;
    const Vec3 d = ray->d;
    /* Leaving the slab. */
    float t_slab = kInf;
    if (d.x > 0.0f) {
      t_slab = (L_ - o.x) / d.x;
    }
    else if (d.x < 0.0f) {
      t_slab = -o.x / d.x;
    }
    t_slab = std::max(t_slab, 0.0f);
    int fiber = -1;
    const float t = nearest_in_slab(o, d, std::min(t_slab, t_cyl), exclude, travelled, exclude_distance, &fiber);
    if (fiber >= 0) {
      const Tube &f = fibers_[size_t(fiber)];
      const Vec3 p = o + d * t;
      const Vec3 w = p - f.a;
      const Vec3 wp = w - f.axis * ny::dot(w, f.axis);
      hit->t = travelled + t;
      hit->fiber = fiber;
      hit->point = p;
      hit->normal = ny::normalize(wp);
      hit->axis = f.axis;
      ray->o = p;
      return true;
    }
    if (t_cyl <= t_slab) {
      ray->o = o + d * t_cyl;
      return false;
    }
    travelled += t_slab;
    t_cyl = std::max(t_cyl - t_slab, 0.0f);
    cross_slab(ray, t_slab);
  }
}

}  // namespace neuralyarn::rdm
