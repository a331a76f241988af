// SPDX-License-Identifier: Apache-2.0
//
// The RDM gatherer against independent references:
//   * the lobe sampler against quadrature of the kernel's eval (unbiasedness);
//   * PlyTracer against brute force over every fiber, and P(T) against straight rays through Embree;
//   * the R map against next-event estimation with Embree (an estimator that never samples a direction);
//   * multiple scattering against a renderer's walk through Embree curves (where a path restarts after an event);
//   * energy bookkeeping, symmetry, determinism across threads, agreement of independent halves;
//   * the map file's round trip and its corruption errors.
// Statistical comparisons use fixed seeds and a chi^2 over all compared numbers with p > 1e-4 (a correct
// implementation fails one such test with probability 1e-4; the seeds are fixed, so a pass is stable).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <boost/math/distributions/chi_squared.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <filesystem>
#include <fstream>
#include <random>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/model/bake.h"
#include "neuralyarn/kernel/exit_placement.h"
#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/embree_ply.h"
#include "neuralyarn/rdm/fiber_lobe_sampler.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/rdm/ply_tracer.h"
#include "neuralyarn/units.h"
#include "quadrature.h"

using namespace neuralyarn;
namespace fs = std::filesystem;

namespace {

/* Accumulates z-scores; p-value of their sum of squares against chi^2(n). */
struct ZTest {
  double chi2 = 0.0;
  int n = 0;
  double worst = 0.0;
  void add(double a, double b, double se)
  {
    if (!(se > 0.0)) {
      return;
    }
    const double z = (a - b) / se;
    chi2 += z * z;
    n++;
    worst = std::max(worst, std::abs(z));
  }
  double p_value() const
  {
    if (n == 0) {
      return 0.0;
    }
    return boost::math::cdf(boost::math::complement(boost::math::chi_squared(n), chi2));
  }
  std::string report() const
  {
    return "chi2 " + std::to_string(chi2) + " over " + std::to_string(n) + " values, worst |z| " +
           std::to_string(worst) + ", p " + std::to_string(p_value());
  }
};

geometry::Ply make_ply(const FiberPreset &p, uint64_t seed = 1)
{
  geometry::PlyParams pp{p.N, p.rho, p.alpha, 1.0};
  return geometry::Ply(pp, geometry::pack_cross_section(pp, seed));
}

rdm::GatherOptions small_options(uint64_t paths, rdm::MapResolution bins, bool symmetrize, bool variance)
{
  rdm::GatherOptions o;
  o.paths = paths;
  o.bins = bins;
  o.symmetrize = symmetrize;
  o.variance = variance;
  o.threads = 2;
  return o;
}

/* An entry as the gather draws one, for the tests that cast rays or walk paths on their own: w_i uniform in
 * solid angle in incident bin (ti, pi) of the entry frame (x = ply axis, z = n, y = ey), n at an azimuth
 * uniform around the axis; `uniform` is called for cos theta_i, phi_i and the azimuth, in that order. */
struct Entry {
  ny::Vec3 n, ey, wi;
};

template <class Uniform>
Entry draw_entry(const rdm::MapResolution &bins, int ti, int pi, Uniform &&uniform)
{
  const double c0 = std::cos(0.5 * kPi * ti / bins.theta_i), c1 = std::cos(0.5 * kPi * (ti + 1) / bins.theta_i);
  const double ct = c0 + (c1 - c0) * uniform(), st = std::sqrt(1 - ct * ct);
  const double ph = -kPi + 2 * kPi * (pi + uniform()) / bins.phi_i;
  const double a = 2 * kPi * uniform();
  Entry e;
  e.n = ny::make_vec3(0.0f, float(std::cos(a)), float(std::sin(a)));
  e.ey = ny::make_vec3(0.0f, float(std::sin(a)), float(-std::cos(a)));
  e.wi = ny::make_vec3(float(st * std::cos(ph)), 0.0f, 0.0f) + e.ey * float(st * std::sin(ph)) + e.n * float(ct);
  return e;
}


/* A path walked as a renderer walks it through explicit fibers (Embree curves, exits culled, the lobe sampler
 * at each hit, Russian roulette on the throughput), from the envelope (radius Rb) along -e.wi: the gather's walk
 * by other means. `lost`: it came within 2 radii of the ends of a ply `len` long. */
struct RendererWalk {
  ny::Vec3 o, d; /* the last event's point and the exit direction (the entry point and -w_i without events) */
  ny::Rgb beta = ny::make_rgb(1.0f);
  int events = 0;
  bool alive = true, lost = false;
};

RendererWalk walk_embree(const rdm::EmbreePly &geo, const Entry &e, float Rb, float r, double len,
                         const rdm::FiberLobeSampler &sampler, std::mt19937_64 &rng)
{
  std::uniform_real_distribution<double> U(0.0, 1.0);
  auto uniform = [&] { return float(U(rng)); };
  RendererWalk w;
  w.o = e.n * Rb;
  w.d = -e.wi;
  int exclude = -1;
  rdm::EmbreeHit h;
  while (geo.intersect(w.o, w.d, 0.0f, rdm::cylinder_exit(w.o, w.d, Rb), &h, exclude, 2.0f * r,
                       /*cull_exits=*/true)) {
    w.events++;
    w.o = w.o + w.d * h.t;
    if (std::abs(w.o.x) > len - 2.0) {
      w.lost = true;
      w.alive = false;
      return w;
    }
    ny::Frame f;
    f.x = h.tangent.x >= 0.0f ? h.tangent : -h.tangent;
    f.z = ny::normalize(h.normal - f.x * ny::dot(h.normal, f.x));
    f.y = ny::cross(f.z, f.x);
    ny::Vec3 wo;
    ny::Rgb lobe_w, albedo;
    if (!sampler.sample(ny::to_local(f, -w.d), w.beta, uniform, &wo, &lobe_w, &albedo)) {
      w.alive = false;
      return w;
    }
    w.beta = w.beta * lobe_w;
    w.d = ny::normalize(ny::to_world(f, wo));
    exclude = h.fiber;
    const float q = std::min(1.0f, std::max(w.beta.r, std::max(w.beta.g, w.beta.b)));
    if (q < 1.0f) {
      if (!(U(rng) < q)) {
        w.alive = false;
        return w;
      }
      w.beta = w.beta * (1.0f / q);
    }
  }
  return w;
}

/* A preset's ply as a renderer's walk meets it (walk_embree): both mirror images as Embree curves (256 segments
 * per turn, 2 kLen long), alternating from walk to walk, with the tracer's envelope and the preset's lobe sampler. */
struct RendererPly {
  static constexpr double kLen = 40.0;
  explicit RendererPly(const FiberPreset &preset)
      : ply(make_ply(preset)), mirror(ply.params(), geometry::mirrored(ply.cross_section())), a(ply, -kLen, kLen, 256),
        b(mirror, -kLen, kLen, 256), tracer(ply), Rb(tracer.bound_radius()), r(tracer.fiber_radius()),
        sampler(preset.fiber_params())
  {
  }
  RendererWalk walk(int k, const Entry &e, std::mt19937_64 &rng) const
  {
    return walk_embree((k & 1) ? b : a, e, Rb, r, kLen, sampler, rng);
  }
  geometry::Ply ply, mirror;
  rdm::EmbreePly a, b;
  rdm::PlyTracer tracer;
  float Rb, r;
  rdm::FiberLobeSampler sampler;
};
}  // namespace

/* ------------------------------------------------------------------------------------------------ */
/* The fiber lobe sampler.                                                                            */
/* ------------------------------------------------------------------------------------------------ */

TEST(FiberLobeSampler, RatioTableMatchesExactAndKernel)
{
  for (double beta_deg : {1.0, 2.141, 7.238, 10.0, 27.197, 38.0}) {
    const double beta = beta_deg * kDeg;
    const rdm::CosSquaredRatioTable table(beta);
    double worst_table = 0.0, worst_kernel = 0.0;
    for (int i = 0; i <= 10007; i++) {
      const double mu = -kPi / 2 + kPi * i / 10007.0;
      const double exact = rdm::CosSquaredRatioTable::exact(mu, beta);
      worst_table = std::max(worst_table, std::abs(double(table(float(mu))) / exact - 1.0));
      /* The kernel's float normaliser and truncated-normal mass: an independent implementation. */
      const ny::TruncatedNormal tn = ny::make_truncated_normal(float(mu), float(beta), -ny::kHalfPi, ny::kHalfPi);
      const double kernel = double(tn.mass) / double(ny::cos2_gaussian_normalizer(float(mu), float(beta)));
      worst_kernel = std::max(worst_kernel, std::abs(kernel / exact - 1.0));
    }
    /* Catmull-Rom on 8192 intervals; the worst case is beta = 1 degree next to the pole. */
    EXPECT_LT(worst_table, 2e-5) << "beta " << beta_deg;
    EXPECT_LT(worst_kernel, 2e-4) << "beta " << beta_deg << " (float kernel)";
  }
}

/* E[weight h(w_o)] = integral of eval h for test functions h, per channel, at incidences that take the
 * rejection branch and the weighted branch, with neutral and coloured path throughputs. */
