// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/yarn_grid_tracer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "neuralyarn/presets.h"

namespace neuralyarn::rdm {

using ny::Vec3;
using ny::make_vec3;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/* The largest curvature of the yarn's fibers, sampled over the structure's period. */
double max_fiber_curvature(const geometry::Yarn &yarn)
{
  const int K = yarn.num_plies(), N = int(yarn.cross_section(0).centers.size());
  const double length = yarn.sampling_length(), h = 1e-3 * yarn.params().ply.R;
  const int samples = 64;
  double kappa = 0.0;
  for (int k = 0; k < K; k++) {
    for (int i = 0; i < N; i++) {
      for (int s = 0; s < samples; s++) {
        const double x = length * (s + 0.5) / samples;
        const Eigen::Vector3d a = yarn.fiber_point(k, i, x - h), b = yarn.fiber_point(k, i, x),
                              c = yarn.fiber_point(k, i, x + h);
        const Eigen::Vector3d d1 = (c - a) / (2.0 * h), d2 = (c - 2.0 * b + a) / (h * h);
        kappa = std::max(kappa, d1.cross(d2).norm() / std::pow(d1.norm(), 3));
      }
    }
  }
  return kappa;
}

/* The parameter u at which fiber (k, i) crosses the plane x = X: its points' x is u plus the fiber's offset
 * along the tilted ply cross-section, monotonic in u (the fibers never turn back along the axis). Newton's
 * steps with a central difference from `guess`. */
double crossing(const geometry::Yarn &yarn, int k, int i, double X, double guess)
{
  const double h = 1e-6 * yarn.params().ply.R;
  double u = guess;
  for (int it = 0; it < 20; it++) {
    const double f = yarn.fiber_point(k, i, u).x() - X;
    if (std::abs(f) <= 1e-13 * (1.0 + std::abs(X))) {
      return u;
    }
    const double df = (yarn.fiber_point(k, i, u + h).x() - yarn.fiber_point(k, i, u - h).x()) / (2.0 * h);
    u -= f / df;
  }
  /* A fiber that turns back along the axis is no yarn geometry.h builds: say so rather than tube a wrong chord. */
  throw std::runtime_error("YarnSlabs: fiber " + std::to_string(i) + " of ply " + std::to_string(k) +
                           " does not cross the plane x = " + std::to_string(X) + " once");
}

}  // namespace

bool fibers_advance_along_axis(const geometry::Yarn &yarn)
{
  const int K = yarn.num_plies(), N = int(yarn.cross_section(0).centers.size());
  const double length = yarn.sampling_length(), h = 1e-4 * yarn.params().ply.R;
  const int samples = 64;
  for (int k = 0; k < K; k++) {
    for (int i = 0; i < N; i++) {
      for (int s = 0; s < samples; s++) {
        const double u = length * (s + 0.5) / samples;
        /* dx/du, with a margin: a fiber nearly normal to the axis would need slabs shorter than its crossing's
         * Newton steps resolve. */
        if ((yarn.fiber_point(k, i, u + h).x() - yarn.fiber_point(k, i, u - h).x()) / (2.0 * h) < 0.05) {
          return false;
        }
      }
    }
  }
  return true;
}

