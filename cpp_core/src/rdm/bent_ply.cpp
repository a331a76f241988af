// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/bent_ply.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "neuralyarn/units.h"

namespace neuralyarn::rdm {

using ny::Vec3;
using ny::make_vec3;

void validate(const Bend &bend)
{
  if (!std::isfinite(bend.radius) || bend.radius < 0.0 || (bend.radius > 0.0 && bend.radius < kMinBendRadius)) {
    throw ParameterError("radius", "a bend's radius is 0 (straight) or at least " + std::to_string(kMinBendRadius) +
                                       " ply radii (tighter folds the tube onto itself), got " +
                                       std::to_string(bend.radius));
  }
  if (bend.sectors < 1 || bend.sector < 0 || bend.sector >= bend.sectors) {
    throw ParameterError("sector", "sector k of K needs 0 <= k < K, got " + std::to_string(bend.sector) + " of " +
                                       std::to_string(bend.sectors));
  }
}

BentPlies::BentPlies(const std::vector<geometry::Ply> &plies, const Bend &bend, BentIntersector intersector,
                     const TracerOptions &options)
    : bend_(bend)
{
  validate(bend);
  if (plies.empty()) {
    throw ParameterError("layouts", "a bent medium needs at least one ply");
  }
  const double Rc = bend.radius;
  r_ = float(plies[0].fiber_radius());
  /* Tubes reach 1 exactly at the envelope; a hair more keeps entry points outside every tube. */
  bound_ = 1.0f + 1e-4f;
  spacing_ = 4.0 + 2.0 * Rc;
  /* Straight: long enough that paths entering over the middle third do not reach the ends. */
  length_ = Rc > 0.0 ? 2.0 * kPi * Rc : 48.0;
  entry_ = Rc > 0.0 ? kPi * Rc : length_ / 3.0;
  plies_ = int(plies.size());
  fibers_ = plies[0].num_fibers();
  if (intersector == BentIntersector::kWedges && Rc > 0.0) {
    build_wedges(plies, options);
    return;
  }
  geometry::CurveSet curves;
  for (int k = 0; k < plies_; k++) {
    const geometry::Ply &ply = plies[size_t(k)];
    const double turns = length_ * ply.twist_rate() / (2.0 * kPi);
    /* 64 chords a helix turn and 20 a ply radius: the bend's sagitta over a chord is below 1e-4 radii. */
    const int segments = int(std::max(std::ceil(turns * 64.0), std::ceil(length_ * 20.0)));
    for (int i = 0; i < ply.num_fibers(); i++) {
      curves.offsets.push_back(int(curves.points.size()));
      curves.radii.push_back(r_);
      for (int s = 0; s <= segments; s++) {
        curves.points.push_back(place(ply.fiber_point(i, length_ * s / segments), k).cast<float>());
      }
    }
  }
  curves.offsets.push_back(int(curves.points.size()));
  curves_ = std::make_unique<EmbreePly>(curves, "");
}

namespace {
/* A point or direction of world coordinates in the frame of the wedge whose middle is at the angle of cosine c and
 * sine s about the circle's axis (x along the circle, y outward, z = -z), and back; points relative to the circle's
 * centre and offset by the circle's radius across it. */
template<class T> inline void to_wedge(T c, T s, T x, T y, T z, T *lx, T *ly, T *lz)
{
  *lx = -s * x + c * y;
  *ly = c * x + s * y;
  *lz = -z;
}
inline Vec3 wedge_dir(float c, float s, Vec3 v)
{
  Vec3 l;
  to_wedge(c, s, v.x, v.y, v.z, &l.x, &l.y, &l.z);
  return l;
}
inline Vec3 world_dir(float c, float s, Vec3 l) { return make_vec3(-s * l.x + c * l.y, c * l.x + s * l.y, -l.z); }
}  // namespace

void BentPlies::build_wedges(const std::vector<geometry::Ply> &plies, const TracerOptions &options)
{
  const double Rc = bend_.radius, r = double(r_), w = plies[0].twist_rate();
  sagitta_ = options.sagitta;
  /* Fiber i of circle k on face angle a, in the frame of the wedge whose middle is at angle m. */
  auto point = [&](int k, int i, double a, double m) {
    const Eigen::Vector3d p = place(plies[size_t(k)].fiber_point(i, a * Rc), k);
    Eigen::Vector3d l;
    to_wedge(std::cos(m), std::sin(m), p.x(), p.y(), p.z() - k * spacing_, &l.x(), &l.y(), &l.z());
    l.y() -= Rc;
    return l;
  };
  /* How many wedges: a first guess from chords of length sqrt(8 sagitta r / kappa) for the curvature of a fiber on the
   * bend's inner side plus its twist's, then every chord checked at its fiber's midpoint (a fiber's curvature varies
   * little over a wedge, so that is where it strays furthest) and the wedges made finer until all hold. */
  const double kappa = 1.0 / (Rc - 1.0) + w;
  const double L = std::sqrt(8.0 * options.sagitta * r / kappa);
  int S = std::max(8, int(std::ceil(2.0 * kPi * (Rc + 1.0) * std::sqrt(1.0 + w * w) / L)));
  for (int attempt = 0;; attempt++) {
    const double delta = 2.0 * kPi / S;
    double worst = 0.0;
    for (int k = 0; k < plies_; k++) {
      for (int j = 0; j < S; j++) {
        const double m = (j + 0.5) * delta;
        for (int i = 0; i < fibers_; i++) {
          const Eigen::Vector3d p0 = point(k, i, j * delta, m), p1 = point(k, i, (j + 1) * delta, m);
          const Eigen::Vector3d u = (p1 - p0).normalized(), mid = point(k, i, m, m) - p0;
          worst = std::max(worst, (mid - mid.dot(u) * u).norm() / r);
        }
      }
    }
    wedge_sagitta_ = worst;
    if (worst <= options.sagitta) {
      break;
    }
    if (attempt == 5) {
      throw std::runtime_error("BentPlies: the wedges' chords do not come within the sagitta of their fibers");
    }
    S = int(std::ceil(S * std::sqrt(worst / options.sagitta) * 1.05));
  }
  delta_ = 2.0 * kPi / S;
  for (int j = 0; j <= S; j++) {
    face_c_.push_back(float(std::cos(j * delta_)));
    face_s_.push_back(float(std::sin(j * delta_)));
    if (j < S) {
      mid_c_.push_back(float(std::cos((j + 0.5) * delta_)));
      mid_s_.push_back(float(std::sin((j + 0.5) * delta_)));
    }
  }
  /* Chords on the bend's inner side run outside the fibers by up to the sagitta; entries start beyond them. */
  bound_ = float(1.0 + std::max(1e-4, 2.0 * options.sagitta * r));
  const double half = 0.5 * delta_;
  const float X = float((Rc + double(bound_) + r) * std::sin(half) + r);
  const float grid_bound = float(double(bound_) + (Rc + 1.0) * (1.0 - std::cos(half)) + 0.01 * r);
  const double cell = std::max(options.cell_size * r, 1e-6);
  wedges_.assign(size_t(plies_), Wedges{});
  std::vector<Chord> chords(static_cast<size_t>(fibers_));
  for (int k = 0; k < plies_; k++) {
    Wedges &W = wedges_[size_t(k)];
    W.grids.reserve(size_t(S));
    for (int j = 0; j < S; j++) {
      const double m = (j + 0.5) * delta_;
      for (int i = 0; i < fibers_; i++) {
        const Eigen::Vector3d p0 = point(k, i, j * delta_, m), p1 = point(k, i, (j + 1) * delta_, m);
        const Eigen::Vector3d u = (p1 - p0).normalized();
        /* The chord's line anchored on the wedge's middle plane x = 0; the cells it touches from its ends, each
         * lengthened by 2 r (a tube's end cut by a tilted face reaches past its chord's end). */
        const Eigen::Vector3d a = p0 - (p0.x() / u.x()) * u;
        const Eigen::Vector3d e0 = p0 - 2.0 * r * u, e1 = p1 + 2.0 * r * u;
        Chord c = make_chord(i, e0.data(), e1.data(), r, 1.0);
        c.a = make_vec3(0.0f, float(a.y()), float(a.z()));
        chords[size_t(i)] = c;
        W.a.push_back(c.a);
        W.axis.push_back(c.axis);
      }
      W.grids.emplace_back(chords, r_, grid_bound, -X, X, cell, 0.0f);
    }
  }
}

Eigen::Vector3d BentPlies::place(const Eigen::Vector3d &p, int k) const
{
  if (!(bend_.radius > 0.0)) {
    return {p.x() - 0.5 * length_, p.y(), p.z() + k * spacing_};
  }
  /* (tangent, outward, -z) is right-handed, as (x, y, z) is. */
  const double phi = p.x() / bend_.radius, rho = bend_.radius + p.y();
  return {rho * std::cos(phi), rho * std::sin(phi), -p.z() + k * spacing_};
}

int BentPlies::ply_of(Vec3 p) const { return std::clamp(int(std::lround(p.z / spacing_)), 0, plies_ - 1); }

double BentPlies::inside(const Eigen::Vector3d &p, int k) const
{
  const double z = p.z() - k * spacing_;
  /* sqrt rather than hypot: no overflow at these sizes, and this is the exit's inner loop (hypot cost the bent
   * gather a third of its time). */
  const double rho = bend_.radius > 0.0 ? std::sqrt(p.x() * p.x() + p.y() * p.y()) - bend_.radius : p.y();
  const double across = std::sqrt(rho * rho + z * z);
  return double(bound_) - across;
}

double BentPlies::psi(const Eigen::Vector3d &p, int k) const
{
  const double z = p.z() - k * spacing_;
  return std::atan2(z, std::hypot(p.x(), p.y()) - bend_.radius);
}

EntryFrame BentPlies::entry_frame(double u_around, double u_along) const
{
  const int k = std::min(plies_ - 1, int(u_along * plies_));
  const double u = u_along * plies_ - k;
  const Vec3 offset = make_vec3(0.0f, 0.0f, float(k * spacing_));
  if (!(bend_.radius > 0.0)) {
    EntryFrame e = cylinder_entry(bound_, entry_, u_around, u);
    e.point = e.point + offset;
    return e;
  }
  /* psi with density proportional to 1 + (bound / Rc) cos(psi), the bent tube's area, within the sector (Newton on
   * its CDF, which is increasing: bound < Rc); phi uniform over the half circle opposite the seam at phi = 0. */
  const double kb = double(bound_) / bend_.radius, width = 2.0 * kPi / bend_.sectors;
  const double lo = (bend_.sector - 0.5) * width, hi = lo + width;
  auto cdf = [kb](double x) { return x + kb * std::sin(x); };
  const double target = cdf(lo) + u_around * (cdf(hi) - cdf(lo));
  double psi = lo + u_around * width;
  for (int it = 0; it < 16; it++) {
    psi = std::clamp(psi - (cdf(psi) - target) / (1.0 + kb * std::cos(psi)), lo, hi);
  }
  const double phi = 0.5 * kPi + kPi * u;
  const Vec3 outward = make_vec3(float(std::cos(phi)), float(std::sin(phi)), 0.0f);
  EntryFrame e;
  e.n = outward * float(std::cos(psi)) + make_vec3(0.0f, 0.0f, float(std::sin(psi)));
  e.ex = make_vec3(float(-std::sin(phi)), float(std::cos(phi)), 0.0f);
  e.ey = ny::cross(e.n, e.ex);
  e.point = outward * float(bend_.radius) + e.n * bound_ + offset;
  return e;
}

float BentPlies::exit_distance(Vec3 o, Vec3 d, float t_max) const
{
  const int k = ply_of(o);
  if (!(bend_.radius > 0.0)) {
    return cylinder_exit(make_vec3(o.x, o.y, o.z - float(k * spacing_)), d, bound_);
  }
  /* Sphere tracing (inside() is the distance to the torus's surface), at least 1 % of the radius a step so that a
   * ray starting on the surface moves in, up to t_max; then the step that left, by false position (Illinois: the
   * retained end's value halved, so that both ends move) to a micro-radius. A ray leaving and coming back within
   * one such step (grazing the inner side) is taken as staying in. */
  const Eigen::Vector3d O(o.x, o.y, o.z), D(d.x, d.y, d.z);
  constexpr double kMinStep = 0.01, kTolerance = 1e-7;
  double t = 0.0, f = inside(O, k);
  for (int step = 0; step < 4096 && t < double(t_max); step++) {
    const double t_next = t + std::max(f, kMinStep), f_next = inside(O + t_next * D, k);
    if (f_next < 0.0) {
      if (f < kTolerance) {
        return float(t);
      }
      double lo = t, hi = t_next, f_lo = f, f_hi = f_next;
      int side = 0;
      /* inside() is the exact distance to the surface: a point within kTolerance of it, on the inside, is the exit. */
      for (int it = 0; it < 60 && hi - lo > kTolerance; it++) {
        const double mid = std::clamp(lo + (hi - lo) * f_lo / (f_lo - f_hi), lo, hi);
        const double f_mid = inside(O + mid * D, k);
        if (f_mid >= 0.0) {
          lo = mid, f_lo = f_mid;
          f_hi *= side == 1 ? 0.5 : 1.0;
          side = 1;
          if (f_mid < kTolerance) {
            break;
          }
        }
        else {
          hi = mid, f_hi = f_mid;
          f_lo *= side == -1 ? 0.5 : 1.0;
          side = -1;
        }
      }
      return float(lo);
    }
    t = t_next;
    f = f_next;
  }
  return t < double(t_max) ? float(t) : std::numeric_limits<float>::infinity();
}

bool BentPlies::nearest_in_wedges(Vec3 o, Vec3 d, float t_end, int exclude, float exclude_distance, TubeHit *hit,
                                  int64_t *crossings) const
{
  const int k = ply_of(o);
  const Wedges &W = wedges_[size_t(k)];
  const int S = num_wedges();
  const float cz = float(k * spacing_), Rc = float(bend_.radius);
  /* The wedge the origin is in, by its angle about the circle's axis. */
  float angle = std::atan2(o.y, o.x);
  angle += angle < 0.0f ? float(2.0 * kPi) : 0.0f;
  int j = std::clamp(int(double(angle) / delta_), 0, S - 1);
  float travelled = 0.0f;
  Vec3 p = o;
  /* Within t_end (the box about the tube) a ray crosses the circle's wedges at most once. */
  for (int step = 0; step <= S; step++) {
    /* Leaving the wedge through its face j + 1 (toward larger angles) or its face j. */
    float t_face = std::numeric_limits<float>::infinity();
    int next = j;
    const float a1 = -face_s_[size_t(j) + 1] * d.x + face_c_[size_t(j) + 1] * d.y;
    if (a1 > 0.0f) {
      t_face = std::max(-(-face_s_[size_t(j) + 1] * p.x + face_c_[size_t(j) + 1] * p.y) / a1, 0.0f);
      next = j + 1;
    }
    const float a0 = -face_s_[size_t(j)] * d.x + face_c_[size_t(j)] * d.y;
    if (a0 < 0.0f) {
      const float t0 = std::max(-(-face_s_[size_t(j)] * p.x + face_c_[size_t(j)] * p.y) / a0, 0.0f);
      if (t0 < t_face) {
        t_face = t0;
        next = j - 1;
      }
    }
    const float left = std::max(t_end - travelled, 0.0f);
    const float cm = mid_c_[size_t(j)], sm = mid_s_[size_t(j)];
    Vec3 pl = wedge_dir(cm, sm, make_vec3(p.x, p.y, p.z - cz));
    pl.y -= Rc;
    const Vec3 dl = wedge_dir(cm, sm, d);
    int fiber = -1;
    const float t = W.grids[size_t(j)].nearest(pl, dl, std::min(t_face, left), exclude, travelled, exclude_distance,
                                                &fiber);
    if (fiber >= 0) {
      const size_t c = size_t(j) * size_t(fibers_) + size_t(fiber);
      hit->t = travelled + t;
      hit->fiber = fiber;
      hit->point = p + d * t;
      hit->normal = world_dir(cm, sm, ny::normalize(chord_radial(W.a[c], W.axis[c], pl + dl * t)));
      hit->axis = world_dir(cm, sm, W.axis[c]);
      return true;
    }
    if (left <= t_face) {
      return false;
    }
    travelled += t_face;
    p = p + d * t_face;
    *crossings += next > j ? 1 : -1;
    j = (next + S) % S;
  }
  return false;
}

bool BentPlies::nearest_fiber(Vec3 o, Vec3 d, float t_end, int exclude, float exclude_distance, TubeHit *hit,
                              int64_t *crossings) const
{
  if (!wedges_.empty()) {
    return nearest_in_wedges(o, d, t_end, exclude, exclude_distance, hit, crossings);
  }
  EmbreeHit h;
  if (!curves_->intersect(o, d, 0.0f, t_end, &h, exclude, exclude_distance, /*cull_exits=*/true)) {
    return false;
  }
  hit->t = h.t;
  hit->fiber = h.fiber;
  hit->point = o + d * h.t;
  hit->normal = h.radial_normal();
  hit->axis = h.tangent; /* every fiber runs the way the ply does (increasing x or angle) */
  return true;
}

bool BentPlies::trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const
{
  const Vec3 o = ray->o, d = ray->d;
  /* The nearest fiber first, within the box about the ray's circle (the cylinder of radius Rc + bound about its axis,
   * |z| <= bound: nothing of the tube lies beyond), then the tube's exit only as far as that fiber: a path's rays
   * mostly end on a fiber a few fiber radii on, and tracing the tube up to there is cheaper than finding where the
   * ray would leave it. */
  float t_end = std::numeric_limits<float>::infinity();
  if (bend_.radius > 0.0) {
    const float cz = float(ply_of(o) * spacing_);
    t_end = cylinder_exit(make_vec3(o.z - cz, o.x, o.y), make_vec3(d.z, d.x, d.y), float(bend_.radius) + bound_);
    if (d.z != 0.0f) {
      t_end = std::min(t_end, std::max(((d.z > 0.0f ? bound_ : -bound_) - (o.z - cz)) / d.z, 0.0f));
    }
  }
  TubeHit h;
  const bool got = nearest_fiber(o, d, t_end, exclude, exclude_distance, &h, &ray->slab);
  const float t_exit = exit_distance(o, d, got ? h.t : std::numeric_limits<float>::infinity());
  if (got && !(t_exit < h.t)) {
    *hit = h;
    ray->o = h.point;
    return true;
  }
  if (std::isfinite(t_exit)) {
    ray->o = o + d * t_exit;
  }
  return false;
}

void BentPlies::leave_fiber(const TubeHit &hit, Vec3 d, SlabRay *ray) const
{
  /* Into the fiber: trace() culls the tube's exit, so the path crosses it (D32). */
  ray->o = hit.point;
  ray->d = d;
}

RdmMaps gather_bent(const FiberPreset &preset, const Bend &bend, const GatherOptions &options,
                    BentIntersector intersector)
{
  validate(preset);
  validate(options);
  validate(bend);
  if (bend.radius > 0.0 && options.symmetrize && 2 * bend.sector != bend.sectors && bend.sector != 0) {
    throw ParameterError("sector", "a sector other than the outer or the inner side is not its own half-turn image "
                                   "(psi goes to -psi): gather it unsymmetrised");
  }
  geometry::PlyParams pp;
  pp.N = preset.N;
  pp.rho = preset.rho;
  pp.alpha = preset.alpha;
  pp.R = 1.0;
  std::vector<geometry::Ply> plies, mirrors;
  for (int j = 0; j < options.layouts; j++) {
    const geometry::PlyCrossSection cs = geometry::pack_cross_section(pp, options.packing_seed + uint64_t(j));
    plies.emplace_back(pp, cs);
    mirrors.emplace_back(pp, geometry::mirrored(cs));
  }
  const BentPlies medium(plies, bend, intersector), mirror(mirrors, bend, intersector);
  GatherOptions one = options;
  one.layouts = 1; /* the media hold the cross-sections side by side */
  RdmMaps maps = gather_through(preset, geometry::YarnStructure{}, one, medium, mirror);
  maps.layouts = options.layouts;
  maps.intersector = medium.intersector_name();
  maps.bend_radius = bend.radius;
  maps.bend_sector = bend.sector;
  maps.bend_sectors = bend.sectors;
  maps.sagitta = medium.chord_sagitta();
  return maps;
}

}  // namespace neuralyarn::rdm