TEST(FiberLobeSampler, UnbiasedAgainstQuadrature)
{
  ZTest zt;
  std::mt19937_64 rng(2024);
  auto uniform = [&rng] { return float(rng() >> 40) * (1.0f / 16777216.0f); };
  const std::function<double(ny::Vec3)> hs[] = {
      [](ny::Vec3) { return 1.0; },
      [](ny::Vec3 w) { return double(w.x); },
      [](ny::Vec3 w) { return double(w.y); },
      [](ny::Vec3 w) { return double(w.z); },
      [](ny::Vec3 w) { return double(w.x * w.x); },
      [](ny::Vec3 w) { return w.z > 0.5f ? 1.0 : 0.0; },
  };
  constexpr int kH = 6;
  for (const char *name : {"fleece", "cotton", "silk", "polyester"}) {
    const ny::FiberBsdfParams params = find_preset(name).fiber_params();
    const rdm::FiberLobeSampler sampler(params);
    for (double th : {0.0, 40.0, 80.0, 88.5}) {
      for (int tp = 0; tp < 2; tp++) {
        const ny::Vec3 wi = ny::direction_from_angles(float(th * kDeg), 0.7f);
        const ny::Rgb throughput = tp == 0 ? ny::make_rgb(1.0f) : ny::make_rgb(0.1f, 0.5f, 1.0f);
        /* Reference by quadrature with breakpoints at the lobes. */
        std::vector<double> tb, pb;
        for (double beta : {double(params.beta_R), double(params.beta_TT)}) {
          for (double k : {-9.0, -6.0, -3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 6.0, 9.0}) {
            tb.push_back(-th * kDeg + k * beta);
          }
        }
        for (double k : {-6.0, -3.0, -1.0, 0.0, 1.0, 3.0, 6.0}) {
          pb.push_back(std::remainder(0.7 + kPi + k * params.gamma_TT, 2 * kPi));
        }
        pb.push_back(std::acos(0.5)); /* the step of the last test function (w.z > 0.5 at theta = 0) */
        pb.push_back(-std::acos(0.5));
        const auto ref = nytest::integrate_2d_fixed<3 * kH>(
            [&](double t, double p) {
              const ny::Vec3 wo = ny::direction_from_angles(float(t), float(p));
              float pdf;
              const ny::Rgb f = ny::fiber_eval(params, wi, wo, &pdf);
              std::array<double, 3 * kH> v{};
              for (int h = 0; h < kH; h++) {
                const double hv = hs[h](wo) * std::cos(t);
                v[size_t(3 * h)] = f.r * hv;
                v[size_t(3 * h + 1)] = f.g * hv;
                v[size_t(3 * h + 2)] = f.b * hv;
              }
              return v;
            },
            nytest::breakpoints(tb, -kPi / 2, kPi / 2, 0.25), nytest::breakpoints(pb, -kPi, kPi, 0.5));
        const int n = 100000;
        std::array<double, 3 * kH> sum{}, sq{};
        for (int i = 0; i < n; i++) {
          ny::Vec3 wo;
          ny::Rgb w, albedo;
          ASSERT_TRUE(sampler.sample(wi, throughput, uniform, &wo, &w, &albedo));
          const float ch[3] = {w.r, w.g, w.b};
          for (int h = 0; h < kH; h++) {
            const double hv = hs[h](wo);
            for (int c = 0; c < 3; c++) {
              const double x = double(ch[c]) * hv;
              sum[size_t(3 * h + c)] += x;
              sq[size_t(3 * h + c)] += x * x;
            }
          }
        }
        for (size_t k = 0; k < sum.size(); k++) {
          const double mean = sum[k] / n;
          const double se = std::sqrt(std::max(0.0, sq[k] / n - mean * mean) / n);
          /* The sample standard error is useless for rare events (an indicator of mass 1e-4 may get no
           * sample at all): floor it by the Poisson bound sqrt(w_max |ref| / n), weights being < 3. */
          const double floor_se = std::sqrt(3.0 * std::abs(ref[k]) / n) + 1e-9;
          zt.add(mean, ref[k], std::max(se, floor_se));
          if (std::getenv("NY_TEST_DEBUG")) {
            std::printf("%s th %g tp %d k %zu: mc %.5f ref %.5f se %.5f\n", name, th, tp, k, mean, ref[k], se);
          }
        }
      }
    }
  }
  EXPECT_GT(zt.p_value(), 1e-4) << zt.report();
}

/* ------------------------------------------------------------------------------------------------ */
/* The tracer.                                                                                        */
/* ------------------------------------------------------------------------------------------------ */

/* Rays from random points on fiber surfaces and on the bounding cylinder, in random directions: trace()
 * must return exactly the nearest entry found by testing every fiber of the slab, whenever that entry
 * lies in the slab the ray starts in — the same distance to the last bit, since the grid's vector lanes
 * compute the scalar tube test's float operations (the maps must not change with the lane width). */
TEST(PlyTracer, MatchesBruteForceInTheSlab)
{
  for (const char *name : {"fleece", "silk", "polyester", "cotton"}) {
    for (bool mirrored : {false, true}) {
      const geometry::Ply base = make_ply(find_preset(name));
      const geometry::Ply ply = mirrored ? geometry::Ply(base.params(), geometry::mirrored(base.cross_section())) : base;
      const rdm::PlyTracer tracer(ply);
      std::mt19937_64 rng(17);
      std::uniform_real_distribution<float> U(0.0f, 1.0f);
      int compared = 0, hits = 0;
      for (int i = 0; i < 20000; i++) {
        /* Origin: a point on the bounding cylinder in the slab, direction into the cylinder. */
        const float a = 6.2831853f * U(rng);
        const ny::Vec3 n = ny::make_vec3(0.0f, std::cos(a), std::sin(a));
        ny::Vec3 d = ny::normalize(ny::make_vec3(2.0f * U(rng) - 1.0f, 2.0f * U(rng) - 1.0f, 2.0f * U(rng) - 1.0f));
        if (ny::dot(d, n) > 0.0f) {
          d = d - n * (2.0f * ny::dot(d, n));
        }
        const ny::Vec3 o = n * tracer.bound_radius() + ny::make_vec3(tracer.slab_length() * U(rng), 0.0f, 0.0f);
        /* Brute force within the slab. */
        float best = INFINITY;
        int best_f = -1;
        for (int f = 0; f < tracer.num_fibers(); f++) {
          const float t = tracer.intersect_fiber(f, o, d);
          const float x = o.x + t * d.x;
          if (t < best && x >= 0.0f && x <= tracer.slab_length()) {
            best = t;
            best_f = f;
          }
        }
        rdm::SlabRay ray{o, d, 0};
        rdm::TubeHit hit;
        const bool got = tracer.trace(&ray, -1, 0.0f, &hit);
        if (best_f >= 0) {
          /* A brute-force hit in the starting slab is always the nearest (the ray reaches other slabs
           * only after leaving this one). */
          compared++;
          ASSERT_TRUE(got) << name << " ray " << i;
          EXPECT_EQ(hit.fiber, best_f) << name << " ray " << i;
          EXPECT_EQ(hit.t, best) << name << " ray " << i;
          EXPECT_NEAR(ny::length(hit.normal), 1.0f, 1e-5f);
          hits++;
        }
      }
      EXPECT_GT(compared, 5000) << name;
      EXPECT_EQ(hits, compared);
    }
  }
}

/* A path scattered into the fiber continues from the hit point and crosses the fiber: the tracer reports
 * tube entries only, so the tube it is in does not stop it (docs/decisions.md D32). */
TEST(PlyTracer, TransmissionCrossesTheFiber)
{
  const geometry::Ply ply = make_ply(find_preset("fleece"));
  const rdm::PlyTracer tracer(ply);
  const float r = tracer.fiber_radius();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  int checked = 0, long_chords = 0;
  for (int i = 0; i < 5000; i++) {
    const float a = 6.2831853f * U(rng);
    const ny::Vec3 n = ny::make_vec3(0.0f, std::cos(a), std::sin(a));
    rdm::SlabRay ray{n * tracer.bound_radius(), -n, 0};
    rdm::TubeHit hit;
    if (!tracer.trace(&ray, -1, 0.0f, &hit)) {
      continue;
    }
    /* A direction into the fiber. */
    ny::Vec3 d = ny::normalize(ny::make_vec3(2.0f * U(rng) - 1.0f, 2.0f * U(rng) - 1.0f, 2.0f * U(rng) - 1.0f));
    if (ny::dot(d, hit.normal) > 0.0f) {
      d = -d;
    }
    rdm::SlabRay out;
    tracer.leave_fiber(hit, d, &out);
    EXPECT_LT(ny::length(out.o - hit.point), 1e-5f);
    /* The chord through the tube: where the ray leaves it. */
    const float da = ny::dot(d, hit.axis);
    const float chord = -2.0f * r * ny::dot(d, hit.normal) / std::max(1.0f - da * da, 1e-12f);
    long_chords += chord > 2.0f * r ? 1 : 0;
    rdm::TubeHit next;
    if (tracer.trace(&out, hit.fiber, 2.0f * r, &next) && next.fiber == hit.fiber) {
      EXPECT_GT(next.t, chord) << "ray " << i << " stopped inside the fiber it crosses";
    }
    checked++;
  }
  EXPECT_GT(checked, 3000);
  EXPECT_GT(long_chords, 100); /* crossings longer than the exclusion distance were checked too */
}

/* One straight fiber is convex: a path that scatters on it leaves on a straight line that cannot meet it
 * again, so no path has two events. A walk that did not carry transmitted paths through the fiber would
 * restart inside it or on its near side and register a second event. */
TEST(Gather, SingleStraightFiberScattersAtMostOnce)
{
  FiberPreset p = find_preset("cotton"); /* TT-heavy: C_TT = 0.999 */
  p.name = "one_fiber";
  p.N = 1;
  p.rho = 0.3;
  p.alpha = 0.0;
  const rdm::RdmMaps maps = rdm::gather(p, small_options(40000, {2, 4, 4, 4}, true, false));
  EXPECT_EQ(maps.stats.max_events_seen, 1);
  EXPECT_GT(maps.stats.events_histogram.at(1), 5000u);
  EXPECT_EQ(maps.stats.invalid_weights, 0u);
}