YarnSlabs::YarnSlabs(const geometry::Yarn &yarn, double half_length, const TracerOptions &options)
    : R_(float(yarn.yarn_radius())), r_(float(yarn.cross_section(0).r)), half_(half_length)
{
  if (!(half_length > 0.0) || !std::isfinite(half_length)) {
    throw ParameterError("half_length", "the explicit yarn's half length must be positive and finite (got " +
                                            std::to_string(half_length) + ")");
  }
  const double r = yarn.cross_section(0).r, R = yarn.yarn_radius();
  const int K = yarn.num_plies(), N = int(yarn.cross_section(0).centers.size());
  fibers_ = K * N;
  /* Slabs as short as the sagitta asks for the most curved fiber (at most two yarn radii). */
  const double kappa = max_fiber_curvature(yarn);
  const double L_max = kappa > 0.0 ? std::sqrt(8.0 * options.sagitta * r / kappa) : 2.0 * R;
  const int S = std::max(1, int(std::ceil(2.0 * half_length / std::min(L_max, 2.0 * R))));
  L_ = float(2.0 * half_length / S);
  planes_.resize(size_t(S) + 1);
  std::vector<double> X(size_t(S) + 1);
  for (int j = 0; j <= S; j++) {
    X[size_t(j)] = -half_length + 2.0 * half_length * j / S;
    planes_[size_t(j)] = float(X[size_t(j)]);
  }
  /* Each fiber's points on the planes (exactly on them, in double), then the chords between them. */
  std::vector<Eigen::Vector3d> points(size_t(S + 1) * size_t(fibers_));
  for (int k = 0; k < K; k++) {
    for (int i = 0; i < N; i++) {
      double u = X[0];
      for (int j = 0; j <= S; j++) {
        u = crossing(yarn, k, i, X[size_t(j)], j == 0 ? u : u + (X[size_t(j)] - X[size_t(j) - 1]));
        Eigen::Vector3d p = yarn.fiber_point(k, i, u);
        p.x() = X[size_t(j)];
        points[size_t(j) * size_t(fibers_) + size_t(k * N + i)] = p;
      }
    }
  }
  auto chord = [&](int j, int f) {
    return make_chord(f, points[size_t(j) * size_t(fibers_) + size_t(f)].data(),
                      points[size_t(j + 1) * size_t(fibers_) + size_t(f)].data(), r, R);
  };
  /* The grids span the bounding cylinder: first how far the tubes reach (only those near the envelope can pass
   * it), then the grids slab by slab, so that one slab's chords are held at a time. */
  double bound = R * (1.0 + 1e-4);
  for (int j = 0; j < S; j++) {
    for (int f = 0; f < fibers_; f++) {
      const Eigen::Vector3d &p0 = points[size_t(j) * size_t(fibers_) + size_t(f)];
      const Eigen::Vector3d &p1 = points[size_t(j + 1) * size_t(fibers_) + size_t(f)];
      if (std::max(std::hypot(p0.y(), p0.z()), std::hypot(p1.y(), p1.z())) > R - 3.0 * r) {
        bound = std::max(bound, clipped_tube_reach(chord(j, f), r, X[size_t(j)], X[size_t(j) + 1], 8) + 1e-2 * r);
      }
    }
  }
  bound_ = float(bound);
  const double cell = std::max(options.cell_size * r, 1e-6 * R);
  chord_a_.resize(size_t(S) * size_t(fibers_));
  chord_axis_.resize(chord_a_.size());
  grids_.reserve(size_t(S));
  std::vector<Chord> chords(static_cast<size_t>(fibers_));
  for (int j = 0; j < S; j++) {
    for (int f = 0; f < fibers_; f++) {
      chords[size_t(f)] = chord(j, f);
      chord_a_[size_t(j) * size_t(fibers_) + size_t(f)] = chords[size_t(f)].a;
      chord_axis_[size_t(j) * size_t(fibers_) + size_t(f)] = chords[size_t(f)].axis;
    }
    grids_.emplace_back(chords, r_, bound_, planes_[size_t(j)], planes_[size_t(j) + 1], cell);
  }
}

float YarnSlabs::intersect_chord(int slab, int fiber, Vec3 o, Vec3 d) const
{
  Chord c;
  c.a = chord_a_[size_t(slab) * size_t(fibers_) + size_t(fiber)];
  c.axis = chord_axis_[size_t(slab) * size_t(fibers_) + size_t(fiber)];
  return tube_entry(c, o, d, r_ * r_);
}

float YarnSlabs::distance_from_chord(int slab, int fiber, Vec3 p) const
{
  const size_t c = size_t(slab) * size_t(fibers_) + size_t(fiber);
  return ny::length(chord_radial(chord_a_[c], chord_axis_[c], p));
}

