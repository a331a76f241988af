// SPDX-License-Identifier: Apache-2.0
//
// RDM gathering throughput (docs/benchmarks.md, "RDM gathering"). Two parts:
//
//   1. end to end: `neuralyarn::rdm::gather` per preset at the paper's resolution, paths/s and peak memory
//      (with --level yarn: `gather_yarn`, the walk through an explicit 3-ply yarn: slabs of chord tubes, or with
//      --yarn-intersector embree Embree's round curves, the reference; D66);
//   2. the intersector: the same recorded walk queries answered by PlyTracer and by Embree 3 round linear
//      curves over an explicit ply (queries/s, and how often the two disagree on the fiber hit).
//
// Usage: bench_gather [--presets fleece,silk,...] [--paths 1e7] [--threads 2] [--bins 22x90x45x90]
//                     [--cell 2] [--sagitta 0.01] [--queries 200000] [--skip-gather] [--skip-queries]
//                     [--level ply|yarn [--plies 3] [--ply-twist 0.5] [--yarn-intersector grid|embree]]
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/embree_ply.h"
#include "neuralyarn/rdm/fiber_lobe_sampler.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/rdm/ply_tracer.h"
#include "cli_common.h"

using namespace neuralyarn;
using Clock = std::chrono::steady_clock;

