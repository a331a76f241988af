// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/bent_ply.h"

#include <algorithm>
#include <cmath>
#include <limits>
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

BentPlies::BentPlies(const std::vector<geometry::Ply> &plies, const Bend &bend) : bend_(bend)
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

bool BentPlies::trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const
{
  const Vec3 o = ray->o, d = ray->d;
  /* The nearest fiber first, then the exit only as far as it: a path's rays mostly end on a fiber a few fiber radii
   * on, and tracing the tube up to there is cheaper than finding where the ray would leave it. */
  EmbreeHit h;
  const bool got = curves_->intersect(o, d, 0.0f, std::numeric_limits<float>::infinity(), &h, exclude,
                                      exclude_distance, /*cull_exits=*/true);
  const float t_exit = exit_distance(o, d, got ? h.t : std::numeric_limits<float>::infinity());
  if (got && !(t_exit < h.t)) {
    hit->t = h.t;
    hit->fiber = h.fiber;
    hit->point = o + d * h.t;
    hit->normal = h.radial_normal();
    hit->axis = h.tangent; /* every fiber runs the way the ply does (increasing x or angle) */
    ray->o = hit->point;
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

RdmMaps gather_bent(const FiberPreset &preset, const Bend &bend, const GatherOptions &options)
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
  const BentPlies medium(plies, bend), mirror(mirrors, bend);
  GatherOptions one = options;
  one.layouts = 1; /* the media hold the cross-sections side by side */
  RdmMaps maps = gather_through(preset, geometry::YarnStructure{}, one, medium, mirror);
  maps.layouts = options.layouts;
  maps.intersector = "embree";
  return maps;
}

}  // namespace neuralyarn::rdm
