// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/rdm/surface_gather.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/random.h"
#include "neuralyarn/rdm/embree_ply.h"
#include "neuralyarn/units.h"

namespace neuralyarn::rdm {

using ny::Vec3;
using ny::make_vec3;

namespace {

constexpr uint64_t kChunk = 1 << 15;

void validate(const SurfaceGatherOptions &o, const Eigen::AlignedBox3f &box)
{
  if (o.paths == 0) {
    throw ParameterError("paths", "the surface gather needs at least one path");
  }
  for (const auto &[name, v] : {std::pair{"view_bins", o.view_bins}, std::pair{"light_theta", o.light_theta},
                                std::pair{"light_phi", o.light_phi}}) {
    if (v < 1 || v > 256) {
      throw ParameterError(name, std::string(name) + " must be in [1, 256], got " + std::to_string(v));
    }
  }
  if (o.max_events < 1) {
    throw ParameterError("max_events", "max_events must be at least 1");
  }
  const bool finite = std::isfinite(o.centre_x) && std::isfinite(o.centre_y) && std::isfinite(o.period_x) &&
                      std::isfinite(o.period_y);
  if (!finite || !(o.period_x > 0) || !(o.period_y > 0)) {
    throw ParameterError("period", "the pattern's period must be positive and finite");
  }
  if (o.centre_x - 0.5 * o.period_x < box.min().x() || o.centre_x + 0.5 * o.period_x > box.max().x() ||
      o.centre_y - 0.5 * o.period_y < box.min().y() || o.centre_y + 0.5 * o.period_y > box.max().y()) {
    throw ParameterError("period", "the entry rectangle (one period about the centre) must lie inside the patch");
  }
}

/* What one chunk of paths left: D's sums (SurfaceMaps::D's layout), the straight-through count per
 * (side, view), the energy of paths cut at the event limit, and the counts of cut paths and of paths that
 * left near the patch's edge. Chunks are summed in order: the same numbers at any thread count. */
struct Tally {
  std::vector<double> D, straight;
  double lost[3] = {0, 0, 0};
  uint64_t lost_paths = 0, past_edges = 0;

  void add(const Tally &t)
  {
    for (size_t i = 0; i < D.size(); i++) {
      D[i] += t.D[i];
    }
    for (size_t i = 0; i < straight.size(); i++) {
      straight[i] += t.straight[i];
    }
    for (int c = 0; c < 3; c++) {
      lost[c] += t.lost[c];
    }
    lost_paths += t.lost_paths, past_edges += t.past_edges;
  }
};

/* The walk of one path, into a tally. */
struct Walker {
  const EmbreePly &curves;
  const ny::YarnBsdfParams &p;
  const SurfaceMaps &layout;
  const SurfaceGatherOptions &o;
  Eigen::AlignedBox3f box;
  float tnear;

