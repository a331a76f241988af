// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/gather.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/rdm/fiber_lobe_sampler.h"
#include "neuralyarn/rdm/fiber_medium.h"
#include "neuralyarn/units.h"

namespace neuralyarn::rdm {

using ny::Rgb;
using ny::Vec3;
using ny::make_vec3;

namespace {

/* Paths per work item: large enough to amortise scheduling, small enough for a smooth progress bar. */
constexpr uint64_t kChunk = 8192;
/* Fixed-point scale of the accumulators: weights are added as round(w * 2^32). */
constexpr double kFixedScale = 4294967296.0;
constexpr double kInvFixedScale = 1.0 / kFixedScale;
/* Largest weight accepted into a fixed-point sum: 2^10 * 2^32 per add leaves room for 2^22 such adds per
 * bin (in practice weights are <= ~3, so ~6e9 paths per bin). Larger weights are counted as invalid. */
constexpr float kMaxWeight = 1024.0f;
constexpr int kEventBins = 4096;
constexpr double kDisplacementBin = 0.02; /* ply radii */
constexpr int kDisplacementBins = 10000;   /* up to 200 R */
/* The signed axial offsets' histogram per side and band (decisions D72): bins of kDisplacementBin over
 * +-kAxialHalf * kDisplacementBin ply radii, the ends taking what lies beyond. */
constexpr int kAxialHalf = 5000;
constexpr int kAxialBins = 2 * kAxialHalf;
size_t axial_index(int side, int band, int bin)
{
  return (size_t(side) * ny::kExitBands + size_t(band)) * kAxialBins + size_t(bin);
}
/* The entry's h histogram per side, band and row of the exit's h (decisions D73): bins of 1 / kEntryHalf. */
constexpr int kEntryHalf = 100;
constexpr int kEntryBins = 2 * kEntryHalf;
size_t entry_index(int side, int band, int row, int bin)
{
  return ((size_t(side) * ny::kExitBands + size_t(band)) * ny::kEntryRows + size_t(row)) * kEntryBins + size_t(bin);
}

/* SplitMix64 (Steele, Lea & Flood 2014): one independent stream per path, seeded from (seed, path). */
struct PathRng {
  uint64_t state;
  static uint64_t mix(uint64_t z)
  {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  PathRng(uint64_t seed, uint64_t path) : state(mix(mix(seed ^ 0x6a09e667f3bcc909ull) + path * 0x9e3779b97f4a7c15ull)) {}
  uint64_t next()
  {
    state += 0x9e3779b97f4a7c15ull;
    return mix(state);
  }
  /* 24 bits: in [0, 1), exactly representable. */
  float uniform() { return float(next() >> 40) * (1.0f / 16777216.0f); }
  double uniform_double() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
};

inline void atomic_add(uint64_t *target, uint64_t v)
{
  if (v != 0) {
    __atomic_fetch_add(target, v, __ATOMIC_RELAXED);
  }
}

/* Round to nearest (w >= 0); a cast instead of llround, which is a library call. */
inline uint64_t to_fixed(float w) { return uint64_t(double(w) * kFixedScale + 0.5); }

struct Accumulators {
  size_t n_in = 0, n_map = 0;
  std::vector<uint64_t> count, count_t;
  std::vector<uint64_t> r, m, r2, m2;       /* fixed point */
  std::vector<uint64_t> exit_energy, absorbed; /* fixed point, [in][3] */
};

/* One scattered path's contribution to the R or M map (fixed point). */
struct MapRecord {
  size_t index;
  uint64_t w[3], w2[3];
  bool is_R;
};

/* Per-chunk statistics, merged into the shared ones once per chunk (integers: order-free). */
struct LocalStats {
  std::vector<MapRecord> records;
  std::vector<uint64_t> events;
  std::vector<uint64_t> displacement, displacement_M;
  /* (axial_index, exit energy fixed point) of each scattered exit: [side 0 entry, 1 far][band][signed offset bin] */
  std::vector<std::pair<uint32_t, uint64_t>> axial;
  /* (entry_index, exit energy times the entry's cosine) of each scattered exit and of its mirror image */
  std::vector<std::pair<uint32_t, uint64_t>> entry;
  uint64_t energy[3][3] = {}; /* [T/R/M][rgb] fixed */
  uint64_t absorbed[3] = {}, lost[3] = {};
  double balance[3] = {}, balance_sq[3] = {}; /* per chunk in double: summed in chunk order below */
  uint64_t paths[3] = {}, terminated = 0, truncated = 0, events_total = 0, slab_crossings = 0,
           invalid = 0, disp_sum = 0, disp_sum_M = 0, disp_count = 0, disp_count_M = 0, past_ends = 0;
  int max_events = 0;
};

struct SharedStats {
  std::vector<uint64_t> events, displacement, displacement_M;
  std::vector<uint64_t> axial; /* axial_index */
  std::vector<uint64_t> entry; /* entry_index */
  uint64_t energy[3][3] = {}, absorbed[3] = {}, lost[3] = {};
  std::vector<double> balance, balance_sq; /* [chunk][rgb]: combined in chunk order, so deterministic */
  uint64_t paths[3] = {}, terminated = 0, truncated = 0, events_total = 0, slab_crossings = 0,
           invalid = 0, disp_sum = 0, disp_sum_M = 0, disp_count = 0, disp_count_M = 0, past_ends = 0;
  std::atomic<int> max_events{0};
};

void merge(SharedStats &s, const LocalStats &l, uint64_t chunk)
{
  for (int c = 0; c < 3; c++) {
    s.balance[chunk * 3 + uint64_t(c)] = l.balance[c];
    s.balance_sq[chunk * 3 + uint64_t(c)] = l.balance_sq[c];
  }
  for (size_t i = 0; i < l.events.size(); i++) {
    atomic_add(&s.events[i], l.events[i]);
  }
  for (size_t i = 0; i < l.displacement.size(); i++) {
    atomic_add(&s.displacement[i], l.displacement[i]);
    atomic_add(&s.displacement_M[i], l.displacement_M[i]);
  }
  for (const auto &[i, w] : l.axial) {
    atomic_add(&s.axial[i], w);
  }
  for (const auto &[i, w] : l.entry) {
    atomic_add(&s.entry[i], w);
  }
  for (int k = 0; k < 3; k++) {
    for (int c = 0; c < 3; c++) {
      atomic_add(&s.energy[k][c], l.energy[k][c]);
    }
    atomic_add(&s.absorbed[k], l.absorbed[k]);
    atomic_add(&s.lost[k], l.lost[k]);
    atomic_add(&s.paths[k], l.paths[k]);
  }
  atomic_add(&s.terminated, l.terminated);
  atomic_add(&s.truncated, l.truncated);
  atomic_add(&s.events_total, l.events_total);
  atomic_add(&s.slab_crossings, l.slab_crossings);
  atomic_add(&s.invalid, l.invalid);
  atomic_add(&s.disp_sum, l.disp_sum);
  atomic_add(&s.disp_sum_M, l.disp_sum_M);
  atomic_add(&s.disp_count, l.disp_count);
  atomic_add(&s.disp_count_M, l.disp_count_M);
  atomic_add(&s.past_ends, l.past_ends);
  int prev = s.max_events.load();
  while (prev < l.max_events && !s.max_events.compare_exchange_weak(prev, l.max_events)) {
  }
}

double percentile(const std::vector<uint64_t> &hist, double q, double bin_width)
{
  uint64_t total = 0;
  for (uint64_t v : hist) {
    total += v;
  }
  if (total == 0) {
    return 0.0;
  }
  const double target = q * double(total);
  uint64_t cum = 0;
  for (size_t i = 0; i < hist.size(); i++) {
    cum += hist[i];
    if (double(cum) >= target) {
      return double(i) * bin_width;
    }
  }
  return double(hist.size() - 1) * bin_width;
}

/* The walks' medium and its mirror image: the ply's own tracers (called directly), one pair per
 * cross-section, or any FiberMedium. */
struct Geometry {
  std::vector<std::array<const PlyTracer *, 2>> plies;
  const FiberMedium *medium[2] = {nullptr, nullptr};
  std::vector<double> cos_theta_edge; /* cos of the theta_i bin edges */
};

/* What trace_path asks of either kind of medium. */
double entry_length(const PlyTracer &) { return 0.0; }
double entry_length(const FiberMedium &m) { return m.entry_length(); }
double half_length(const PlyTracer &) { return std::numeric_limits<double>::infinity(); }
double half_length(const FiberMedium &m) { return m.half_length(); }
float envelope_radius(const PlyTracer &t) { return t.ply_radius(); }
float envelope_radius(const FiberMedium &m) { return m.envelope_radius(); }
Vec3 world_point(const PlyTracer &t, const SlabRay &r) { return t.to_world_point(r.o, r.slab); }
Vec3 world_point(const FiberMedium &, const SlabRay &r) { return r.o; }
Vec3 world_dir(const PlyTracer &t, const SlabRay &r) { return t.to_world_dir(r.d, r.slab); }
Vec3 world_dir(const FiberMedium &, const SlabRay &r) { return r.d; }
EntryFrame entry_frame(const PlyTracer &t, double u_around, double u_along)
{
  return cylinder_entry(t.bound_radius(), 0.0, u_around, u_along);
}
EntryFrame entry_frame(const FiberMedium &m, double u_around, double u_along) { return m.entry_frame(u_around, u_along); }

/* Where a path enters: the entry frame and point (EntryFrame: n the envelope's normal, ex the axis, ey = n x ex),
 * its incident bin and direction. */
struct Entry : EntryFrame {
  size_t in_bin = 0;
  Vec3 wi; /* w_i (toward the light); its x: its cosine with the axis */
  /* The light that came in with it, for a uniform field of light: w_i's cosine with n times its bin's share of the
   * solid angle over its share of the paths (theta bins of equal angle hold equal paths, not equal solid angle). */
  float irradiance = 0.0f;
};

/* How a walk ended: left the medium (alive) or not, its throughput and what its events absorbed. */
struct Walk {
  SlabRay ray; /* the last ray: the exit, when alive */
  float beta[3] = {1.0f, 1.0f, 1.0f};
  uint64_t absorbed_fx[3] = {0, 0, 0};
  int events = 0;
  bool alive = true;
};

/* w_i uniform in solid angle inside the bin (cos(theta) uniform, phi uniform); the entry frame at a
 * uniform azimuth a on the ring x = 0 (screw invariance makes one ring enough), or at a uniform x over the
 * entry length of a medium that has none, or where a bent medium says (FiberMedium::entry_frame). */
template <class Medium>
Entry enter(const Medium &tracer, const MapResolution &b, const std::vector<double> &cos_theta_edge, size_t in_bin,
            PathRng &rng, SlabRay *ray)
{
  const int ti = int(in_bin / size_t(b.phi_i));
  const int pi = int(in_bin % size_t(b.phi_i));
  const double c0 = cos_theta_edge[size_t(ti)], c1 = cos_theta_edge[size_t(ti) + 1];
  const double cos_t = c0 + (c1 - c0) * rng.uniform_double();
  const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
  const double phi = -kPi + 2.0 * kPi * (pi + rng.uniform_double()) / b.phi_i;
  const Vec3 wi_local = make_vec3(float(sin_t * std::cos(phi)), float(sin_t * std::sin(phi)), float(cos_t));
  const double u_around = rng.uniform_double();
  const double u_along = entry_length(tracer) > 0.0 ? rng.uniform_double() : 0.5;
  Entry e;
  static_cast<EntryFrame &>(e) = entry_frame(tracer, u_around, u_along);
  e.in_bin = in_bin;
  const Vec3 wi = e.ex * wi_local.x + e.ey * wi_local.y + e.n * wi_local.z;
  e.wi = wi;
  e.irradiance = float(cos_t * (c0 - c1) * double(b.theta_i));
  ray->o = e.point;
  ray->d = -wi;
  ray->slab = 0;
  return e;
}

/* The random walk from the entry ray: fiber events sampled by the lobe sampler until the path leaves the
 * medium, is absorbed (Russian roulette) or runs past opt.max_events. */
template <class Medium>
Walk walk(const Medium &tracer, const FiberLobeSampler &sampler, const GatherOptions &opt, const SlabRay &entry_ray,
          PathRng &rng, LocalStats &ls)
{
  Walk w;
  w.ray = entry_ray;
  float *beta = w.beta;
  int exclude = -1;
  const float exclude_distance = 2.0f * tracer.fiber_radius();
  TubeHit hit;
  for (;;) {
    const int64_t slab_before = w.ray.slab;
    const bool got = tracer.trace(&w.ray, exclude, exclude_distance, &hit);
    ls.slab_crossings += uint64_t(std::llabs(w.ray.slab - slab_before));
    if (!got) {
      return w;
    }
    w.events++;
    if (w.events > opt.max_events) {
      ls.truncated++;
      for (int c = 0; c < 3; c++) {
        ls.lost[c] += to_fixed(beta[c]);
      }
      w.alive = false;
      return w;
    }
    /* Scatter in the fiber frame: x = tangent, z = tube normal. */
    ny::Frame frame;
    frame.x = hit.axis;
    frame.z = hit.normal;
    frame.y = ny::cross(frame.z, frame.x);
    const Vec3 wi_f = ny::to_local(frame, -w.ray.d);
    Vec3 wo_f = make_vec3(0.0f, 0.0f, 1.0f);
    Rgb weight, albedo;
    const bool scattered = sampler.sample(wi_f, ny::make_rgb(beta[0], beta[1], beta[2]), [&rng] { return rng.uniform(); },
                                          &wo_f, &weight, &albedo);
    /* Expected absorption at this event, for the energy bookkeeping: beta (1 - albedo). */
    w.absorbed_fx[0] += to_fixed(beta[0] * (1.0f - albedo.r));
    w.absorbed_fx[1] += to_fixed(beta[1] * (1.0f - albedo.g));
    w.absorbed_fx[2] += to_fixed(beta[2] * (1.0f - albedo.b));
    if (!scattered) {
      w.alive = false;
      ls.terminated++;
      return w;
    }
    beta[0] *= weight.r;
    beta[1] *= weight.g;
    beta[2] *= weight.b;
    if (!(std::isfinite(beta[0]) && std::isfinite(beta[1]) && std::isfinite(beta[2]))) {
      ls.invalid++;
      w.alive = false;
      return w;
    }
    /* From the hit point; into the fiber, the path crosses it (D32). */
    tracer.leave_fiber(hit, ny::normalize(ny::to_world(frame, wo_f)), &w.ray);
    exclude = hit.fiber;
    /* Russian roulette from the second event on (as pbrt's integrators): survive with q = min(1, max
     * channel), then divide by q. At the first it would estimate the R map, single scattering, from the
     * few paths of a dark fiber that survive it, each with a weight near 1 (D34). */
    const float q = std::min(1.0f, std::max(beta[0], std::max(beta[1], beta[2])));
    if (q < 1.0f && w.events > 1) {
      if (!(rng.uniform() < q)) {
        w.alive = false;
        ls.terminated++;
        return w;
      }
      beta[0] /= q;
      beta[1] /= q;
      beta[2] /= q;
    }
  }
}

/* Where along the axis (world x) light leaving from `p` along `d` crosses the envelope (radius R about the x axis),
 * minus where a ray from the entry point along `d` crosses it: how far a renderer, which continues the path from
 * its hit point, must move that ray along the ply to leave where the walk did (decisions D68). In double: a
 * near-axial exit subtracts two long chords. A direction along the axis never crosses the side: its points' x. */
double axial_exit_offset(Vec3 p, Vec3 d, Vec3 entry, double R)
{
  const double a2 = double(d.y) * d.y + double(d.z) * d.z;
  auto crossing_x = [&](Vec3 o) {
    if (!(a2 > 0.0)) {
      return double(o.x);
    }
    const double b = double(o.y) * d.y + double(o.z) * d.z, c = double(o.y) * o.y + double(o.z) * o.z - R * R;
    const double t = (-b + std::sqrt(std::max(b * b - a2 * c, 0.0))) / a2;
    return double(o.x) + std::max(t, 0.0) * double(d.x);
  };
  return crossing_x(p) - crossing_x(entry);
}

/* Where light leaving from `p` along `d` crosses the envelope (radius R about the x axis), seen along `w` (decisions
 * D73): its h across the width in [-1, 1] (the crossing's offset from the axis along w's perpendicular part turned a
 * quarter about +x: the renderer's cross(w's perpendicular part, tangent)) and whether it lies on the envelope's
 * half that faces w. A `d` along the axis never crosses the side: `p` itself. `w` must not lie along the axis. */
struct WidthPoint {
  double h;
  bool facing;
};
WidthPoint width_point(Vec3 p, Vec3 d, Vec3 w, double R)
{
  double y = p.y, z = p.z;
  const double a2 = double(d.y) * d.y + double(d.z) * d.z;
  if (a2 > 0.0) {
    const double b = y * d.y + z * d.z, c = y * y + z * z - R * R;
    const double t = std::max((-b + std::sqrt(std::max(b * b - a2 * c, 0.0))) / a2, 0.0);
    y += t * d.y;
    z += t * d.z;
  }
  const double aw = std::sqrt(double(w.y) * w.y + double(w.z) * w.z);
  return {std::clamp((y * w.z - z * w.y) / (aw * R), -1.0, 1.0), y * w.y + z * w.z >= 0.0};
}

/* A finished walk into the accumulators: its incident bin's count and absorption, the energy balance, and,
 * if it left, its label (T, R or M), exit energy, displacement and map record. */
template <class Medium>
void score(const Medium &tracer, const GatherOptions &opt, const Entry &e, const Walk &w, Accumulators &acc,
           LocalStats &ls)
{
  const MapResolution &b = opt.bins;
  const size_t in_bin = e.in_bin;
  const float *beta = w.beta;
  atomic_add(&acc.count[in_bin], 1);
  for (int c = 0; c < 3; c++) {
    atomic_add(&acc.absorbed[in_bin * 3 + size_t(c)], w.absorbed_fx[c]);
    ls.absorbed[c] += w.absorbed_fx[c];
  }
  /* Energy balance of this path: what left + what was absorbed + what was cut off. */
  for (int c = 0; c < 3; c++) {
    const double out = w.alive ? double(beta[c]) : 0.0;
    const double lost = (!w.alive && w.events > opt.max_events) ? double(beta[c]) : 0.0;
    const double total = out + double(w.absorbed_fx[c]) * kInvFixedScale + lost;
    ls.balance[c] += total;
    ls.balance_sq[c] += total * total;
  }
  ls.events[size_t(std::min(w.events, kEventBins - 1))]++;
  ls.events_total += uint64_t(w.events);
  ls.max_events = std::max(ls.max_events, w.events);
  if (!w.alive) {
    return;
  }

  /* Exit: direction and point in world coordinates, then in the entry frame. */
  const Vec3 d_w = world_dir(tracer, w.ray);
  const Vec3 p_w = world_point(tracer, w.ray);
  if (std::abs(double(p_w.x)) > half_length(tracer)) {
    ls.past_ends++;
  }
  const Vec3 wo = make_vec3(ny::dot(d_w, e.ex), ny::dot(d_w, e.ey), ny::dot(d_w, e.n));
  const int label = w.events == 0 ? 0 : (w.events == 1 && wo.z > 0.0f ? 1 : 2);
  ls.paths[label]++;
  for (int c = 0; c < 3; c++) {
    if (!(beta[c] <= kMaxWeight)) {
      ls.invalid++;
      return;
    }
  }
  uint64_t fx[3];
  for (int c = 0; c < 3; c++) {
    fx[c] = to_fixed(beta[c]);
    ls.energy[label][c] += fx[c];
    atomic_add(&acc.exit_energy[in_bin * 3 + size_t(c)], fx[c]);
  }
  if (label == 0) {
    atomic_add(&acc.count_t[in_bin], 1);
    return;
  }
  const double disp = std::sqrt(double(ny::dot(p_w - e.point, p_w - e.point))) / double(envelope_radius(tracer));
  const size_t dbin = size_t(std::min(disp / kDisplacementBin, double(kDisplacementBins - 1)));
  const uint64_t disp_fx = uint64_t(std::llround(disp * 1e6));
  ls.displacement[dbin]++;
  ls.disp_sum += disp_fx;
  ls.disp_count++;
  if (label == 2) {
    ls.displacement_M[dbin]++;
    ls.disp_sum_M += disp_fx;
    ls.disp_count_M++;
  }
  /* Signed: positive the way the light travelled along the axis (-w_i's), banded by |cos(w_i, axis)| (D72), weighted
   * by the light that came in with it (Entry::irradiance, as the entry's h below: D73). */
  const double travel = e.wi.x > 0.0f ? -1.0 : 1.0;
  const double axial = travel * axial_exit_offset(p_w, d_w, e.point, double(tracer.bound_radius())) /
                       double(envelope_radius(tracer));
  const int band = std::min(ny::kExitBands - 1, int(std::abs(e.wi.x) * float(ny::kExitBands)));
  const int abin = int(std::clamp(std::floor(axial / kDisplacementBin) + kAxialHalf, 0.0, double(kAxialBins - 1)));
  const int side = wo.z < 0.0f ? 1 : 0;
  const uint64_t w_in = to_fixed((beta[0] + beta[1] + beta[2]) * (1.0f / 3.0f) * e.irradiance);
  ls.axial.emplace_back(uint32_t(axial_index(side, band, abin)), w_in);
  /* Where around the ply the light came in, given where it leaves, across the width seen along w_i (D73), on the
   * side a renderer tells by the leaving point's normal (the light in front of it or behind): weighted by the light
   * that came in there (Entry::irradiance), recorded with its mirror image too (h -> -h: a renderer's tangent may
   * run either way along the ply). */
  if (std::abs(e.wi.x) < 0.9999f) {
    const double R = double(tracer.bound_radius());
    const WidthPoint in = width_point(e.point, e.wi, e.wi, R), out = width_point(p_w, d_w, e.wi, R);
    const int row = std::min(ny::kEntryRows - 1, int((out.h + 1.0) * 0.5 * ny::kEntryRows));
    const int bin = std::min(kEntryBins - 1, int((in.h + 1.0) * kEntryHalf));
    const int half = out.facing ? 0 : 1;
    ls.entry.emplace_back(uint32_t(entry_index(half, band, row, bin)), w_in);
    ls.entry.emplace_back(uint32_t(entry_index(half, band, ny::kEntryRows - 1 - row, kEntryBins - 1 - bin)), w_in);
  }
  int to, po;
  outgoing_bin(b, wo.x, wo.y, wo.z, &to, &po);
  const size_t idx = (in_bin * b.outgoing() + size_t(to) * size_t(b.phi_o) + size_t(po)) * 3;
  /* Deferred to the end of the chunk (flush_records), where the random writes into the large maps are
   * issued with prefetching. */
  MapRecord rec;
  rec.index = idx;
  rec.is_R = label == 1;
  for (int c = 0; c < 3; c++) {
    rec.w[c] = fx[c];
    rec.w2[c] = opt.variance ? to_fixed(beta[c] * beta[c]) : 0;
  }
  ls.records.push_back(rec);
}

/* Path k: incident bin k mod (bins), alternating between the medium and its mirror image per sweep over
 * the bins (and, for several cross-sections, to the next one every second sweep: accumulate()); its own
 * random stream. */
template <class Medium>
void trace_path(const Medium *const media[2], const std::vector<double> &cos_theta_edge, const FiberLobeSampler &sampler,
                const GatherOptions &opt, uint64_t k, Accumulators &acc, LocalStats &ls)
{
  const size_t n_in = opt.bins.incident();
  const Medium &tracer = *media[(k / n_in) & 1u];
  PathRng rng(opt.seed, k);
  SlabRay ray;
  const Entry e = enter(tracer, opt.bins, cos_theta_edge, size_t(k % n_in), rng, &ray);
  score(tracer, opt, e, walk(tracer, sampler, opt, ray, rng, ls), acc, ls);
}

void flush_records(LocalStats &ls, Accumulators &acc, bool variance)
{
  constexpr size_t kAhead = 8;
  const size_t n = ls.records.size();
  for (size_t i = 0; i < n; i++) {
    if (i + kAhead < n) {
      const MapRecord &f = ls.records[i + kAhead];
      __builtin_prefetch((f.is_R ? acc.r.data() : acc.m.data()) + f.index, 1);
      if (variance) {
        __builtin_prefetch((f.is_R ? acc.r2.data() : acc.m2.data()) + f.index, 1);
      }
    }
    const MapRecord &r = ls.records[i];
    uint64_t *map = r.is_R ? acc.r.data() : acc.m.data();
    uint64_t *map2 = r.is_R ? acc.r2.data() : acc.m2.data();
    for (int c = 0; c < 3; c++) {
      atomic_add(&map[r.index + size_t(c)], r.w[c]);
      if (variance) {
        atomic_add(&map2[r.index + size_t(c)], r.w2[c]);
      }
    }
  }
  ls.records.clear();
}

}  // namespace

int bin_of(double value, double lo, double hi, int n)
{
  const int i = int(std::floor((value - lo) / (hi - lo) * n));
  return std::clamp(i, 0, n - 1);
}

double bin_center(int index, double lo, double hi, int n) { return lo + (hi - lo) * (index + 0.5) / n; }

BinTaps bin_taps(double value, double lo, double hi, int n, bool wraps)
{
  const double u = (value - lo) / (hi - lo) * n - 0.5, f = std::floor(u);
  int b0 = int(f), b1 = b0 + 1;
  if (wraps) {
    b0 = (b0 % n + n) % n, b1 = (b1 % n + n) % n;
  }
  else {
    b0 = std::clamp(b0, 0, n - 1), b1 = std::clamp(b1, 0, n - 1);
  }
  return {{b0, b1}, {1.0 - (u - f), u - f}};
}

void incident_bin(const MapResolution &b, double x, double y, double z, int *ti, int *pi)
{
  *ti = bin_of(std::acos(std::clamp(z, -1.0, 1.0)), 0.0, 0.5 * kPi, b.theta_i);
  *pi = bin_of(std::atan2(y, x), -kPi, kPi, b.phi_i);
}

void outgoing_bin(const MapResolution &b, double x, double y, double z, int *to, int *po)
{
  *to = bin_of(std::acos(std::clamp(z, -1.0, 1.0)), 0.0, kPi, b.theta_o);
  *po = bin_of(std::atan2(y, x), -kPi, kPi, b.phi_o);
}

namespace {

/* A pseudo-angle of (x, y) in [0, 4), increasing with atan2(y, x) taken in [0, 2 pi): 1 at +y, 2 at -x, 3 at -y
 * (the "diamond angle", one division instead of an arc tangent). */
double diamond_angle(double x, double y)
{
  if (y >= 0.0) {
    return x >= 0.0 ? y / (x + y) : 1.0 - x / (y - x);
  }
  return x < 0.0 ? 2.0 - y / (-x - y) : 3.0 + x / (x - y);
}

/* Its inverse on the unit circle (for the table's cell centres only). */
double angle_of_diamond(double d)
{
  const int q = std::clamp(int(d), 0, 3);
  const double f = d - q; /* within the quadrant: y / (x + y) for x, y >= 0 */
  return 0.5 * kPi * q + std::atan2(f, 1.0 - f);
}

}  // namespace

OutgoingBinner::OutgoingBinner(const MapResolution &b) : n_theta_(b.theta_o), n_phi_(b.phi_o)
{
  for (int t = 0; t <= n_theta_; t++) {
    cos_theta_edge_.push_back(std::cos(kPi * t / n_theta_));
  }
  for (int k = 0; k <= n_phi_; k++) {
    phi_edge_c_.push_back(std::cos(-kPi + 2.0 * kPi * k / n_phi_));
    phi_edge_s_.push_back(std::sin(-kPi + 2.0 * kPi * k / n_phi_));
  }
  for (int c = 0; c < kGuessCells; c++) {
    const double z = -1.0 + 2.0 * (c + 0.5) / kGuessCells;
    theta_guess_.push_back(bin_of(std::acos(z), 0.0, kPi, n_theta_));
    /* The cell's centre as an angle in [0, 2 pi), then as atan2's in [-pi, pi). */
    double a = angle_of_diamond(4.0 * (c + 0.5) / kGuessCells);
    a = a >= kPi ? a - 2.0 * kPi : a;
    phi_guess_.push_back(bin_of(a, -kPi, kPi, n_phi_));
  }
}

void OutgoingBinner::operator()(double x, double y, double z, int *to, int *po) const
{
  /* theta_o is in bin t when cos(pi (t + 1) / n) < z <= cos(pi t / n). */
  const double zc = std::clamp(z, -1.0, 1.0);
  int t = theta_guess_[size_t(std::clamp(int((zc + 1.0) * (0.5 * kGuessCells)), 0, kGuessCells - 1))];
  while (t + 1 < n_theta_ && zc <= cos_theta_edge_[size_t(t + 1)]) {
    t++;
  }
  while (t > 0 && zc > cos_theta_edge_[size_t(t)]) {
    t--;
  }
  *to = t;
  if (!(y != 0.0) || n_phi_ < 4) {
    /* On the -x half-line atan2 tells -pi (bin 0) from pi (the last bin) by the sign of a zero y; and the
     * half-plane test below needs bins narrower than pi. */
    *po = bin_of(std::atan2(y, x), -kPi, kPi, n_phi_);
    return;
  }
  /* phi_o >= edge k (within pi of it, as the guess is) when the edge's direction turns left onto (x, y). */
  auto at_or_past = [&](int k) { return phi_edge_c_[size_t(k)] * y - phi_edge_s_[size_t(k)] * x >= 0.0; };
  /* The guess's cell on the side of the -x half-line that y's sign says (the pseudo-angle may round onto it):
   * settling moves at most one bin and cannot cross from pi to -pi. */
  constexpr int half = kGuessCells / 2;
  const int cell = int(diamond_angle(x, y) * (0.25 * kGuessCells));
  int k = phi_guess_[size_t(y > 0.0 ? std::clamp(cell, 0, half - 1) : std::clamp(cell, half, kGuessCells - 1))];
  while (k + 1 < n_phi_ && at_or_past(k + 1)) {
    k++;
  }
  while (k > 0 && !at_or_past(k)) {
    k--;
  }
  *po = k;
}

RdmMaps mean_of_maps(const RdmMaps &a, const RdmMaps &b)
{
  if (!(a.bins == b.bins)) {
    throw ParameterError("maps", "maps of different resolutions cannot be averaged");
  }
  if (preset_to_json(a.preset) != preset_to_json(b.preset) || a.packing_seed != b.packing_seed || a.layouts != b.layouts ||
      a.symmetrized != b.symmetrized || a.structure.plies != b.structure.plies ||
      a.structure.ply_twist != b.structure.ply_twist) {
    throw ParameterError("maps", "maps of different plies or yarns (preset, packing seed, cross-sections, structure or "
                                 "symmetrisation) cannot be averaged");
  }
  if (a.seed == b.seed) {
    throw ParameterError("maps", "maps of the same path seed are not independent");
  }
  const double wa = double(a.paths) / double(a.paths + b.paths), wb = 1.0 - wa;
  RdmMaps m = a;
  auto mix = [&](auto &out, const auto &va, const auto &vb) {
    for (size_t i = 0; i < out.size(); i++) {
      out[i] = decltype(out[i] + 0)(wa * va[i] + wb * vb[i]);
    }
  };
  mix(m.p_t, a.p_t, b.p_t);
  mix(m.r, a.r, b.r);
  mix(m.m, a.m, b.m);
  mix(m.exit_energy, a.exit_energy, b.exit_energy);
  mix(m.absorbed, a.absorbed, b.absorbed);
  for (size_t i = 0; i < m.count.size(); i++) {
    m.count[i] = a.count[i] + b.count[i];
  }
  m.paths = a.paths + b.paths;
  m.p_t_se.clear();
  m.r_se.clear();
  m.m_se.clear();
  return m;
}

double RdmMaps::outgoing_solid_angle(int to) const
{
  const double t0 = kPi * to / bins.theta_o, t1 = kPi * (to + 1) / bins.theta_o;
  return (std::cos(t0) - std::cos(t1)) * 2.0 * kPi / bins.phi_o;
}

double RdmMaps::incident_solid_angle(int ti) const
{
  const double t0 = 0.5 * kPi * ti / bins.theta_i, t1 = 0.5 * kPi * (ti + 1) / bins.theta_i;
  return (std::cos(t0) - std::cos(t1)) * 2.0 * kPi / bins.phi_i;
}

std::vector<double> RdmMaps::energy(const std::vector<float> &map) const
{
  std::vector<double> e(bins.incident() * 3, 0.0);
  for (int ti = 0; ti < bins.theta_i; ti++) {
    for (int pi = 0; pi < bins.phi_i; pi++) {
      double *out = &e[incident_index(ti, pi) * 3];
      for (int to = 0; to < bins.theta_o; to++) {
        const double dO = outgoing_solid_angle(to);
        for (int po = 0; po < bins.phi_o; po++) {
          const float *v = &map[map_index(ti, pi, to, po)];
          for (int c = 0; c < 3; c++) {
            out[c] += double(v[c]) * dO;
          }
        }
      }
    }
  }
  return e;
}

MapResolution parse_resolution(const std::string &text)
{
  MapResolution b;
  char x1 = 0, x2 = 0, x3 = 0;
  std::istringstream in(text);
  if (!(in >> b.theta_i >> x1 >> b.phi_i >> x2 >> b.theta_o >> x3 >> b.phi_o) || x1 != 'x' || x2 != 'x' ||
      x3 != 'x' || !in.eof()) {
    throw ParameterError("bins", "--bins must look like 22x90x45x90 (theta_i x phi_i x theta_o x phi_o), got '" +
                                     text + "'");
  }
  return b;
}

void validate(const GatherOptions &o)
{
  if (o.paths < 1 || o.paths > uint64_t(1e12)) {
    throw ParameterError("paths", "--paths must be in [1, 1e12], got " + std::to_string(o.paths));
  }
  if (o.layouts < 1 || o.layouts > 1024) {
    throw ParameterError("layouts", "--layouts must be in [1, 1024] cross-sections, got " + std::to_string(o.layouts));
  }
  if (o.threads < 0 || o.threads > 1024) {
    throw ParameterError("threads", "--threads must be in [0, 1024] (0: all cores), got " + std::to_string(o.threads));
  }
  const MapResolution &b = o.bins;
  if (b.theta_i < 1 || b.theta_o < 1 || b.phi_i < 2 || b.phi_o < 2 || b.theta_i > 720 || b.theta_o > 1440 ||
      b.phi_i > 2880 || b.phi_o > 2880) {
    throw ParameterError("bins", "map resolution must have 1..720 theta_i, 1..1440 theta_o and 2..2880 phi bins");
  }
  if (o.symmetrize && (b.phi_i % 2 != 0 || b.phi_o % 2 != 0)) {
    throw ParameterError("bins", "symmetrisation needs an even number of phi bins (a half turn must be whole bins)");
  }
  const double bytes = double(b.incident()) * double(b.outgoing()) * 3.0 * 8.0 * (o.variance ? 4.0 : 2.0);
  if (bytes > 64e9) {
    throw ParameterError("bins", "map resolution needs " + std::to_string(bytes / 1e9) + " GB of accumulators");
  }
  if (o.max_events < 1) {
    throw ParameterError("max_events", "max_events must be >= 1");
  }
  if (!(o.tracer.sagitta > 0.0 && o.tracer.sagitta <= 0.5) || !(o.tracer.cell_size >= 0.25 && o.tracer.cell_size <= 64.0)) {
    throw ParameterError("tracer", "tracer sagitta must be in (0, 0.5] and cell size in [0.25, 64] fiber radii");
  }
}

namespace {

/* The walks, in parallel over chunks of paths, into the accumulators and the shared statistics; returns the
 * seconds spent tracing (without the allocations). */
double accumulate(const FiberPreset &preset, const GatherOptions &opt, const Geometry &geo, tbb::task_arena &arena,
                Accumulators &acc, SharedStats &shared)
{
  const FiberLobeSampler sampler(preset.fiber_params(), opt.plain_estimator);
  const MapResolution &b = opt.bins;
  acc.n_in = b.incident();
  acc.n_map = b.incident() * b.outgoing() * 3;
  acc.count.assign(acc.n_in, 0);
  acc.count_t.assign(acc.n_in, 0);
  acc.exit_energy.assign(acc.n_in * 3, 0);
  acc.absorbed.assign(acc.n_in * 3, 0);
  acc.r.assign(acc.n_map, 0);
  acc.m.assign(acc.n_map, 0);
  if (opt.variance) {
    acc.r2.assign(acc.n_map, 0);
    acc.m2.assign(acc.n_map, 0);
  }
  shared.events.assign(kEventBins, 0);
  shared.displacement.assign(kDisplacementBins, 0);
  shared.displacement_M.assign(kDisplacementBins, 0);
  shared.axial.assign(2 * size_t(ny::kExitBands) * kAxialBins, 0);
  shared.entry.assign(2 * size_t(ny::kExitBands) * ny::kEntryRows * kEntryBins, 0);

  const uint64_t n_chunks = (opt.paths + kChunk - 1) / kChunk;
  std::atomic<uint64_t> done{0};
  shared.balance.assign(n_chunks * 3, 0.0);
  shared.balance_sq.assign(n_chunks * 3, 0.0);
  auto work = [&](const tbb::blocked_range<uint64_t> &range) {
    for (uint64_t chunk = range.begin(); chunk != range.end(); chunk++) {
      LocalStats ls;
      ls.events.assign(kEventBins, 0);
      ls.displacement.assign(kDisplacementBins, 0);
      ls.displacement_M.assign(kDisplacementBins, 0);
      const uint64_t k0 = chunk * kChunk, k1 = std::min(opt.paths, k0 + kChunk);
      ls.records.reserve(k1 - k0);
      ls.axial.reserve(k1 - k0);
      ls.entry.reserve(2 * (k1 - k0));
      for (uint64_t k = k0; k < k1; k++) {
        if (!geo.plies.empty()) {
          /* Every cross-section gets the same paths per incident bin, each with its mirror image. */
          const uint64_t pair = (k / b.incident() / 2) % geo.plies.size();
          trace_path(geo.plies[pair].data(), geo.cos_theta_edge, sampler, opt, k, acc, ls);
        }
        else {
          trace_path(geo.medium, geo.cos_theta_edge, sampler, opt, k, acc, ls);
        }
      }
      flush_records(ls, acc, opt.variance);
      merge(shared, ls, chunk);
      const uint64_t now = done.fetch_add(k1 - k0) + (k1 - k0);
      if (opt.progress) {
        opt.progress(now, opt.paths);
      }
    }
  };
  const auto t_trace = std::chrono::steady_clock::now();
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n_chunks, 1), work, tbb::simple_partitioner());
  });
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_trace).count();
}

