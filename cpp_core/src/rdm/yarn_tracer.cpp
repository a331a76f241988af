// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/yarn_tracer.h"
#include "neuralyarn/rdm/yarn_grid_tracer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>


namespace neuralyarn::rdm {

using ny::Vec3;
using ny::make_vec3;

YarnTracer::YarnTracer(const geometry::Yarn &yarn, double entry_length, double half_length, bool mirrored,
                       int segments_per_turn)
    : R_(float(yarn.yarn_radius())), r_(float(yarn.cross_section(0).r)), entry_(entry_length), half_(half_length)
{
  geometry::CurveSet curves = geometry::export_fibers(yarn, -half_length, half_length, segments_per_turn);
  if (mirrored) {
    /* Turned by pi about y: (x, y, z) -> (-x, y, -z). */
    for (Eigen::Vector3f &q : curves.points) {
      q.x() = -q.x();
      q.z() = -q.z();
    }
  }
  curves_ = std::make_unique<EmbreePly>(curves, "");
  /* Tubes reach R exactly at the envelope; a hair more keeps entry points outside every tube. */
  bound_ = R_ * (1.0f + 1e-4f);
}

bool YarnTracer::trace(SlabRay *ray, int exclude, float exclude_distance, TubeHit *hit) const
{
  const Vec3 o = ray->o, d = ray->d;
  EmbreeHit h;
  if (curves_->intersect(o, d, 0.0f, std::numeric_limits<float>::infinity(), &h, exclude, exclude_distance,
                        /*cull_exits=*/true))
  {
    hit->t = h.t;
    hit->fiber = h.fiber;
    hit->point = o + d * h.t;
    hit->normal = h.radial_normal();
    hit->axis = h.tangent.x >= 0.0f ? h.tangent : -h.tangent;
    ray->o = hit->point;
    return true;
  }
  /* No fiber: the path leaves. Move it to where it crosses the bounding cylinder, or, running along the
   * axis, keep it where it is. */
  const float t = cylinder_exit(o, d, bound_);
  if (std::isfinite(t)) {
    ray->o = o + d * t;
  }
  return false;
}

void YarnTracer::leave_fiber(const TubeHit &hit, Vec3 d, SlabRay *ray) const
{
  /* Into the fiber: trace() culls the tube's exit, so the path crosses it (D32). */
  ray->o = hit.point;
  ray->d = d;
}

RdmMaps gather_yarn(const FiberPreset &preset, const geometry::YarnStructure &structure, const GatherOptions &options,
                    YarnIntersector intersector)
{
  if (structure.plies == 1) {
    throw ParameterError("plies", "a one-ply yarn is its ply: plies and yarns coincide (gather or bake the ply level)");
  }
  geometry::validate(structure);
  validate(preset);
  validate(options);
  const geometry::Yarn yarn(geometry::yarn_params(preset, structure), options.packing_seed);
  const double R = yarn.yarn_radius();
  const double entry = std::clamp(yarn.sampling_length(), 2.0 * R, 24.0 * R);
  const double half = 0.5 * entry + kYarnEndMargin * R;
  geometry::YarnStructure s = structure;
  s.surface_alpha = geometry::surface_twist(yarn);
  if (intersector == YarnIntersector::kEmbree || !fibers_advance_along_axis(yarn)) {
    const YarnTracer plain(yarn, entry, half, false), mirror(yarn, entry, half, true);
    RdmMaps maps = gather_through(preset, s, options, plain, mirror);
    maps.intersector = "embree";
    return maps;
  }
  TracerOptions tracer = yarn_tracer_options();
  tracer.sagitta = options.tracer.sagitta;
  const auto slabs = std::make_shared<const YarnSlabs>(yarn, half, tracer);
  const YarnGridTracer plain(slabs, entry, false), mirror(slabs, entry, true);
  RdmMaps maps = gather_through(preset, s, options, plain, mirror);
  maps.intersector = "slabs";
  return maps;
}

}  // namespace neuralyarn::rdm