  void walk(Rng &rng, int side, int view, Tally &tally) const
  {
    const double cos_v = (view + double(uniform_float(rng))) / o.view_bins;
    const double sin_v = std::sqrt(std::max(0.0, 1.0 - cos_v * cos_v));
    const double phi_v = 2.0 * kPi * double(uniform_float(rng));
    const double zs = side == 0 ? 1.0 : -1.0; /* the side's frame: z -> zs z */
    const Vec3 wv = make_vec3(float(sin_v * std::cos(phi_v)), float(sin_v * std::sin(phi_v)), float(zs * cos_v));
    const double ex = o.centre_x + (double(uniform_float(rng)) - 0.5) * o.period_x;
    const double ey = o.centre_y + (double(uniform_float(rng)) - 0.5) * o.period_y;
    const double height = side == 0 ? box.max().z() + 1.0 : 1.0 - box.min().z(); /* above the patch's top */
    const double back = height / std::max(cos_v, 1e-9);
    Vec3 org = make_vec3(float(ex + back * wv.x), float(ey + back * wv.y), float(back * wv.z));
    Vec3 d = -wv;
    Vec3 last = make_vec3(float(ex), float(ey), 0.0f);
    double beta[3] = {1.0, 1.0, 1.0};
    bool straight = true;
    int events = 0;
    for (int step = 0;; step++) {
      EmbreeHit h;
      if (!curves.intersect(org, d, tnear, std::numeric_limits<float>::infinity(), &h, -1, 0.0f, /*cull_exits=*/true)) {
        break;
      }
      if (step >= o.max_events) {
        for (int c = 0; c < 3; c++) {
          tally.lost[c] += beta[c];
        }
        tally.lost_paths++;
        return;
      }
      const Vec3 x = h.tangent, n = h.radial_normal(), y = ny::cross(n, x);
      org = org + d * h.t;
      last = org;
      const Vec3 wi = make_vec3(-ny::dot(d, x), -ny::dot(d, y), -ny::dot(d, n));
      if (!(wi.z > 1e-6f)) {
        continue; /* grazing past the tube's silhouette within rounding: the ray goes on */
      }
      ny::YarnSample s;
      const float u0 = uniform_float(rng), u1 = uniform_float(rng), u2 = uniform_float(rng);
      if (!ny::yarn_sample(p, wi, u0, u1, u2, /*include_T=*/true, &s)) {
        return; /* nothing scattered: absorbed */
      }
      if (s.delta) {
        continue; /* T: on through the tube, whose exit the query culls */
      }
      const double w[3] = {s.weight.r, s.weight.g, s.weight.b};
      for (int c = 0; c < 3; c++) {
        beta[c] *= w[c];
      }
      if (!(std::isfinite(beta[0]) && std::isfinite(beta[1]) && std::isfinite(beta[2]))) {
        return;
      }
      straight = false;
      d = x * s.wo.x + y * s.wo.y + n * s.wo.z;
      d = d * (1.0f / ny::length(d));
      /* Russian roulette from the fourth scattering: unbiased, and keeps the dark walks short. */
      if (++events >= 4) {
        const double q = std::min(1.0, std::max({beta[0], beta[1], beta[2]}));
        if (double(uniform_float(rng)) >= q) {
          return;
        }
        for (double &b : beta) {
          b /= q;
        }
      }
    }
    if (straight) {
      tally.straight[size_t(side * layout.view_bins + view)] += 1.0;
    }
    else {
      const double wz = zs * d.z;
      const int t = std::min(int(std::abs(wz) * layout.light_theta), layout.light_theta - 1);
      double rel = std::atan2(double(d.y), double(d.x)) - phi_v;
      rel -= 2.0 * kPi * std::floor(rel / (2.0 * kPi));
      const int q = std::min(int(rel / (2.0 * kPi) * layout.light_phi), layout.light_phi - 1);
      const size_t i = layout.index(side, view, wz > 0.0 ? 0 : 1, t, q);
      for (int c = 0; c < 3; c++) {
        tally.D[i + size_t(c)] += beta[c];
      }
    }
    tally.past_edges += last.x < box.min().x() + o.period_x || last.x > box.max().x() - o.period_x ||
                        last.y < box.min().y() + o.period_y || last.y > box.max().y() - o.period_y;
  }
};

}  // namespace

SurfaceMaps gather_surface(const geometry::CurveSet &curves, const model::YarnModel &model,
                           const SurfaceGatherOptions &o)
{
  const auto t0 = std::chrono::steady_clock::now();
  if (curves.num_curves() == 0) {
    throw std::invalid_argument("the surface gather needs curves");
  }
  Eigen::AlignedBox3f box;
  float r_min = std::numeric_limits<float>::infinity(), r_max = 0.0f;
  for (const float r : curves.radii) {
    r_min = std::min(r_min, r), r_max = std::max(r_max, r);
  }
  for (const Eigen::Vector3f &q : curves.points) {
    box.extend(q);
  }
  box.min().array() -= r_max;
  box.max().array() += r_max;
  validate(o, box);
  const EmbreePly tubes(curves, ""); /* "": the walks' TBB threads are not limited by Embree's device */
  const std::vector<float> flat = model.kernel_flat();
  const ny::YarnBsdfParams params = ny::yarn_params_from_flat(flat.data());

  SurfaceMaps maps;
  maps.view_bins = o.view_bins, maps.light_theta = o.light_theta, maps.light_phi = o.light_phi;
  const size_t V = size_t(o.view_bins), cells = 2 * V;
  Tally empty;
  empty.D.assign(cells * 2 * size_t(o.light_theta) * size_t(o.light_phi) * 3, 0.0);
  empty.straight.assign(cells, 0.0);
  const Walker walker{tubes, params, maps, o, box, 1e-4f * r_min};

  const uint64_t n_chunks = (o.paths + kChunk - 1) / kChunk;
  std::vector<Tally> chunks(n_chunks);
  std::atomic<uint64_t> done{0};
  const int threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n_chunks, 1), [&](const tbb::blocked_range<uint64_t> &range) {
      for (uint64_t chunk = range.begin(); chunk != range.end(); chunk++) {
        /* One generator per chunk, seeded from (seed, chunk): the same paths at any thread count. */
        Rng rng(o.seed * 0x9E3779B97F4A7C15ULL + chunk * 0xD1B54A32D192ED03ULL + 1);
        Tally tally = empty;
        const uint64_t k0 = chunk * kChunk, k1 = std::min(o.paths, k0 + kChunk);
        for (uint64_t k = k0; k < k1; k++) {
          const size_t cell = size_t(k % cells);
          walker.walk(rng, int(cell / V), int(cell % V), tally);
        }
        chunks[chunk] = std::move(tally);
        const uint64_t now = done.fetch_add(k1 - k0) + (k1 - k0);
        if (o.progress) {
          o.progress(now, o.paths);
        }
      }
    }, tbb::simple_partitioner());
  });
  Tally all = empty;
  for (const Tally &t : chunks) {
    all.add(t);
  }

  /* Per (side, view) cell: means per path, D per steradian; what scattered is D's integral. */
  maps.paths = o.paths;
  maps.paths_lost = all.lost_paths;
  maps.paths_past_edges = all.past_edges;
  maps.D = std::move(all.D);
  maps.tau.assign(cells, 0.0);
  maps.scattered.assign(cells * 3, 0.0);
  const size_t per_cell = maps.D.size() / cells;
  const double omega = maps.bin_solid_angle();
  double exit[3] = {0, 0, 0};
  for (size_t cell = 0; cell < cells; cell++) {
    const uint64_t n = o.paths / cells + (cell < o.paths % cells ? 1 : 0);
    const double inv = n > 0 ? 1.0 / double(n) : 0.0;
    maps.tau[cell] = all.straight[cell] * inv;
    for (size_t i = 0; i < per_cell; i++) {
      const size_t j = cell * per_cell + i;
      exit[i % 3] += maps.D[j];
      maps.scattered[cell * 3 + i % 3] += maps.D[j] * inv;
      maps.D[j] *= inv / omega;
    }
    for (int c = 0; c < 3; c++) {
      exit[c] += all.straight[cell];
    }
  }
  for (int c = 0; c < 3; c++) {
    maps.absorbed[c] = 1.0 - (exit[c] + all.lost[c]) / double(o.paths);
  }
  maps.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return maps;
}

}  // namespace neuralyarn::rdm