/* Fixed point -> estimates, per incident bin; with symmetrisation a bin is the mean of itself and its
 * half-turn image. */
void finalize(const Accumulators &acc, const GatherOptions &opt, tbb::task_arena &arena, RdmMaps &maps)
{
  const MapResolution &b = opt.bins;
  maps.count = acc.count;
  maps.p_t.assign(acc.n_in, 0.0f);
  maps.exit_energy.assign(acc.n_in * 3, 0.0);
  maps.absorbed.assign(acc.n_in * 3, 0.0);
  maps.r.assign(acc.n_map, 0.0f);
  maps.m.assign(acc.n_map, 0.0f);
  if (opt.variance) {
    maps.p_t_se.assign(acc.n_in, 0.0f);
    maps.r_se.assign(acc.n_map, 0.0f);
    maps.m_se.assign(acc.n_map, 0.0f);
  }
  std::vector<double> inv_sa(size_t(b.theta_o));
  for (int t = 0; t < b.theta_o; t++) {
    inv_sa[size_t(t)] = 1.0 / maps.outgoing_solid_angle(t);
  }
  /* Per incident bin the estimate of a bin is mean(w) / dOmega, its variance (E[w^2] - E[w]^2) / n. */
  const int half_i = b.phi_i / 2, half_o = b.phi_o / 2;
  /* Each incident bin writes only its own outputs: parallel and still deterministic. */
  auto finalize_bin = [&](size_t i) {
      const int ti = int(i / size_t(b.phi_i)), pi = int(i % size_t(b.phi_i));
      /* The bins averaged into this one: itself, and with symmetrisation its half-turn image. */
      size_t src[2] = {i, maps.incident_index(ti, (pi + half_i) % b.phi_i)};
      const int n_src = opt.symmetrize ? 2 : 1;
      double pt = 0.0, pt_var = 0.0;
      for (int s = 0; s < n_src; s++) {
        const double n = double(acc.count[src[s]]);
        if (n > 0) {
          const double p = double(acc.count_t[src[s]]) / n;
          pt += p / n_src;
          pt_var += p * (1.0 - p) / n / (n_src * n_src);
        }
      }
      maps.p_t[i] = float(pt);
      if (opt.variance) {
        maps.p_t_se[i] = float(std::sqrt(pt_var));
      }
      /* Exit and absorbed energies are averaged over the same sources as the maps, so that exit_energy is
       * exactly p_t + the R and M maps' energies (up to rounding). */
      for (int c = 0; c < 3; c++) {
        double exit = 0.0, absorbed = 0.0;
        for (int s = 0; s < n_src; s++) {
          const double n = double(acc.count[src[s]]);
          if (n > 0) {
            exit += double(acc.exit_energy[src[s] * 3 + size_t(c)]) * kInvFixedScale / n / n_src;
            absorbed += double(acc.absorbed[src[s] * 3 + size_t(c)]) * kInvFixedScale / n / n_src;
          }
        }
        maps.exit_energy[i * 3 + size_t(c)] = exit;
        maps.absorbed[i * 3 + size_t(c)] = absorbed;
      }
      for (int to = 0; to < b.theta_o; to++) {
        for (int po = 0; po < b.phi_o; po++) {
          const size_t dst = maps.map_index(ti, pi, to, po);
          const size_t srcm[2] = {dst, maps.map_index(ti, (pi + half_i) % b.phi_i, to, (po + half_o) % b.phi_o)};
          for (int c = 0; c < 3; c++) {
            /* One map: the bin's mean over the averaged sources and the variance of that mean. */
            auto estimate = [&](const std::vector<uint64_t> &sum, const std::vector<uint64_t> &sum2, float *mean,
                                float *se) {
              double v = 0.0, var = 0.0;
              for (int s = 0; s < n_src; s++) {
                const double n = double(acc.count[src[s]]);
                if (!(n > 0)) {
                  continue;
                }
                const size_t j = srcm[s] + size_t(c);
                const double m1 = double(sum[j]) * kInvFixedScale / n * inv_sa[size_t(to)];
                v += m1 / n_src;
                if (se) {
                  const double m2 = double(sum2[j]) * kInvFixedScale / n * inv_sa[size_t(to)] * inv_sa[size_t(to)];
                  var += std::max(0.0, m2 - m1 * m1) / n / (n_src * n_src);
                }
              }
              *mean = float(v);
              if (se) {
                *se = float(std::sqrt(var));
              }
            };
            estimate(acc.r, acc.r2, &maps.r[dst + size_t(c)], opt.variance ? &maps.r_se[dst + size_t(c)] : nullptr);
            estimate(acc.m, acc.m2, &maps.m[dst + size_t(c)], opt.variance ? &maps.m_se[dst + size_t(c)] : nullptr);
          }
        }
      }
  };
  arena.execute([&] {
    tbb::parallel_for(size_t(0), acc.n_in, [&](size_t i) { finalize_bin(i); });
  });
  maps.symmetrized = opt.symmetrize;
}