/* P(T | w_i) against straight rays through an explicit Embree 3 ply (round linear curves, 256 segments per
 * turn, the same two mirror-image geometries), a different intersector and a different ray generator. */
TEST(Gather, TransmissionProbabilityMatchesStraightEmbreeRays)
{
  const rdm::MapResolution bins{6, 8, 4, 8};
  for (const char *name : {"fleece", "silk"}) {
    const FiberPreset &preset = find_preset(name);
    const rdm::RdmMaps maps = rdm::gather(preset, small_options(6 * 8 * 3000, bins, false, false));
    const geometry::Ply ply = make_ply(preset);
    const double len = 60.0;
    const geometry::Ply ply_mirror(ply.params(), geometry::mirrored(ply.cross_section()));
    const rdm::EmbreePly ply_a(ply, -len, len, 256), ply_b(ply_mirror, -len, len, 256);
    const rdm::PlyTracer tracer(ply); /* only for the bounding radius */
    const float Rb = tracer.bound_radius();
    const double period = std::isfinite(ply.pitch()) ? ply.pitch() : 1.0;
    std::mt19937_64 rng(99);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    ZTest zt;
    int escaped_ends = 0;
    for (int ti = 0; ti < bins.theta_i; ti++) {
      for (int pi = 0; pi < bins.phi_i; pi++) {
        const int n_rays = 4000;
        int passed = 0;
        for (int k = 0; k < n_rays; k++) {
          const Entry e = draw_entry(bins, ti, pi, [&] { return U(rng); });
          const double x0 = period * (U(rng) - 0.5);
          const ny::Vec3 o = e.n * Rb + ny::make_vec3(float(x0), 0.0f, 0.0f);
          const ny::Vec3 d = -e.wi;
          const float tfar = rdm::cylinder_exit(o, d, Rb);
          if (std::abs(o.x + tfar * d.x) > len - 1.0) {
            escaped_ends++;
          }
          rdm::EmbreeHit h;
          const rdm::EmbreePly &geo = (k & 1) ? ply_b : ply_a;
          passed += geo.intersect(o, d, 0.0f, tfar, &h) ? 0 : 1;
        }
        const size_t i = maps.incident_index(ti, pi);
        const double n1 = double(maps.count[i]), p1 = maps.p_t[i];
        const double p2 = double(passed) / n_rays;
        const double pooled = (p1 * n1 + p2 * n_rays) / (n1 + n_rays);
        if (pooled * (n1 + n_rays) < 10 || (1 - pooled) * (n1 + n_rays) < 10) {
          continue; /* normal approximation needs counts */
        }
        zt.add(p1, p2, std::sqrt(pooled * (1 - pooled) * (1 / n1 + 1.0 / n_rays)));
      }
    }
    /* Near-axial rays that would leave the explicit ply through its ends (the tracer's ply is infinite):
     * too few to matter. */
    EXPECT_LT(escaped_ends, bins.theta_i * bins.phi_i * 4000 / 1000) << name;
    EXPECT_GT(zt.n, 10) << name;
    EXPECT_GT(zt.p_value(), 1e-4) << name << ": " << zt.report();
  }
}

/* The R map against next-event estimation: for each straight ray's first fiber hit (Embree), the fiber
 * BSDF is *evaluated* for directions spread over every upper-hemisphere outgoing bin, times visibility to
 * the bounding cylinder (Embree again). No direction is sampled, no event counted: an independent estimate
 * of the single-scattering, upward-leaving part of f |cos theta_o|. */
TEST(Gather, ReflectionMapMatchesNextEventEstimation)
{
  const rdm::MapResolution bins{3, 4, 4, 8};
  const FiberPreset &preset = find_preset("fleece");
  const rdm::RdmMaps maps = rdm::gather(preset, small_options(3 * 4 * 30000, bins, false, true));
  const geometry::Ply ply = make_ply(preset);
  const double len = 60.0;
  const geometry::Ply ply_mirror(ply.params(), geometry::mirrored(ply.cross_section()));
  const rdm::EmbreePly ply_a(ply, -len, len, 256), ply_b(ply_mirror, -len, len, 256);
  const rdm::PlyTracer tracer(ply);
  const float Rb = tracer.bound_radius(), r = tracer.fiber_radius();
  const ny::FiberBsdfParams fp = preset.fiber_params();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  auto exit_distance = [&](ny::Vec3 o, ny::Vec3 d) { return rdm::cylinder_exit(o, d, Rb); };
  ZTest zt;
  const int n_out_up = (bins.theta_o / 2) * bins.phi_o;
  for (int ti = 0; ti < bins.theta_i; ti++) {
    for (int pi = 0; pi < bins.phi_i; pi++) {
      const int n_rays = 3000;
      std::vector<double> sum(size_t(n_out_up) * 3, 0.0), sq(size_t(n_out_up) * 3, 0.0);
      for (int k = 0; k < n_rays; k++) {
        const Entry e = draw_entry(bins, ti, pi, [&] { return U(rng); });
        const double x0 = ply.pitch() * (U(rng) - 0.5);
        const ny::Vec3 n = e.n, ey = e.ey, ex = ny::make_vec3(1.0f, 0.0f, 0.0f);
        const ny::Vec3 o = n * Rb + ex * float(x0);
        const ny::Vec3 d = -e.wi;
        const rdm::EmbreePly &geo = (k & 1) ? ply_b : ply_a;
        rdm::EmbreeHit h;
        std::vector<double> v(size_t(n_out_up) * 3, 0.0);
        if (geo.intersect(o, d, 0.0f, exit_distance(o, d), &h)) {
          const ny::Vec3 p = o + d * h.t;
          ny::Frame f;
          f.x = h.tangent;
          f.z = ny::normalize(h.normal - h.tangent * ny::dot(h.normal, h.tangent));
          f.y = ny::cross(f.z, f.x);
          const ny::Vec3 wi_f = ny::to_local(f, -d);
          for (int to = 0; to < bins.theta_o / 2; to++) {
            for (int po = 0; po < bins.phi_o; po++) {
              const int ob = to * bins.phi_o + po;
              const int m = 2; /* directions per bin, uniform in solid angle */
              for (int j = 0; j < m; j++) {
                const double oc0 = std::cos(kPi * to / bins.theta_o), oc1 = std::cos(kPi * (to + 1) / bins.theta_o);
                const double oct = oc0 + (oc1 - oc0) * U(rng), ost = std::sqrt(1 - oct * oct);
                const double oph = -kPi + 2 * kPi * (po + U(rng)) / bins.phi_o;
                const ny::Vec3 wo = ex * float(ost * std::cos(oph)) + ey * float(ost * std::sin(oph)) + n * float(oct);
                const ny::Rgb fv = ny::fiber_eval(fp, wi_f, ny::to_local(f, wo), nullptr);
                if (!(fv.r + fv.g + fv.b > 0.0f)) {
                  continue;
                }
                /* Leave from the hit point; into the fiber, across it (exits culled, D32). */
                rdm::EmbreeHit h2;
                if (geo.intersect(p, wo, 0.0f, exit_distance(p, wo), &h2, h.fiber, 2.0f * r, /*cull_exits=*/true)) {
                  continue;
                }
                v[size_t(ob) * 3 + 0] += fv.r / m;
                v[size_t(ob) * 3 + 1] += fv.g / m;
                v[size_t(ob) * 3 + 2] += fv.b / m;
              }
            }
          }
        }
        for (size_t q = 0; q < v.size(); q++) {
          sum[q] += v[q];
          sq[q] += v[q] * v[q];
        }
      }
      for (int to = 0; to < bins.theta_o / 2; to++) {
        for (int po = 0; po < bins.phi_o; po++) {
          for (int c = 0; c < 3; c++) {
            const size_t q = size_t(to * bins.phi_o + po) * 3 + size_t(c);
            const double mean = sum[q] / n_rays;
            const double se = std::sqrt(std::max(0.0, sq[q] / n_rays - mean * mean) / n_rays);
            const size_t mi = maps.map_index(ti, pi, to, po) + size_t(c);
            /* A bin that caught few samples has a useless sample standard error: floor it by the Poisson
             * bound for the expected value (weights < 3). */
            const double n_paths = double(maps.count[maps.incident_index(ti, pi)]);
            const double se_map = std::max(double(maps.r_se[mi]),
                                           std::sqrt(3.0 * mean / (n_paths * maps.outgoing_solid_angle(to))));
            if (mean < 1e-4 && maps.r[mi] < 1e-4) {
              continue; /* nothing there in either estimate (e.g. grazing outgoing bins) */
            }
            zt.add(maps.r[mi], mean, std::sqrt(se * se + se_map * se_map));
            if (std::getenv("NY_TEST_DEBUG")) {
              std::printf("bin %d %d %d %d c%d: map %.5f +- %.5f  nee %.5f +- %.5f  z %.2f\n", ti, pi, to, po, c,
                          double(maps.r[mi]), se_map, mean, se, (maps.r[mi] - mean) / std::sqrt(se * se + se_map * se_map));
            }
          }
        }
      }
    }
  }
  EXPECT_GT(zt.n, 400);
  EXPECT_GT(zt.p_value(), 1e-4) << zt.report();
}

/* EmbreePly skips a walk's unwanted hits (the exits of the tube a ray starts in or crosses; the fiber it
 * just left, within two radii) inside one traversal, with an intersection filter. It must find the hit that
 * re-tracing finds: the nearest plain hit, then the next past it, until one is wanted. Rays as a walk casts
 * them: from points on the fibers, in every direction (into the tube and out of it). */