bool YarnSlabs::trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const
{
  const int S = int(grids_.size());
  Vec3 o = ray->o;
  const Vec3 d = ray->d;
  float travelled = 0.0f;
  float t_cyl = cylinder_exit(o, d, bound_);
  /* The slab the origin is in; outside the fibers' range, the face the ray enters it through, if any. */
  int j;
  if (o.x < planes_.front() || o.x > planes_.back()) {
    const bool below = o.x < planes_.front();
    if (below ? !(d.x > 0.0f) : !(d.x < 0.0f)) {
      j = -1;
    }
    else {
      const float t = std::max(((below ? planes_.front() : planes_.back()) - o.x) / d.x, 0.0f);
      if (t >= t_cyl) {
        j = -1;
      }
      else {
        o = o + d * t;
        o.x = below ? planes_.front() : planes_.back();
        travelled = t;
        t_cyl = std::max(t_cyl - t, 0.0f);
        j = below ? 0 : S - 1;
      }
    }
  }
  else {
    j = std::clamp(int(std::floor((o.x - planes_.front()) / L_)), 0, S - 1);
    while (j > 0 && o.x < planes_[size_t(j)]) {
      j--;
    }
    while (j < S - 1 && o.x > planes_[size_t(j) + 1]) {
      j++;
    }
  }
  while (j >= 0 && j < S) {
    const float x0 = planes_[size_t(j)], x1 = planes_[size_t(j) + 1];
    float t_slab = kInf;
    if (d.x > 0.0f) {
      t_slab = (x1 - o.x) / d.x;
    }
    else if (d.x < 0.0f) {
      t_slab = (x0 - o.x) / d.x;
    }
    t_slab = std::max(t_slab, 0.0f);
    int fiber = -1;
    const float t = grids_[size_t(j)].nearest(o, d, std::min(t_slab, t_cyl), exclude, travelled, exclude_distance, &fiber);
    if (fiber >= 0) {
      const size_t c = size_t(j) * size_t(fibers_) + size_t(fiber);
      const Vec3 p = o + d * t;
      hit->t = travelled + t;
      hit->fiber = fiber;
      hit->point = p;
      hit->normal = ny::normalize(chord_radial(chord_a_[c], chord_axis_[c], p));
      hit->axis = chord_axis_[c];
      ray->o = p;
      return true;
    }
    if (t_cyl <= t_slab) {
      break;
    }
    travelled += t_slab;
    t_cyl = std::max(t_cyl - t_slab, 0.0f);
    o = o + d * t_slab;
    o.x = d.x > 0.0f ? x1 : x0;
    j += d.x > 0.0f ? 1 : -1;
    ray->slab += d.x > 0.0f ? 1 : -1; /* the gather's count of slab crossings */
  }
  /* No fiber: the path leaves through the bounding cylinder (or, running along the axis past an end, stays
   * where it is). */
  if (std::isfinite(t_cyl)) {
    o = o + d * t_cyl;
  }
  ray->o = o;
  return false;
}

namespace {
/* The mirror image (x, y, z) -> (-x, y, -z): a turn by pi about the y axis. */
Vec3 mirror(Vec3 v) { return make_vec3(-v.x, v.y, -v.z); }
}  // namespace

bool YarnGridTracer::trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const
{
  if (!mirrored_) {
    return slabs_->trace(ray, exclude, exclude_distance, hit);
  }
  SlabRay r = *ray;
  r.o = mirror(r.o);
  r.d = mirror(r.d);
  const bool found = slabs_->trace(&r, exclude, exclude_distance, hit);
  ray->o = mirror(r.o);
  ray->slab = r.slab;
  if (found) {
    hit->point = mirror(hit->point);
    hit->normal = mirror(hit->normal);
    hit->axis = -mirror(hit->axis); /* +x-ward */
  }
  return found;
}

void YarnGridTracer::leave_fiber(const TubeHit &hit, Vec3 d, SlabRay *ray) const
{
  /* Into the fiber: the tracer reports entries only, so the path crosses it (D32). */
  ray->o = hit.point;
  ray->d = d;
}

}  // namespace neuralyarn::rdm