/* A histogram of `bins` bins of width `step` from `lo` -> its quantiles at ny::exit_knot_level(1 ..
 * ny::kExitQuantiles), linear within a bin, appended to `quantiles`; `empty` for each if it holds no weight. */
void histogram_quantiles(const uint64_t *h, int bins, double lo, double step, double empty, std::vector<double> &quantiles)
{
  double total = 0.0;
  for (int i = 0; i < bins; i++) {
    total += double(h[i]);
  }
  double cum = 0.0;
  int i = 0;
  for (int k = 1; k <= ny::kExitQuantiles; k++) {
    if (!(total > 0.0)) {
      quantiles.push_back(empty);
      continue;
    }
    const double target = double(ny::exit_knot_level(k)) * total;
    while (i + 1 < bins && cum + double(h[i]) < target) {
      cum += double(h[i]);
      i++;
    }
    const double in_bin = h[i] ? std::clamp((target - cum) / double(h[i]), 0.0, 1.0) : 0.0;
    quantiles.push_back(lo + (double(i) + in_bin) * step);
  }
}

/* One side's signed axial offset histograms (kExitBands of kAxialBins, from `hist`) -> per band its quantiles,
 * band after band, and its mean (bin centres); a band without weight gets zeros (no offset). */
void axial_summary(const uint64_t *hist, std::vector<double> &quantiles, std::vector<double> &means)
{
  quantiles.clear();
  means.clear();
  for (int band = 0; band < ny::kExitBands; band++) {
    const uint64_t *h = hist + size_t(band) * kAxialBins;
    double total = 0.0, moment = 0.0;
    for (int i = 0; i < kAxialBins; i++) {
      total += double(h[i]);
      moment += double(h[i]) * (double(i - kAxialHalf) + 0.5) * kDisplacementBin;
    }
    means.push_back(total > 0.0 ? moment / total : 0.0);
    histogram_quantiles(h, kAxialBins, -kAxialHalf * kDisplacementBin, kDisplacementBin, 0.0, quantiles);
  }
}