TEST(EmbreePly, FilterFindsTheHitReTracingFinds)
{
  const FiberPreset &preset = find_preset("cotton"); /* dense: many tubes touch */
  const geometry::Ply ply = make_ply(preset);
  const rdm::EmbreePly geo(ply, -20.0, 20.0, 128);
  const rdm::PlyTracer tracer(ply);
  const float Rb = tracer.bound_radius(), r = tracer.fiber_radius();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  auto direction = [&] { return ny::sample_uniform_sphere(U(rng), U(rng)); };
  auto retrace = [&](ny::Vec3 o, ny::Vec3 d, int exclude, rdm::EmbreeHit *h, int *rounds) {
    float tnear = 0.0f;
    for (*rounds = 1; *rounds <= 64; ++*rounds) {
      if (!geo.intersect(o, d, tnear, rdm::cylinder_exit(o, d, Rb), h)) {
        return false;
      }
      if ((h->fiber != exclude || h->t >= 2.0f * r) && h->entering) {
        return true;
      }
      tnear = h->t * (1.0f + 1e-6f) + 1e-7f;
    }
    return false;
  };
  int rays = 0, hits = 0, skipped = 0, differ = 0;
  while (rays < 40000) {
    /* A first hit from inside the bounding cylinder gives a point on a fiber. */
    const ny::Vec3 o0 = ny::make_vec3(float(4.0 * (U(rng) - 0.5)), 0.0f, 0.0f);
    const ny::Vec3 d0 = direction();
    rdm::EmbreeHit h0;
    if (!geo.intersect(o0, d0, 0.0f, rdm::cylinder_exit(o0, d0, Rb), &h0, -1, 0.0f, /*cull_exits=*/true)) {
      continue;
    }
    const ny::Vec3 p = o0 + d0 * h0.t;
    for (int k = 0; k < 4; k++, rays++) {
      const ny::Vec3 d = direction();
      rdm::EmbreeHit a, b;
      int rounds = 0;
      const bool got_a = geo.intersect(p, d, 0.0f, rdm::cylinder_exit(p, d, Rb), &a, h0.fiber, 2.0f * r, true);
      const bool got_b = retrace(p, d, h0.fiber, &b, &rounds);
      hits += got_b ? 1 : 0;
      skipped += rounds > 1 ? 1 : 0;
      if (got_a != got_b || (got_b && (a.fiber != b.fiber || std::abs(a.t - b.t) > 1e-5f * std::max(b.t, r)))) {
        differ++;
      }
    }
  }
  /* The rays exercise both: half go into their own tube and skip its exit; most hit another fiber. */
  EXPECT_GT(skipped, rays / 3);
  EXPECT_GT(hits, rays / 2);
  /* Re-tracing also steps over hits within 1e-6 t past a skipped one (its tnear); a filter keeps them. */
  EXPECT_LE(differ, rays / 10000) << differ << " of " << rays << " rays differ";
}

/* ------------------------------------------------------------------------------------------------ */
/* Bookkeeping, symmetry, determinism, convergence.                                                   */
/* ------------------------------------------------------------------------------------------------ */

/* Multiple scattering against a walk as a renderer takes it (Cycles, Mitsuba): through the explicit Embree
 * ply (round linear curves, 256 segments per turn, both mirror images), each event sampled by the same
 * lobe sampler, the path continuing from the hit point, a direction into the fiber crossing it because the
 * tube's exit is culled. Per incident bin, the energy that leaves into the upper (reflection) and lower
 * (transmission) hemisphere of the entry frame. Cotton: bright fibers and tens of events per path, where
 * the point a path restarts from after an event decides how much light gets through the ply (restarting
 * on the far side of the fiber's cross-section, the first gatherer's rule, put 15-20 % more light behind
 * a backlit cotton ply than explicit fibers render; docs/decisions.md D32). */
TEST(Gather, HemisphereEnergiesMatchARendererWalkThroughEmbreeCurves)
{
  /* theta_o in three bands of 60 degrees: reflection, sideways, through the ply; theta_i below 45 degrees
   * (the bins of a backlit close-up). Cotton is bright and reflective: ~2.5 % of its exit energy leaves
   * through the last band, where the far-side restart put 13 % more (0.0274 against 0.0245); 200 000 walks
   * per incident bin resolve that at ~5 standard errors per bin (with 40 000 the old rule passed, p 0.05). */
  const rdm::MapResolution bins{2, 2, 3, 2};
  const FiberPreset &preset = find_preset("cotton");
  const int n_walks = 200000;
  const rdm::RdmMaps maps = rdm::gather(preset, small_options(uint64_t(2 * 2) * n_walks, bins, false, true));
  const RendererPly ply(preset);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  ZTest zt;
  int lost = 0;
  std::string table;
  for (int ti = 0; ti < 1; ti++) {
    for (int pi = 0; pi < bins.phi_i; pi++) {
      double sum[3] = {0.0, 0.0, 0.0}, sq[3] = {0.0, 0.0, 0.0};
      for (int k = 0; k < n_walks; k++) {
        const Entry e = draw_entry(bins, ti, pi, [&] { return U(rng); });
        const ny::Vec3 ex = ny::make_vec3(1.0f, 0.0f, 0.0f);
        const RendererWalk w = ply.walk(k, e, rng);
        lost += w.lost;
        if (!w.alive || w.events == 0) {
          continue; /* absorbed, or T (not in the R and M maps) */
        }
        const ny::Vec3 d = w.d;
        int band, po;
        rdm::outgoing_bin(bins, ny::dot(d, ex), ny::dot(d, e.ey), ny::dot(d, e.n), &band, &po);
        const double energy = (double(w.beta.r) + w.beta.g + w.beta.b) / 3.0;
        sum[band] += energy;
        sq[band] += energy * energy;
      }
      for (int band = 0; band < bins.theta_o; band++) {
        double gathered = 0.0, var = 0.0;
        for (int po = 0; po < bins.phi_o; po++) {
          for (int c = 0; c < 3; c++) {
            const size_t mi = maps.map_index(ti, pi, band, po) + size_t(c);
            const double w = maps.outgoing_solid_angle(band) / 3.0;
            gathered += (double(maps.r[mi]) + maps.m[mi]) * w;
            var += (double(maps.r_se[mi]) * maps.r_se[mi] + double(maps.m_se[mi]) * maps.m_se[mi]) * w * w;
          }
        }
        const double walked = sum[band] / n_walks;
        const double se = std::sqrt(std::max(0.0, sq[band] / n_walks - walked * walked) / n_walks);
        zt.add(gathered, walked, std::sqrt(var + se * se));
        table += " (" + std::to_string(ti) + "," + std::to_string(pi) + "," + std::to_string(band) + ") " +
                 std::to_string(gathered) + " vs " + std::to_string(walked) + ";";
      }
    }
  }
  EXPECT_LT(lost, 2 * n_walks / 1000);
  EXPECT_EQ(zt.n, 6);
  EXPECT_GT(zt.p_value(), 1e-4) << zt.report() << table;
}

/* How far scattered light travels along the ply (GatherStats::axial_exit_reflected, _through; D68, D72) against the
 * same renderer's walk: fleece, one theta_i bin over the hemisphere and both phi_i halves, the exit's crossing of the
 * envelope against a ray's from the entry point along the exit direction, signed the way the light travelled along
 * the axis, energy-weighted, per band of |cos(w_i, axis)|. 60 000 walks give each band's mean to ~0.02-0.05 radii;
 * the gather's 4e5 paths to ~0.4x that. */