namespace {

double peak_rss_mb()
{
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;
}

struct Query {
  ny::Vec3 o, d; /* canonical slab coordinates (slab 0) */
  int exclude;
};

/* Records the queries of real walks (PlyTracer's own), so that both intersectors answer the same ones. */
std::vector<Query> record_queries(const rdm::PlyTracer &tracer, const FiberPreset &preset, size_t count, uint64_t seed)
{
  std::vector<Query> out;
  out.reserve(count);
  const rdm::FiberLobeSampler sampler(preset.fiber_params());
  std::mt19937_64 rng(seed);
  auto u = [&] { return float(rng() >> 40) * (1.0f / 16777216.0f); };
  while (out.size() < count) {
    const float a = 6.2831853f * u();
    const ny::Vec3 n = ny::make_vec3(0.0f, std::cos(a), std::sin(a));
    const float cz = u(), sz = std::sqrt(1.0f - cz * cz), ph = 6.2831853f * u();
    const ny::Vec3 ey = ny::make_vec3(0.0f, std::sin(a), -std::cos(a));
    const ny::Vec3 wi = ny::make_vec3(sz * std::cos(ph), 0, 0) + ey * (sz * std::sin(ph)) + n * cz;
    rdm::SlabRay ray;
    ray.o = n * tracer.bound_radius();
    ray.d = -wi;
    int exclude = -1;
    for (int events = 0; events < 200 && out.size() < count; events++) {
      rdm::SlabRay q = ray;
      q.slab = 0;
      out.push_back({q.o, q.d, exclude});
      rdm::TubeHit hit;
      if (!tracer.trace(&ray, exclude, 2.0f * tracer.fiber_radius(), &hit)) {
        break;
      }
      ny::Frame f{hit.axis, ny::cross(hit.normal, hit.axis), hit.normal};
      ny::Vec3 wo;
      ny::Rgb w, alb;
      if (!sampler.sample(ny::to_local(f, -ray.d), ny::make_rgb(1.0f), u, &wo, &w, &alb)) {
        break;
      }
      tracer.leave_fiber(hit, ny::normalize(ny::to_world(f, wo)), &ray);
      ray.slab = 0;
      exclude = hit.fiber;
    }
  }
  return out;
}

void bench_queries(const FiberPreset &preset, const rdm::TracerOptions &topt, size_t count)
{
  geometry::PlyParams pp{preset.N, preset.rho, preset.alpha, 1.0};
  const geometry::Ply ply(pp, geometry::pack_cross_section(pp, 1));
  const rdm::PlyTracer tracer(ply, topt);
  const std::vector<Query> qs = record_queries(tracer, preset, count, 7);

  /* PlyTracer. */
  auto t0 = Clock::now();
  size_t hits_tracer = 0;
  std::vector<int> fiber_tracer(qs.size(), -1);
  std::vector<float> t_tracer(qs.size(), -1.0f);
  for (size_t i = 0; i < qs.size(); i++) {
    rdm::SlabRay r{qs[i].o, qs[i].d, 0};
    rdm::TubeHit h;
    if (tracer.trace(&r, qs[i].exclude, 2.0f * tracer.fiber_radius(), &h)) {
      hits_tracer++;
      fiber_tracer[i] = h.fiber;
      t_tracer[i] = h.t;
    }
  }
  const double s_tracer = std::chrono::duration<double>(Clock::now() - t0).count();

  /* Embree over x in [-40, 40] ply radii; 64 segments per turn (chord sagitta ~0.5 % of r for fleece). */
  const rdm::EmbreePly embree(ply, -40.0, 40.0, 64);
  t0 = Clock::now();
  size_t hits_embree = 0, agree = 0, self_hits = 0, entry_mismatch = 0, origin_inside = 0, debug_printed = 0;
  for (size_t i = 0; i < qs.size(); i++) {
    /* Embree sees the explicit ply; the query leaves the fiber it starts on by a hair. */
    rdm::EmbreeHit h;
    const ny::Vec3 o = qs[i].o;
    int fiber = -1;
    /* Stop at the bounding cylinder like PlyTracer does. */
    const float a2 = qs[i].d.y * qs[i].d.y + qs[i].d.z * qs[i].d.z;
    const float bb = tracer.bound_radius();
    const float b = o.y * qs[i].d.y + o.z * qs[i].d.z, c = o.y * o.y + o.z * o.z - bb * bb;
    const float tfar = a2 > 0 ? (-b + std::sqrt(std::max(b * b - a2 * c, 0.0f))) / a2 : 1e30f;
    if (embree.intersect(o, qs[i].d, 0.0f, tfar, &h, qs[i].exclude, 2.0f * tracer.fiber_radius())) {
      hits_embree++;
      fiber = h.fiber;
    }
    agree += fiber == fiber_tracer[i];
    if (fiber != fiber_tracer[i]) {
      self_hits += fiber >= 0 && fiber == qs[i].exclude;
      entry_mismatch += qs[i].exclude < 0;
      if (fiber >= 0 && std::getenv("NY_BENCH_DEBUG")) {
        /* Distance of the query origin from Embree's fiber's helix (dense search). */
        const Eigen::Vector3d O(qs[i].o.x, qs[i].o.y, qs[i].o.z);
        double best = 1e9;
        for (double x = O.x() - 0.3; x <= O.x() + 0.3; x += 1e-4) {
          best = std::min(best, (ply.fiber_point(fiber, x) - O).norm());
        }
        origin_inside += best < ply.fiber_radius();
        if (debug_printed++ < 10) {
          std::printf("  mismatch: tracer %d (t %.4f) embree %d (t %.4f), origin distance to embree's fiber %.5f r\n",
                      fiber_tracer[i], double(t_tracer[i]), fiber, double(h.t), best / ply.fiber_radius());
        }
      }
    }
  }
  const double s_embree = std::chrono::duration<double>(Clock::now() - t0).count();
  if (std::getenv("NY_BENCH_DEBUG")) {
    std::printf("  mismatches with the origin inside Embree's fiber: %zu\n", origin_inside);
  }
  std::printf("%-10s queries %zu: PlyTracer %.2f M/s (%.0f ns, grid %dx%d, %zu entries, slab %.3f R) | Embree 3 "
              "(%zu segments) %.2f M/s (%.0f ns) | same fiber or both miss %.3f%%, hits %zu vs %zu (mismatches: %zu "
              "Embree re-hits the fiber the query leaves, %zu entry queries)\n",
              preset.name.c_str(), qs.size(), qs.size() / s_tracer / 1e6, s_tracer / qs.size() * 1e9,
              tracer.grid_resolution(), tracer.grid_resolution(), tracer.grid_entries(), tracer.slab_length(),
              embree.num_segments(), qs.size() / s_embree / 1e6, s_embree / qs.size() * 1e9,
              100.0 * double(agree) / double(qs.size()), hits_tracer, hits_embree, self_hits, entry_mismatch);
}


}  // namespace