/* One side's entry-h histograms (kExitBands x kEntryRows of kEntryBins, from `hist`) -> per row its quantiles, band
 * after band, row after row; a row without weight gets its own centre (the light came in on the line it leaves on). */
std::vector<double> entry_summary(const uint64_t *hist)
{
  std::vector<double> quantiles;
  for (int r = 0; r < ny::kExitBands * ny::kEntryRows; r++) {
    const double centre = -1.0 + (2.0 * (r % ny::kEntryRows) + 1.0) / ny::kEntryRows;
    histogram_quantiles(hist + size_t(r) * kEntryBins, kEntryBins, -1.0, 1.0 / kEntryHalf, centre, quantiles);
  }
  for (double &q : quantiles) {
    q = std::clamp(q, -1.0, 1.0);
  }
  return quantiles;
}

/* The shared statistics -> the gather's summary (all but its timings). */
void summarize(const SharedStats &shared, const GatherOptions &opt, GatherStats &st)
{
  const uint64_t n_chunks = shared.balance.size() / 3;
  st.paths = opt.paths;
  const double np = double(opt.paths);
  for (int c = 0; c < 3; c++) {
    st.energy_T[c] = double(shared.energy[0][c]) * kInvFixedScale / np;
    st.energy_R[c] = double(shared.energy[1][c]) * kInvFixedScale / np;
    st.energy_M[c] = double(shared.energy[2][c]) * kInvFixedScale / np;
    st.absorbed[c] = double(shared.absorbed[c]) * kInvFixedScale / np;
    st.lost[c] = double(shared.lost[c]) * kInvFixedScale / np;
  }
  for (int c = 0; c < 3; c++) {
    double sum = 0.0, sq = 0.0;
    for (uint64_t k = 0; k < n_chunks; k++) {
      sum += shared.balance[k * 3 + uint64_t(c)];
      sq += shared.balance_sq[k * 3 + uint64_t(c)];
    }
    st.balance[c] = sum / np;
    st.balance_se[c] = std::sqrt(std::max(0.0, sq / np - st.balance[c] * st.balance[c]) / np);
  }
  st.paths_T = shared.paths[0];
  st.paths_R = shared.paths[1];
  st.paths_M = shared.paths[2];
  st.paths_terminated = shared.terminated;
  st.paths_truncated = shared.truncated;
  st.paths_past_ends = shared.past_ends;
  st.events_histogram = shared.events;
  st.events_total = shared.events_total;
  st.mean_events = double(shared.events_total) / np;
  st.p95_events = int(percentile(shared.events, 0.95, 1.0));
  st.max_events_seen = shared.max_events.load();
  st.slab_crossings = shared.slab_crossings;
  st.invalid_weights = shared.invalid;
  st.mean_displacement = shared.disp_count ? double(shared.disp_sum) * 1e-6 / double(shared.disp_count) : 0.0;
  st.mean_displacement_M = shared.disp_count_M ? double(shared.disp_sum_M) * 1e-6 / double(shared.disp_count_M) : 0.0;
  st.p95_displacement = percentile(shared.displacement, 0.95, kDisplacementBin);
  st.p95_displacement_M = percentile(shared.displacement_M, 0.95, kDisplacementBin);
  axial_summary(shared.axial.data() + axial_index(0, 0, 0), st.axial_exit_reflected, st.mean_axial_exit_reflected);
  axial_summary(shared.axial.data() + axial_index(1, 0, 0), st.axial_exit_through, st.mean_axial_exit_through);
  st.entry_h_reflected = entry_summary(shared.entry.data() + entry_index(0, 0, 0, 0));
  st.entry_h_through = entry_summary(shared.entry.data() + entry_index(1, 0, 0, 0));
}