TEST(Gather, AxialExitOffsetMatchesARendererWalk)
{
  const rdm::MapResolution bins{1, 2, 2, 2};
  const FiberPreset &preset = find_preset("fleece");
  const rdm::RdmMaps maps = rdm::gather(preset, small_options(400000, bins, false, false));
  const RendererPly ply(preset);
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  /* x where the line through o along d leaves the cylinder of radius ply.Rb (in double, as a renderer's ray would). */
  auto crossing_x = [&](ny::Vec3 o, ny::Vec3 d) {
    const double a2 = double(d.y) * d.y + double(d.z) * d.z, b = double(o.y) * d.y + double(o.z) * d.z;
    const double c = double(o.y) * o.y + double(o.z) * o.z - double(ply.Rb) * ply.Rb;
    return a2 > 0.0 ? double(o.x) + std::max(0.0, (-b + std::sqrt(std::max(b * b - a2 * c, 0.0))) / a2) * d.x
                    : double(o.x);
  };
  /* [0] exits on the entry side (R and M), [1] through the far side; per band: sums of w, w s, w s^2, w^2 s^2,
   * w^2 s, w^2. */
  double m[2][ny::kExitBands][6] = {};
  int lost = 0;
  const int n_walks = 60000;
  for (int k = 0; k < n_walks; k++) {
    const Entry e = draw_entry(bins, 0, (k >> 1) & 1, [&] { return U(rng); });
    const RendererWalk w = ply.walk(k, e, rng);
    lost += w.lost;
    const bool through = ny::dot(w.d, e.n) < 0.0f;
    if (!w.alive || w.events == 0) {
      continue; /* absorbed or T */
    }
    const double travel = e.wi.x > 0.0f ? -1.0 : 1.0; /* the light goes along -w_i */
    const double s = travel * (crossing_x(w.o, w.d) - crossing_x(e.n * ply.Rb, w.d)) /
                     double(ply.tracer.ply_radius());
    const int band = std::min(ny::kExitBands - 1, int(std::abs(e.wi.x) * float(ny::kExitBands)));
    /* The light that came in with it: w_i is drawn uniformly in solid angle (the gather's one theta bin). */
    const double wt = (double(w.beta.r) + w.beta.g + w.beta.b) / 3.0 * double(ny::dot(e.wi, e.n));
    const double add[6] = {wt, wt * s, wt * s * s, wt * wt * s * s, wt * wt * s, wt * wt};
    for (int i = 0; i < 6; i++) {
      m[int(through)][band][i] += add[i];
    }
  }
  EXPECT_LT(lost, n_walks / 1000);
  const rdm::GatherStats &st = maps.stats;
  const size_t nq = size_t(ny::kExitBands) * ny::kExitQuantiles;
  ASSERT_EQ(st.axial_exit_reflected.size(), nq);
  ASSERT_EQ(st.axial_exit_through.size(), nq);
  ASSERT_EQ(int(st.mean_axial_exit_reflected.size()), ny::kExitBands);
  ASSERT_EQ(int(st.mean_axial_exit_through.size()), ny::kExitBands);
  for (int j = 0; j < 2; j++) {
    const std::vector<double> &gathered = j ? st.mean_axial_exit_through : st.mean_axial_exit_reflected;
    const std::vector<double> &q = j ? st.axial_exit_through : st.axial_exit_reflected;
    for (int b = 0; b < ny::kExitBands; b++) {
      const double *mb = m[j][b];
      const double W = mb[0], mean = mb[1] / W;
      /* The ratio estimator's standard error: sum w^2 (s - mean)^2 / W^2. */
      const double se = std::sqrt(std::max(0.0, mb[3] - 2.0 * mean * mb[4] + mean * mean * mb[5])) / W;
      /* The gather's own noise (~sqrt(60 000 / 400 000) of the walk's) and its bins' centres (0.01 radii). */
      const double tol = 4.0 * std::sqrt(se * se * (1.0 + 60000.0 / 400000.0)) + 0.01;
      EXPECT_NEAR(gathered[size_t(b)], mean, tol)
          << (j ? "through" : "entry side") << ", band " << b << ": walked " << mean << " +- " << se;
      for (int k = 1; k < ny::kExitQuantiles; k++) {
        EXPECT_GE(q[size_t(b * ny::kExitQuantiles + k)], q[size_t(b * ny::kExitQuantiles + k - 1)]);
      }
    }
    /* It must measure something, in both: light along the axis keeps going (fleece ~0.7-0.8 radii), light across
     * it hardly moves on average (~0.06). */
    EXPECT_GT(m[j][ny::kExitBands - 1][1] / m[j][ny::kExitBands - 1][0], 0.4) << (j ? "through" : "entry side");
    EXPECT_LT(std::abs(m[j][0][1] / m[j][0][0]), 0.2) << (j ? "through" : "entry side");
    EXPECT_GT(gathered[ny::kExitBands - 1], 0.4) << (j ? "through" : "entry side");
    EXPECT_LT(std::abs(gathered[0]), 0.2) << (j ? "through" : "entry side");
  }
}

/* Where around the ply light came in, given where it leaves (decisions D73): the gather's entry-h quantiles per row of
 * the exit's h against the same statistic from a renderer's walk through Embree curves. Per side (the leaving point's
 * half: facing the light or not) and row, the mean entry h (the quantile function's trapezoid mean: its knots, the
 * ends stepped out and kept on [-1, 1]) must be the walk's within its noise, and what it measures must show: light
 * across the axis that leaves through the far side at the width's edge came in nearer the middle, light that leaves
 * on its own side near where it came in. */
TEST(Gather, EntryAcrossTheWidthMatchesARendererWalk)
{
  /* The walks draw w_i uniformly in solid angle; the gather's theta bins of equal angle hold equal paths, and its
   * weights must make up for that (unweighted, the gather's 22 bins put the far side's edge row's median at -0.39 for
   * the -0.81 the weights give at any bins). */
  const rdm::MapResolution bins{1, 2, 2, 2};
  const FiberPreset &preset = find_preset("fleece");
  const rdm::RdmMaps maps = rdm::gather(preset, small_options(400000, {6, 2, 2, 2}, false, false));
  const RendererPly ply(preset);
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  /* h across the width seen along w of where the line through o along d leaves the cylinder, and its half. */
  auto width = [&](ny::Vec3 o, ny::Vec3 d, ny::Vec3 w, bool *facing) {
    double y = o.y, z = o.z;
    const double a2 = double(d.y) * d.y + double(d.z) * d.z;
    if (a2 > 0.0) {
      const double b = y * d.y + z * d.z, c = y * y + z * z - double(ply.Rb) * ply.Rb;
      const double t = std::max(0.0, (-b + std::sqrt(std::max(b * b - a2 * c, 0.0))) / a2);
      y += t * d.y;
      z += t * d.z;
    }
    *facing = y * w.y + z * w.z >= 0.0;
    const double aw = std::sqrt(double(w.y) * w.y + double(w.z) * w.z);
    return std::clamp((y * w.z - z * w.y) / (aw * double(ply.Rb)), -1.0, 1.0);
  };
  /* [half][band][row]: sums of w, w h, w^2 h^2, w^2 h, w^2 (the mirror image included, as the gather records it) */
  double m[2][ny::kExitBands][ny::kEntryRows][5] = {};
  const int n_walks = 60000;
  for (int k = 0; k < n_walks; k++) {
    const Entry e = draw_entry(bins, 0, (k >> 1) & 1, [&] { return U(rng); });
    const RendererWalk w = ply.walk(k, e, rng);
    if (!w.alive || w.events == 0 || !(std::abs(e.wi.x) < 0.9999f)) {
      continue;
    }
    bool facing = true, unused = true;
    const double h_in = width(e.n * ply.Rb, e.wi, e.wi, &unused), h_out = width(w.o, w.d, e.wi, &facing);
    const int band = std::min(ny::kExitBands - 1, int(std::abs(e.wi.x) * float(ny::kExitBands)));
    const double wt = (double(w.beta.r) + w.beta.g + w.beta.b) / 3.0 * double(ny::dot(e.wi, e.n));
    for (const double sign : {1.0, -1.0}) {
      const int row = std::min(ny::kEntryRows - 1, int((sign * h_out + 1.0) * 0.5 * ny::kEntryRows));
      const double h = sign * h_in, add[5] = {wt, wt * h, wt * wt * h * h, wt * wt * h, wt * wt};
      for (int i = 0; i < 5; i++) {
        m[facing ? 0 : 1][band][row][i] += add[i];
      }
    }
  }
  const rdm::GatherStats &st = maps.stats;
  const size_t nq = size_t(ny::kExitBands) * ny::kEntryRows * ny::kExitQuantiles;
  ASSERT_EQ(st.entry_h_reflected.size(), nq);
  ASSERT_EQ(st.entry_h_through.size(), nq);
  auto trapezoid_mean = [](const double *q) {
    float qf[ny::kExitQuantiles], knots[ny::kExitKnots];
    for (int k = 0; k < ny::kExitQuantiles; k++) {
      qf[k] = float(q[k]);
    }
    ny::exit_knots(qf, knots);
    knots[0] = std::max(knots[0], -1.0f);
    knots[ny::kExitKnots - 1] = std::min(knots[ny::kExitKnots - 1], 1.0f);
    double mean = 0.0;
    for (int k = 1; k < ny::kExitKnots; k++) {
      mean += double(ny::exit_knot_level(k) - ny::exit_knot_level(k - 1)) * 0.5 * double(knots[k - 1] + knots[k]);
    }
    return mean;
  };
  int compared = 0;
  for (int j = 0; j < 2; j++) {
    const std::vector<double> &q = j ? st.entry_h_through : st.entry_h_reflected;
    for (int b = 0; b < ny::kExitBands; b++) {
      double W_band = 0.0;
      for (int r = 0; r < ny::kEntryRows; r++) {
        W_band += m[j][b][r][0];
      }
      for (int r = 0; r < ny::kEntryRows; r++) {
        const double *mr = m[j][b][r];
        const double *qr = q.data() + (size_t(b) * ny::kEntryRows + size_t(r)) * ny::kExitQuantiles;
        for (int k = 1; k < ny::kExitQuantiles; k++) {
          EXPECT_GE(qr[k], qr[k - 1]);
        }
        if (mr[0] < 0.02 * W_band) {
          continue; /* too few walks in this row to compare */
        }
        const double mean = mr[1] / mr[0];
        const double se = std::sqrt(std::max(0.0, mr[2] - 2.0 * mean * mr[3] + mean * mean * mr[4])) / mr[0];
        /* The walk's noise with the gather's (~sqrt(60 000 / 400 000) of it), the trapezoid's approximation of a
         * quantile function known at nine levels (~0.02 for the edge rows' steep tails). */
        const double tol = 4.0 * se * std::sqrt(1.0 + 60000.0 / 400000.0) + 0.03;
        EXPECT_NEAR(trapezoid_mean(qr), mean, tol)
            << (j ? "far side" : "entry side") << ", band " << b << ", row " << r << ": walked " << mean << " +- " << se;
        compared++;
      }
    }
  }
  EXPECT_GT(compared, 50);
  /* It must measure something a renderer that starts on the hit point's line (D72) leaves out: light across the axis
   * came in spread across the width (fleece, 10-90 %: ~1.0 at the far side's edge row, ~1.5 in its middle, ~0.7 in
   * the entry side's middle), more so when it went through the ply. */
  auto spread = [&](const std::vector<double> &q, int row) {
    const double *r = q.data() + size_t(row) * ny::kExitQuantiles;
    return r[6] - r[2];
  };
  EXPECT_GT(spread(st.entry_h_through, 0), 0.4);
  EXPECT_GT(spread(st.entry_h_reflected, ny::kEntryRows / 2), 0.2);
  EXPECT_GT(spread(st.entry_h_through, ny::kEntryRows / 2), spread(st.entry_h_reflected, ny::kEntryRows / 2) + 0.3);
}