int main(int argc, char **argv)
{
  CLI::App app{"RDM gathering benchmark"};
  std::string presets = "fleece,silk,polyester,cotton,gabardine", bins = "22x90x45x90";
  double paths = 1e7, cell = 2.0, sagitta = 0.01;
  int threads = 2;
  size_t queries = 200000;
  bool skip_gather = false, skip_queries = false, noise = false;
  cli::LevelOptions level; /* the CLI's --level, --plies, --ply-twist and their defaults */
  app.add_option("--presets", presets);
  app.add_option("--paths", paths);
  app.add_option("--threads", threads);
  app.add_option("--bins", bins);
  app.add_option("--cell", cell);
  app.add_option("--sagitta", sagitta);
  app.add_option("--queries", queries);
  app.add_flag("--skip-gather", skip_gather);
  app.add_flag("--skip-queries", skip_queries);
  cli::add_level_options(&app, &level);
  app.add_flag("--noise", noise, "Map noise per second: our estimator vs. the plain one (two seeds each)");
  CLI11_PARSE(app, argc, argv);

  std::vector<std::string> names;
  std::stringstream ss(presets);
  for (std::string n; std::getline(ss, n, ',');) {
    names.push_back(n);
  }
  rdm::TracerOptions topt;
  topt.cell_size = cell;
  topt.sagitta = sagitta;
  if (!skip_queries) {
    std::printf("# Intersector: recorded walk queries, 1 thread\n");
    for (const auto &n : names) {
      bench_queries(find_preset(n), topt, queries);
    }
  }
  if (noise) {
    std::printf("# Map noise: RMS over bins of (map(seed 1) - map(seed 2)) / sqrt(2), %d threads, bins %s, %.0e paths\n",
                threads, bins.c_str(), paths);
    for (const auto &n : names) {
      for (int plain = 0; plain < 2; plain++) {
        rdm::RdmMaps maps[2];
        double seconds = 0.0;
        for (int k = 0; k < 2; k++) {
          rdm::GatherOptions opt;
          opt.paths = uint64_t(paths);
          opt.threads = threads;
          opt.bins = rdm::parse_resolution(bins);
          opt.tracer = topt;
          opt.seed = uint64_t(k + 1);
          opt.plain_estimator = plain != 0;
          maps[k] = rdm::gather(find_preset(n), opt);
          seconds += maps[k].stats.seconds_tracing;
        }
        double sq_m = 0.0, sq_r = 0.0, sum_m = 0.0;
        for (size_t i = 0; i < maps[0].m.size(); i++) {
          const double dm = double(maps[0].m[i]) - maps[1].m[i], dr = double(maps[0].r[i]) - maps[1].r[i];
          sq_m += dm * dm;
          sq_r += dr * dr;
          sum_m += 0.5 * (double(maps[0].m[i]) + maps[1].m[i]);
        }
        const double noise_m = std::sqrt(sq_m / double(maps[0].m.size()) / 2.0);
        const double noise_r = std::sqrt(sq_r / double(maps[0].r.size()) / 2.0);
        const double mean_m = sum_m / double(maps[0].m.size());
        const double t = seconds / 2.0;
        std::printf("%-10s %-22s %.3f M paths/s, events/path %.2f, M noise %.4g (mean M %.4g), R noise %.4g, "
                    "1/(noise_M^2 s) %.4g\n",
                    n.c_str(), plain ? "plain estimator" : "ours (default)", paths / t / 1e6,
                    maps[0].stats.mean_events, noise_m, mean_m, noise_r, 1.0 / (noise_m * noise_m * t));
        std::fflush(stdout);
      }
    }
  }
  if (!skip_gather) {
    std::printf("# End to end: gather, %s level, %d threads, bins %s\n", level.level.c_str(), threads, bins.c_str());
    for (const auto &n : names) {
      rdm::GatherOptions opt;
      opt.paths = uint64_t(paths);
      opt.threads = threads;
      opt.bins = rdm::parse_resolution(bins);
      opt.tracer = topt;
      const rdm::RdmMaps maps = cli::gather_level(find_preset(n), level, opt);
      const rdm::GatherStats &s = maps.stats;
      std::printf("%-10s paths %.0e: %.3f s (tracing %.3f s), %.3f M paths/s (tracing alone %.3f M/s), events/path %.2f (p95 %d), queries/path %.2f, "
                  "slab crossings/path %.2f, peak RSS %.0f MB\n",
                  n.c_str(), paths, s.seconds, s.seconds_tracing, s.paths_per_second() / 1e6,
                  double(s.paths) / s.seconds_tracing / 1e6, s.mean_events, s.p95_events,
                  double(s.events_total + s.paths) / double(s.paths), double(s.slab_crossings) / double(s.paths),
                  peak_rss_mb());
      auto avg = [](const double v[3]) { return (v[0] + v[1] + v[2]) / 3.0; };
      std::printf("%-10s   energy (channel mean) T %.4f R %.4f M %.4f absorbed %.4f lost %.1e, balance %.5f +- %.5f; "
                  "exit displacement mean %.2f R (95th %.2f), M paths mean %.2f R (95th %.2f)\n",
                  n.c_str(), avg(s.energy_T), avg(s.energy_R), avg(s.energy_M), avg(s.absorbed), avg(s.lost),
                  avg(s.balance), avg(s.balance_se), s.mean_displacement, s.p95_displacement, s.mean_displacement_M,
                  s.p95_displacement_M);
      std::fflush(stdout);
    }
  }
  return 0;
}