RdmMaps gather_in(const FiberPreset &preset, const geometry::YarnStructure &structure, const GatherOptions &opt,
                  Geometry &geo, std::chrono::steady_clock::time_point t_start)
{
  for (int t = 0; t <= opt.bins.theta_i; t++) {
    geo.cos_theta_edge.push_back(std::cos(0.5 * kPi * t / opt.bins.theta_i));
  }
  const int threads = opt.threads > 0 ? opt.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  Accumulators acc;
  SharedStats shared;
  const double seconds_tracing = accumulate(preset, opt, geo, arena, acc, shared);

  RdmMaps maps;
  maps.bins = opt.bins;
  maps.preset = preset;
  maps.structure = structure;
  maps.seed = opt.seed;
  maps.packing_seed = opt.packing_seed;
  maps.layouts = opt.layouts;
  maps.paths = opt.paths;
  /* The cross-sections share the fiber radius and the slab (both the preset's, not the packing's). */
  maps.fiber_radius = !geo.plies.empty() ? geo.plies[0][0]->fiber_radius() : geo.medium[0]->fiber_radius();
  maps.slab_length = !geo.plies.empty() ? geo.plies[0][0]->slab_length() : 2.0 * geo.medium[0]->half_length();
  maps.sagitta = opt.tracer.sagitta;
  finalize(acc, opt, arena, maps);
  summarize(shared, opt, maps.stats);
  maps.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  maps.stats.seconds_tracing = seconds_tracing;
  return maps;
}

}  // namespace

