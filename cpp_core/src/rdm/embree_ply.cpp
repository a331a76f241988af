// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/embree_ply.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <embree3/rtcore.h>

namespace neuralyarn::rdm {

struct EmbreePly::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  const float *vertices = nullptr; /* owned by the geometry, which the scene keeps alive */
  const unsigned *indices = nullptr;
};

namespace {

/* The fiber of a segment (the primitive id): every curve has the same number of segments. */
int fiber_of(unsigned segment, int segments_per_fiber)
{
  return segments_per_fiber > 0 ? int(segment / unsigned(segments_per_fiber)) : -1;
}

/* The context of a query that skips hits: Embree passes it to the filter, which rejects them inside one
 * traversal (re-tracing from each skipped hit costs a traversal per skip, D32's culled exits at least one
 * per step). */
struct SkipContext {
  RTCIntersectContext base; /* first: Embree sees a plain context */
  int exclude;
  float exclude_distance;
  bool cull_exits;
  int segments_per_fiber;
};

void skip_filter(const RTCFilterFunctionNArguments *args)
{
  const auto *ctx = reinterpret_cast<const SkipContext *>(args->context);
  for (unsigned i = 0; i < args->N; i++) {
    if (args->valid[i] != -1) {
      continue;
    }
    /* Embree's Ng of a round curve points out of the tube: facing along the ray, the ray leaves it. */
    const bool leaving = !(RTCRayN_dir_x(args->ray, args->N, i) * RTCHitN_Ng_x(args->hit, args->N, i) +
                               RTCRayN_dir_y(args->ray, args->N, i) * RTCHitN_Ng_y(args->hit, args->N, i) +
                               RTCRayN_dir_z(args->ray, args->N, i) * RTCHitN_Ng_z(args->hit, args->N, i) <
                           0.0f);
    const int fiber = fiber_of(RTCHitN_primID(args->hit, args->N, i), ctx->segments_per_fiber);
    /* tfar holds the distance of the hit under test. */
    const bool excluded = fiber == ctx->exclude && RTCRayN_tfar(args->ray, args->N, i) < ctx->exclude_distance;
    if ((leaving && ctx->cull_exits) || excluded) {
      args->valid[i] = 0;
    }
  }
}

}  // namespace

EmbreePly::EmbreePly(const geometry::Ply &ply, double x0, double x1, int segments_per_turn)
    : EmbreePly(geometry::export_fibers(ply, x0, x1, segments_per_turn))
{
}

EmbreePly::EmbreePly(const geometry::CurveSet &curves, const char *device_config) : impl_(std::make_unique<Impl>())
{
  for (int c = 1; c < curves.num_curves(); c++) {
    if (curves.offsets[size_t(c) + 1] - curves.offsets[size_t(c)] != curves.offsets[1] - curves.offsets[0]) {
      throw std::invalid_argument("EmbreePly: every curve must have the same number of points");
    }
  }
  impl_->device = rtcNewDevice(device_config);
  if (!impl_->device) {
    throw std::runtime_error("Embree: cannot create a device (error " + std::to_string(rtcGetDeviceError(nullptr)) + ")");
  }
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_ROUND_LINEAR_CURVE);
  const size_t nv = curves.points.size();
  size_t nseg = 0;
  for (int c = 0; c < curves.num_curves(); c++) {
    nseg += size_t(curves.offsets[size_t(c) + 1] - curves.offsets[size_t(c)] - 1);
  }
  auto *v = static_cast<float *>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), nv));
  auto *idx = static_cast<unsigned *>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, sizeof(unsigned), nseg));
  /* Which fiber each segment belongs to (the primitive id is a segment id). */
  size_t s = 0;
  for (int c = 0; c < curves.num_curves(); c++) {
    for (int k = curves.offsets[size_t(c)]; k < curves.offsets[size_t(c) + 1]; k++) {
      const auto &p = curves.points[size_t(k)];
      v[4 * size_t(k) + 0] = p.x();
      v[4 * size_t(k) + 1] = p.y();
      v[4 * size_t(k) + 2] = p.z();
      v[4 * size_t(k) + 3] = curves.radii[size_t(c)];
      if (k + 1 < curves.offsets[size_t(c) + 1]) {
        idx[s++] = unsigned(k);
      }
    }
  }
  impl_->vertices = v;
  impl_->indices = idx;
  rtcCommitGeometry(geom);
  rtcAttachGeometry(impl_->scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(impl_->scene);
  segments_ = nseg;
  /* Segment -> fiber: curves have equal point counts, so fiber = segment / segments per curve. */
  if (curves.num_curves() > 0) {
    segments_per_fiber_ = curves.offsets[1] - curves.offsets[0] - 1;
  }
}

EmbreePly::~EmbreePly()
{
  if (impl_->scene) {
    rtcReleaseScene(impl_->scene);
  }
  if (impl_->device) {
    rtcReleaseDevice(impl_->device);
  }
}

bool EmbreePly::intersect(ny::Vec3 o, ny::Vec3 d, float tnear, float tfar, EmbreeHit *hit, int exclude,
                          float exclude_distance, bool cull_exits) const
{
  SkipContext ctx;
  rtcInitIntersectContext(&ctx.base);
  ctx.exclude = exclude;
  ctx.exclude_distance = exclude_distance;
  ctx.cull_exits = cull_exits;
  ctx.segments_per_fiber = segments_per_fiber_;
  if (exclude >= 0 || cull_exits) {
    ctx.base.filter = skip_filter;
  }
  return nearest_hit(o, d, tnear, tfar, &ctx.base, hit);
}

bool EmbreePly::nearest_hit(ny::Vec3 o, ny::Vec3 d, float tnear, float tfar, RTCIntersectContext *ctx,
                            EmbreeHit *hit) const
{
  RTCRayHit rh;
  rh.ray.org_x = o.x;
  rh.ray.org_y = o.y;
  rh.ray.org_z = o.z;
  rh.ray.dir_x = d.x;
  rh.ray.dir_y = d.y;
  rh.ray.dir_z = d.z;
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xffffffffu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    return false;
  }
  hit->t = rh.ray.tfar;
  hit->fiber = fiber_of(rh.hit.primID, segments_per_fiber_);
  /* Embree's Ng of a round curve points out of the tube. */
  hit->normal = ny::normalize(ny::make_vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
  hit->entering = ny::dot(hit->normal, d) < 0.0f;
  if (!hit->entering) {
    hit->normal = -hit->normal;
  }
  const size_t v0 = impl_->indices[rh.hit.primID];
  const float *a = impl_->vertices + 4 * v0, *b = impl_->vertices + 4 * (v0 + 1);
  hit->tangent = ny::normalize(ny::make_vec3(b[0] - a[0], b[1] - a[1], b[2] - a[2]));
  return true;
}

}  // namespace neuralyarn::rdm