TEST(Gather, EnergyBookkeeping)
{
  for (const char *name : {"fleece", "cotton", "polyester"}) {
    const rdm::RdmMaps maps = rdm::gather(find_preset(name), small_options(60000, {4, 8, 6, 8}, true, false));
    const rdm::GatherStats &s = maps.stats;
    EXPECT_EQ(s.invalid_weights, 0u) << name;
    EXPECT_EQ(s.paths_truncated, 0u) << name;
    EXPECT_EQ(s.paths_T + s.paths_R + s.paths_M + s.paths_terminated, s.paths) << name;
    for (int c = 0; c < 3; c++) {
      /* Exit + absorbed has expectation 1 per path. */
      EXPECT_NEAR(s.balance[c], 1.0, 4.0 * s.balance_se[c]) << name << " channel " << c;
      EXPECT_LT(s.balance_se[c], 0.01) << name;
    }
    /* Per incident bin, the maps integrate to the recorded exit energy: sum (R + M) dOmega + P_T. This is
     * the normalisation, so it holds to float rounding (the maps are symmetrised: compare the same). */
    for (int ti = 0; ti < maps.bins.theta_i; ti++) {
      for (int pi = 0; pi < maps.bins.phi_i; pi++) {
        const size_t i = maps.incident_index(ti, pi);
        const size_t i2 = maps.incident_index(ti, (pi + maps.bins.phi_i / 2) % maps.bins.phi_i);
        for (int c = 0; c < 3; c++) {
          double total = maps.p_t[i];
          for (int to = 0; to < maps.bins.theta_o; to++) {
            for (int po = 0; po < maps.bins.phi_o; po++) {
              const size_t mi = maps.map_index(ti, pi, to, po) + size_t(c);
              total += (double(maps.r[mi]) + double(maps.m[mi])) * maps.outgoing_solid_angle(to);
            }
          }
          const double want = 0.5 * (maps.exit_energy[i * 3 + size_t(c)] + maps.exit_energy[i2 * 3 + size_t(c)]);
          EXPECT_NEAR(total, want, 1e-5 * std::max(1.0, want)) << name << " bin " << ti << "," << pi;
        }
      }
    }
  }
}

namespace {
/* chi^2 between a map and its image under an index map, using the raw standard errors. */
ZTest compare_map_images(const rdm::RdmMaps &m, const std::vector<float> &map, const std::vector<float> &se,
                         const std::function<int(int)> &image_phi_i, const std::function<int(int)> &image_phi_o)
{
  ZTest zt;
  const rdm::MapResolution &b = m.bins;
  for (int ti = 0; ti < b.theta_i; ti++) {
    for (int pi = 0; pi < b.phi_i; pi++) {
      const int pi2 = image_phi_i(pi);
      if (pi2 < pi) {
        continue; /* each pair once */
      }
      for (int to = 0; to < b.theta_o; to++) {
        for (int po = 0; po < b.phi_o; po++) {
          const int po2 = image_phi_o(po);
          if (pi2 == pi && po2 <= po) {
            continue;
          }
          for (int c = 0; c < 3; c++) {
            const size_t a = m.map_index(ti, pi, to, po) + size_t(c), z = m.map_index(ti, pi2, to, po2) + size_t(c);
            if (se[a] > 0 && se[z] > 0) {
              zt.add(map[a], map[z], std::sqrt(double(se[a]) * se[a] + double(se[z]) * se[z]));
            }
          }
        }
      }
    }
  }
  return zt;
}
}  // namespace

/* Raw (unsymmetrised) data: a 180-degree rotation about n maps the statistics onto themselves. */
/* A very dark fiber's exit light is mostly single scattering. Russian roulette at the first event kept ~2 %
 * of those paths with weights near 1 (the stability suite's dark bake was 17.8 % off); with roulette from the
 * second event every single-scattering path reaches the map with its own small weight (D34). */
TEST(Gather, DarkFiberSingleScatteringIsNotLeftToRoulette)
{
  FiberPreset dark = find_preset("fleece");
  dark.C_R = {0.01, 0.01, 0.01};
  dark.C_TT = {0.02, 0.02, 0.02};
  const rdm::MapResolution bins{2, 4, 4, 8};
  rdm::RdmMaps maps[2];
  for (int k = 0; k < 2; k++) {
    rdm::GatherOptions o = small_options(8 * 5000, bins, true, false);
    o.seed = uint64_t(k + 1);
    maps[k] = rdm::gather(dark, o);
  }
  const std::vector<double> ea = maps[0].energy(maps[0].r), eb = maps[1].energy(maps[1].r);
  double rel = 0.0;
  for (size_t i = 0; i < ea.size(); i++) {
    ASSERT_GT(ea[i] + eb[i], 0.0);
    rel += std::abs(ea[i] - eb[i]) / (ea[i] + eb[i]) / double(ea.size());
  }
  /* These seeds: 1.7 % with roulette from the second event, 5.9 % with it at the first (noise ~ 1/sqrt of
   * the paths that carry the R map, ~50x more now); 3 % lies between them by a factor ~2 either way. */
  EXPECT_LT(rel, 0.03) << "mean |A - B| / (A + B) of the R energies per incident bin and channel";
}

TEST(Gather, RawDataHasTheHalfTurnSymmetry)
{
  const rdm::RdmMaps m = rdm::gather(find_preset("fleece"), small_options(3 * 8 * 25000, {3, 8, 6, 8}, false, true));
  const int hi = m.bins.phi_i / 2, ho = m.bins.phi_o / 2;
  for (const auto *which : {&m.r, &m.m}) {
    const auto &se = which == &m.r ? m.r_se : m.m_se;
    const ZTest zt = compare_map_images(m, *which, se, [&](int p) { return (p + hi) % m.bins.phi_i; },
                                        [&](int p) { return (p + ho) % m.bins.phi_o; });
    EXPECT_GT(zt.n, 300);
    EXPECT_GT(zt.p_value(), 1e-4) << (which == &m.r ? "R: " : "M: ") << zt.report();
  }
}

/* Symmetrised maps: each bin is the mean of the raw bin and its half-turn image (the same paths, seed and
 * threads), so a bin and its image hold the same value (kills a symmetrisation that averages with the wrong
 * bin or forgets the outgoing half turn; docs/benchmarks.md, "Test power"). */
