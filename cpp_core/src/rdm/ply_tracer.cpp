// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/ply_tracer.h"
#include "neuralyarn/units.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>

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
  for (int i = 0; i < N; i++) {
    const Eigen::Vector3d p0 = ply.fiber_point(i, 0.0);
    const Eigen::Vector3d p1 = ply.fiber_point(i, double(L_));
    fibers_[size_t(i)] = make_chord(i, p0.data(), p1.data(), r, R);
  }

  /* Bounding radius: the largest distance from the axis that any clipped chord tube reaches (its x-slices
   * are ellipses stretched along the projected chord, which can poke a hair beyond R for fibers touching
   * the ply surface), sampled densely, plus a margin. Entry points then never start inside a tube. */
  double bound = R;
  for (const Chord &c : fibers_) {
    bound = std::max(bound, clipped_tube_reach(c, r, 0.0, double(L_), 32));
  }
  /* The sampling above can miss the true maximum by r (1 - cos(pi / 64)) ~ 1.2e-3 r; 1 % of r covers it. */
  bound_ = float(bound + 1e-2 * r);

  grid_ = TubeGrid(fibers_, r_, bound_, 0.0f, L_, double(float(std::max(options.cell_size * r, 1e-6 * R))));
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

void PlyTracer::leave_fiber(const TubeHit &hit, Vec3 d, SlabRay *ray) const
{
  ray->o = hit.point;
  ray->d = d;
  canonicalize(ray);
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
    const float t = grid_.nearest(o, d, std::min(t_slab, t_cyl), exclude, travelled, exclude_distance, &fiber);
    if (fiber >= 0) {
      const Chord &f = fibers_[size_t(fiber)];
      const Vec3 p = o + d * t;
      hit->t = travelled + t;
      hit->fiber = fiber;
      hit->point = p;
      hit->normal = ny::normalize(chord_radial(f.a, f.axis, p));
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