RdmMaps gather(const FiberPreset &preset, const GatherOptions &opt)
{
  validate(preset);
  validate(opt);
  const auto t_start = std::chrono::steady_clock::now();
  geometry::PlyParams pp;
  pp.N = preset.N;
  pp.rho = preset.rho;
  pp.alpha = preset.alpha;
  pp.R = 1.0;
  std::vector<std::unique_ptr<PlyTracer>> tracers;
  Geometry geo;
  for (int j = 0; j < opt.layouts; j++) {
    const geometry::PlyCrossSection cs = geometry::pack_cross_section(pp, opt.packing_seed + uint64_t(j));
    tracers.push_back(std::make_unique<PlyTracer>(geometry::Ply(pp, cs), opt.tracer));
    tracers.push_back(std::make_unique<PlyTracer>(geometry::Ply(pp, geometry::mirrored(cs)), opt.tracer));
    geo.plies.push_back({tracers[tracers.size() - 2].get(), tracers.back().get()});
  }
  return gather_in(preset, geometry::YarnStructure{}, opt, geo, t_start);
}

RdmMaps gather_through(const FiberPreset &preset, const geometry::YarnStructure &structure, const GatherOptions &opt,
                       const FiberMedium &medium, const FiberMedium &mirror)
{
  validate(preset);
  validate(opt);
  if (opt.layouts != 1) {
    throw ParameterError("layouts", "the yarn level gathers through one yarn: several cross-sections are a ply-level "
                                    "option");
  }
  Geometry geo;
  geo.medium[0] = &medium;
  geo.medium[1] = &mirror;
  return gather_in(preset, structure, opt, geo, std::chrono::steady_clock::now());
}

}  // namespace neuralyarn::rdm