TEST(Gather, SymmetrisedBinIsTheMeanOfTheRawBinAndItsHalfTurnImage)
{
  const rdm::MapResolution bins{3, 8, 6, 8};
  const rdm::RdmMaps raw = rdm::gather(find_preset("fleece"), small_options(3 * 8 * 4000, bins, false, false));
  const rdm::RdmMaps sym = rdm::gather(find_preset("fleece"), small_options(3 * 8 * 4000, bins, true, false));
  const int hi = bins.phi_i / 2, ho = bins.phi_o / 2;
  int nonzero = 0;
  for (int ti = 0; ti < bins.theta_i; ti++) {
    for (int pi = 0; pi < bins.phi_i; pi++) {
      const int pi2 = (pi + hi) % bins.phi_i;
      EXPECT_NEAR(sym.p_t[size_t(sym.incident_index(ti, pi))],
                  0.5 * (raw.p_t[size_t(raw.incident_index(ti, pi))] + raw.p_t[size_t(raw.incident_index(ti, pi2))]),
                  1e-6);
      for (int to = 0; to < bins.theta_o; to++) {
        for (int po = 0; po < bins.phi_o; po++) {
          const int po2 = (po + ho) % bins.phi_o;
          for (const auto map : {&rdm::RdmMaps::r, &rdm::RdmMaps::m}) {
            for (int c = 0; c < 3; c++) {
              const size_t a = sym.map_index(ti, pi, to, po) + size_t(c), b = sym.map_index(ti, pi2, to, po2) + size_t(c);
              const double want = 0.5 * (double((raw.*map)[a]) + double((raw.*map)[b]));
              EXPECT_EQ((sym.*map)[a], (sym.*map)[b]);
              EXPECT_NEAR((sym.*map)[a], want, 1e-6 * want + 1e-12);
              nonzero += want > 0.0;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(nonzero, 1000);
}

/* alpha = 0: straight fibers are symmetric under x -> -x, i.e. phi -> pi - phi for both directions. */
TEST(Gather, UntwistedPlyIsMirrorSymmetric)
{
  const rdm::RdmMaps m = rdm::gather(find_preset("silk"), small_options(3 * 8 * 25000, {3, 8, 6, 8}, false, true));
  auto mirror = [](int P) { return [P](int p) { return ((P / 2 - 1 - p) % P + P) % P; }; };
  for (const auto *which : {&m.r, &m.m}) {
    const auto &se = which == &m.r ? m.r_se : m.m_se;
    const ZTest zt = compare_map_images(m, *which, se, mirror(m.bins.phi_i), mirror(m.bins.phi_o));
    EXPECT_GT(zt.n, 300);
    EXPECT_GT(zt.p_value(), 1e-4) << (which == &m.r ? "R: " : "M: ") << zt.report();
  }
}

TEST(Gather, BitIdenticalAcrossThreadCounts)
{
  auto run = [](int threads) {
    rdm::GatherOptions o = small_options(50000, {4, 8, 6, 8}, true, true);
    o.threads = threads;
    return rdm::gather(find_preset("gabardine"), o);
  };
  const rdm::RdmMaps a = run(1), b = run(2), c = run(3);
  for (const rdm::RdmMaps *x : {&b, &c}) {
    EXPECT_EQ(a.count, x->count);
    EXPECT_EQ(a.p_t, x->p_t);
    EXPECT_EQ(a.r, x->r);
    EXPECT_EQ(a.m, x->m);
    EXPECT_EQ(a.r_se, x->r_se);
    EXPECT_EQ(a.m_se, x->m_se);
    EXPECT_EQ(a.exit_energy, x->exit_energy);
    EXPECT_EQ(a.absorbed, x->absorbed);
    EXPECT_EQ(a.stats.events_histogram, x->stats.events_histogram);
    for (int ch = 0; ch < 3; ch++) {
      EXPECT_EQ(a.stats.balance[ch], x->stats.balance[ch]);
      EXPECT_EQ(a.stats.energy_M[ch], x->stats.energy_M[ch]);
    }
    EXPECT_EQ(a.stats.mean_displacement, x->stats.mean_displacement);
    EXPECT_EQ(a.stats.axial_exit_reflected, x->stats.axial_exit_reflected);
    EXPECT_EQ(a.stats.mean_axial_exit_through, x->stats.mean_axial_exit_through);
  }
}

/* Two gathers with different path seeds (same geometry) agree within their standard errors, and
 * symmetrisation shrinks the standard errors by about 1/sqrt(2). */
TEST(Gather, IndependentHalvesAgreeWithinNoise)
{
  rdm::GatherOptions o = small_options(3 * 8 * 20000, {3, 8, 6, 8}, true, true);
  o.seed = 11;
  const rdm::RdmMaps a = rdm::gather(find_preset("polyester"), o);
  o.seed = 12;
  const rdm::RdmMaps b = rdm::gather(find_preset("polyester"), o);
  ZTest zt;
  for (size_t i = 0; i < a.m.size(); i++) {
    if (a.m_se[i] > 0 && b.m_se[i] > 0) {
      /* Symmetrised bins come in identical pairs: count each pair once by halving. */
      zt.add(a.m[i], b.m[i], std::sqrt(double(a.m_se[i]) * a.m_se[i] + double(b.m_se[i]) * b.m_se[i]));
    }
  }
  ZTest halved = zt;
  halved.chi2 *= 0.5;
  halved.n /= 2;
  EXPECT_GT(halved.n, 300);
  EXPECT_GT(halved.p_value(), 1e-4) << zt.report();
  for (size_t i = 0; i < a.p_t.size(); i++) {
    EXPECT_NEAR(a.p_t[i], b.p_t[i], 5.0 * std::sqrt(double(a.p_t_se[i]) * a.p_t_se[i] + double(b.p_t_se[i]) * b.p_t_se[i]) + 1e-6);
  }
  /* Symmetrisation: raw standard errors are about sqrt(2) larger. */
  o.symmetrize = false;
  const rdm::RdmMaps raw = rdm::gather(find_preset("polyester"), o);
  std::vector<double> ratios;
  for (size_t i = 0; i < raw.m.size(); i++) {
    if (raw.m_se[i] > 0 && b.m_se[i] > 0 && raw.m[i] > 0.05f) {
      ratios.push_back(double(b.m_se[i]) / raw.m_se[i]);
    }
  }
  ASSERT_GT(ratios.size(), 100u);
  std::nth_element(ratios.begin(), ratios.begin() + long(ratios.size() / 2), ratios.end());
  EXPECT_NEAR(ratios[ratios.size() / 2], 1.0 / std::sqrt(2.0), 0.05);
}

/* Several cross-sections (D42): the maps spread their paths evenly over the packings packing_seed,
 * packing_seed + 1, ..., so they estimate the mean of the single cross-sections' maps. P_T, the fraction of
 * light that passes unscattered, is the most precise number a map holds and depends on where the fibers lie:
 * one cross-section's P_T is told apart from another's, while the two-layout maps agree with their mean. */
TEST(Gather, SeveralCrossSectionsHoldTheirMean)
{
  const FiberPreset p = find_preset("polyester");
  const rdm::MapResolution bins{4, 8, 6, 8};
  const uint64_t n = 2 * 4 * 8 * 6000;
  auto run = [&](uint64_t packing_seed, int layouts, uint64_t paths, uint64_t seed) {
    rdm::GatherOptions o = small_options(paths, bins, true, true);
    o.packing_seed = packing_seed;
    o.layouts = layouts;
    o.seed = seed;
    return rdm::gather(p, o);
  };
  const rdm::RdmMaps one = run(5, 1, n, 21), other = run(6, 1, n, 22), both = run(5, 2, 2 * n, 23);
  EXPECT_EQ(both.layouts, 2);
  EXPECT_EQ(both.packing_seed, 5u);
  ZTest mean_z, apart_z;
  for (size_t i = 0; i < both.p_t.size(); i++) {
    const double mean = 0.5 * (double(one.p_t[i]) + other.p_t[i]);
    const double se_mean = 0.5 * std::hypot(double(one.p_t_se[i]), double(other.p_t_se[i]));
    if (se_mean > 0 && both.p_t_se[i] > 0) {
      mean_z.add(both.p_t[i], mean, std::hypot(double(both.p_t_se[i]), se_mean));
      apart_z.add(one.p_t[i], other.p_t[i], std::hypot(double(one.p_t_se[i]), double(other.p_t_se[i])));
    }
  }
  for (ZTest *z : {&mean_z, &apart_z}) { /* symmetrised incident bins come in identical pairs */
    z->chi2 *= 0.5;
    z->n /= 2;
  }
  EXPECT_GE(mean_z.n, 6);
  EXPECT_GT(mean_z.p_value(), 1e-4) << mean_z.report();
  EXPECT_LT(apart_z.p_value(), 1e-6) << "two cross-sections should differ: " << apart_z.report();
  /* The M map too: the mean within its noise. */
  ZTest m_z;
  for (size_t i = 0; i < both.m.size(); i++) {
    const double se_mean = 0.5 * std::hypot(double(one.m_se[i]), double(other.m_se[i]));
    if (se_mean > 0 && both.m_se[i] > 0) {
      m_z.add(both.m[i], 0.5 * (double(one.m[i]) + other.m[i]), std::hypot(double(both.m_se[i]), se_mean));
    }
  }
  ZTest halved = m_z; /* symmetrised bins come in identical pairs */
  halved.chi2 *= 0.5;
  halved.n /= 2;
  EXPECT_GT(halved.n, 300);
  EXPECT_GT(halved.p_value(), 1e-4) << m_z.report();
  /* Bit-identical at any thread count with several cross-sections as with one. */
  rdm::GatherOptions o = small_options(30000, {3, 8, 6, 8}, true, false);
  o.layouts = 3;
  o.threads = 1;
  const rdm::RdmMaps t1 = rdm::gather(p, o);
  o.threads = 3;
  const rdm::RdmMaps t3 = rdm::gather(p, o);
  EXPECT_EQ(t1.m, t3.m);
  EXPECT_EQ(t1.r, t3.r);
  EXPECT_EQ(t1.p_t, t3.p_t);
  /* Averaging maps of other cross-sections would mix two yarns' draws: refused. */
  rdm::RdmMaps a = t1, b = t3;
  b.seed = a.seed + 1;
  EXPECT_NO_THROW(rdm::mean_of_maps(a, b));
  b.layouts = 2;
  EXPECT_THROW(rdm::mean_of_maps(a, b), ParameterError);
}

TEST(Gather, RejectsBadOptions)
{
  rdm::GatherOptions o;
  o.paths = 0;
  EXPECT_THROW(rdm::validate(o), ParameterError);
  o = rdm::GatherOptions();
  o.bins.phi_o = 45;
  EXPECT_THROW(rdm::validate(o), ParameterError); /* symmetrisation needs even phi bins */
  o.symmetrize = false;
  EXPECT_NO_THROW(rdm::validate(o));
  o.layouts = 0;
  EXPECT_THROW(rdm::validate(o), ParameterError);
  FiberPreset p = find_preset("fleece");
  p.rho = 0.95;
  EXPECT_THROW(rdm::gather(p, small_options(100, {2, 4, 4, 4}, true, false)), ParameterError);
  p = find_preset("fleece");
  p.alpha = std::nan("");
  EXPECT_THROW(rdm::gather(p, small_options(100, {2, 4, 4, 4}, true, false)), ParameterError);
}

/* ------------------------------------------------------------------------------------------------ */
/* Map files.                                                                                         */
/* ------------------------------------------------------------------------------------------------ */

namespace {
std::string temp_path(const std::string &name)
{
  const fs::path dir = fs::temp_directory_path() / ("ny_rdm_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return (dir / name).string();
}
std::string read_all(const std::string &path)
{
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
void write_all(const std::string &path, const std::string &data)
{
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(data.data(), std::streamsize(data.size()));
}
template<class F> std::string error_of(F f)
{
  try {
    f();
  }
  catch (const rdm::MapFileError &e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(MapFile, RoundTripAndCorruption)
{
  rdm::GatherOptions o = small_options(20000, {3, 4, 4, 6}, true, true);
  o.layouts = 2;
  const rdm::RdmMaps maps = rdm::gather(find_preset("silk"), o);
  const std::string path = temp_path("silk.nyrdm");
  rdm::save_maps(maps, path);
  const rdm::RdmMaps back = rdm::load_maps(path);
  EXPECT_EQ(back.r, maps.r);
  EXPECT_EQ(back.m, maps.m);
  EXPECT_EQ(back.p_t, maps.p_t);
  EXPECT_EQ(back.count, maps.count);
  EXPECT_EQ(back.r_se, maps.r_se);
  EXPECT_EQ(back.exit_energy, maps.exit_energy);
  EXPECT_EQ(back.bins.phi_o, 6);
  EXPECT_EQ(back.preset.name, "silk");
  EXPECT_EQ(back.preset.beta_R_deg, maps.preset.beta_R_deg);
  EXPECT_EQ(back.paths, 20000u);
  EXPECT_EQ(back.layouts, 2);
  /* The file stores the histogram up to its last non-empty bin. */
  std::vector<uint64_t> trimmed = maps.stats.events_histogram;
  while (!trimmed.empty() && trimmed.back() == 0) {
    trimmed.pop_back();
  }
  EXPECT_EQ(back.stats.events_histogram, trimmed);
  EXPECT_EQ(back.stats.axial_exit_reflected, maps.stats.axial_exit_reflected);
  EXPECT_EQ(back.stats.axial_exit_through, maps.stats.axial_exit_through);
  ASSERT_EQ(maps.stats.entry_h_through.size(), size_t(ny::kExitBands * ny::kEntryRows * ny::kExitQuantiles));
  EXPECT_EQ(back.stats.entry_h_reflected, maps.stats.entry_h_reflected);
  EXPECT_EQ(back.stats.entry_h_through, maps.stats.entry_h_through);
  EXPECT_EQ(back.stats.mean_axial_exit_reflected, maps.stats.mean_axial_exit_reflected);
  EXPECT_EQ(back.stats.mean_axial_exit_through, maps.stats.mean_axial_exit_through);
  EXPECT_EQ(int(back.stats.axial_exit_reflected.size()), ny::kExitBands * ny::kExitQuantiles);
  /* No temporary file is left behind. */
  int files = 0;
  for (const auto &e : fs::directory_iterator(fs::path(path).parent_path())) {
    files += e.path().filename().string().find(".tmp-") != std::string::npos;
  }
  EXPECT_EQ(files, 0);

  const std::string good = read_all(path);
  const std::string bad = temp_path("bad.nyrdm");
  write_all(bad, good.substr(0, good.size() - 100));
  EXPECT_NE(error_of([&] { rdm::load_maps(bad); }).find("truncated"), std::string::npos);
  std::string flipped = good;
  flipped[flipped.size() - 7] ^= 0x10;
  write_all(bad, flipped);
  EXPECT_NE(error_of([&] { rdm::load_maps(bad); }).find("hash mismatch"), std::string::npos);
  std::string text = good;
  text[5] = '\n'; /* a text-mode transfer rewrote "\r\n" */
  write_all(bad, text);
  EXPECT_NE(error_of([&] { rdm::load_maps(bad); }).find("bad magic"), std::string::npos);
  std::string newer = good;
  newer[8] = 3;
  write_all(bad, newer);
  EXPECT_NE(error_of([&] { rdm::load_maps(bad); }).find("version 3 is not supported"), std::string::npos);
  /* Version 2 (a yarn's maps) needs the header's yarn structure: a ply's header marked 2 is refused. */
  newer[8] = 2;
  write_all(bad, newer);
  EXPECT_NE(error_of([&] { rdm::load_maps(bad); }), "");
  write_all(bad, good.substr(0, 30));
  EXPECT_NE(error_of([&] { rdm::load_maps(bad); }), "");
  EXPECT_NE(error_of([&] { rdm::load_maps(temp_path("missing.nyrdm")); }).find("cannot open"), std::string::npos);
  /* The header's JSON edited (its length field rewritten; the payload's hash does not cover it). */
  auto with_header = [&](const std::function<void(nlohmann::json &)> &change) {
    uint64_t h = 0;
    std::memcpy(&h, good.data() + 12, 8);
    nlohmann::json header = nlohmann::json::parse(good.substr(20, size_t(h)));
    change(header);
    const std::string text = header.dump();
    const uint64_t n = text.size();
    std::string out = good.substr(0, 12) + std::string(reinterpret_cast<const char *>(&n), 8) + text +
                      good.substr(20 + size_t(h));
    write_all(bad, out);
  };
  /* Maps from D68 to D72 hold the offsets unsigned and pooled, under other keys: they load, with none (a model
   * made from them keeps no near field). */
  with_header([](nlohmann::json &hd) {
    nlohmann::json &s = hd["summary"];
    for (const char *side : {"reflected", "through"}) {
      s[std::string("axial_exit_") + side + "_R"] = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
      s[std::string("mean_axial_exit_") + side + "_R"] = 0.3;
      s.erase(std::string("axial_exit_") + side + "_bands_R");
      s.erase(std::string("mean_axial_exit_") + side + "_bands_R");
    }
  });
  const rdm::RdmMaps d68 = rdm::load_maps(bad);
  EXPECT_TRUE(d68.stats.axial_exit_through.empty());
  EXPECT_TRUE(model::near_field_of(d68).empty());
  /* A band short: refused, naming it. */
  with_header([](nlohmann::json &hd) { hd["summary"]["axial_exit_through_bands_R"].erase(0); });
  EXPECT_NE(error_of([&] { rdm::load_maps(bad); }).find("axial exit offsets must hold 5 bands of 9"), std::string::npos);
  /* Maps from before D73: no entry h; they load, and a model from them starts paths on the hit point's line. */
  with_header([](nlohmann::json &hd) {
    hd["summary"].erase("entry_h_reflected_bands_rows");
    hd["summary"].erase("entry_h_through_bands_rows");
  });
  const rdm::RdmMaps d72 = rdm::load_maps(bad);
  EXPECT_TRUE(d72.stats.entry_h_through.empty());
  EXPECT_FALSE(model::near_field_of(d72).through.empty());
  EXPECT_TRUE(model::near_field_of(d72).through_entry.empty());
  rdm::save_maps(d72, bad + ".again"); /* written again: still without, and it loads */
  EXPECT_TRUE(rdm::load_maps(bad + ".again").stats.entry_h_through.empty());
  /* An entry h off the width, or a row short: refused. */
  for (const auto &edit : std::vector<std::function<void(nlohmann::json &)>>{
           [](nlohmann::json &hd) { hd["summary"]["entry_h_through_bands_rows"][3] = 1.5; },
           [](nlohmann::json &hd) { hd["summary"]["entry_h_reflected_bands_rows"].erase(0); },
           [](nlohmann::json &hd) { hd["summary"]["entry_h_reflected_bands_rows"][8] = -1.0; /* a row's 99 % below its 95 % */ }}) {
    with_header(edit);
    EXPECT_NE(error_of([&] { rdm::load_maps(bad); }).find("the entry's h must hold 5 bands of 10 rows"), std::string::npos);
  }
  /* Unwritable destination: an error, and an existing file there is left alone. */
  EXPECT_NE(error_of([&] { rdm::save_maps(maps, "/nonexistent-dir/x.nyrdm"); }).find("does not exist"), std::string::npos);
  EXPECT_NE(error_of([&] { rdm::save_maps(maps, "/dev/null/x.nyrdm"); }), "");
  fs::remove_all(fs::path(path).parent_path());
}

/* The binner the R lobe's quadrature uses must put every direction where outgoing_bin does: random directions
 * (the bins of their exact angles) and directions a hair (1e-9 rad) either side of every bin edge, where a
 * first guess from float acosf / atan2f is off by one and the edge test must settle it. */
TEST(OutgoingBinner, PutsEveryDirectionWhereOutgoingBinDoes)
{
  for (const rdm::MapResolution b : {rdm::MapResolution{22, 90, 45, 90}, rdm::MapResolution{4, 8, 7, 12}}) {
    const rdm::OutgoingBinner binner(b);
    auto check = [&](double x, double y, double z) {
      int to0, po0, to1, po1;
      rdm::outgoing_bin(b, x, y, z, &to0, &po0);
      binner(x, y, z, &to1, &po1);
      ASSERT_EQ(to0, to1) << x << " " << y << " " << z;
      ASSERT_EQ(po0, po1) << x << " " << y << " " << z;
    };
    std::mt19937_64 rng(7);
    std::normal_distribution<double> N;
    for (int i = 0; i < 200000; i++) {
      const double x = N(rng), y = N(rng), z = N(rng), r = std::sqrt(x * x + y * y + z * z);
      check(x / r, y / r, z / r);
    }
    for (int t = 0; t <= b.theta_o; t++) {
      for (int k = 0; k <= b.phi_o; k++) {
        for (double dt : {-1e-9, 1e-9}) {
          for (double dp : {-1e-9, 1e-9}) {
            const double theta = kPi * t / b.theta_o + dt, phi = -kPi + 2.0 * kPi * k / b.phi_o + dp;
            check(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
          }
        }
      }
    }
    /* The poles and the -x half-line, where atan2 reads the sign of a zero. */
    for (double z : {-1.0, 1.0}) {
      check(0.0, 0.0, z);
    }
    check(-1.0, 0.0, 0.0);
    check(-1.0, -0.0, 0.0);
    /* Next to the -x half-line, where the azimuth's guess must stay on y's side of pi / -pi: y far below what
     * the pseudo-angle resolves (it rounds to exactly -x there), and subnormal. */
    for (double y : {1e-17, -1e-17, 1e-300, -1e-300, 4.9e-324, -4.9e-324}) {
      for (double z : {0.0, 0.6, -0.6}) {
        check(-std::sqrt(1.0 - z * z), y, z);
      }
    }
  }
}
