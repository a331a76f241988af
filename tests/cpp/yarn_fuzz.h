// SPDX-License-Identifier: Apache-2.0
// Fuzzing the aggregated yarn BSDF (issue 19): eval, pdf and sample of kernel/yarn_bsdf.h on random models
// (synthetic_model.h: random networks with biases from very dark to saturated, every preset's twist,
// random proxies from an all-R needle to a uniform M), w_i and w_o anywhere on the sphere (with exactly
// normal and exactly tangent w_i among them), every third call with the lobes widened by a renderer's glossy
// filter of random roughness (D61), and random numbers including the interval ends. Every output
// must be finite and non-negative, and a sampled direction a unit vector. Work is split into chunks of
// kFuzzChunk iterations whose model and random numbers depend only on (seed, chunk): the same result at any
// thread count. Used by the CI test (test_yarn_bsdf.cpp, 10^7 calls) and by the on-demand program
// fuzz_yarn_bsdf (10^8 and more).
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>

#include "synthetic_model.h"

namespace neuralyarn::testing {

constexpr long kFuzzChunk = 1 << 15; /* iterations (4 calls each) per random model */

struct FuzzResult {
  long calls = 0, bad = 0;
  std::string first_bad; /* the first failing case found (lowest chunk), empty if none */
};

/* The random model of one chunk. */
inline model::YarnModel fuzz_model(uint64_t seed, long chunk)
{
  static const char *presets[] = {"fleece", "silk", "polyester", "cotton", "gabardine"};
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + uint64_t(chunk));
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const char *preset = presets[rng() % 5];
  const double m_bias = -12.0 + 32.0 * U(rng); /* M from ~1e-5 to saturated */
  model::YarnModel m = synthetic_model(preset, rng(), m_bias);
  switch (rng() % 4) {
    case 0: break; /* the synthetic default */
    case 1: m.proxy = {1.0, 0.001, 0.001, 1.0}; break; /* all R, needle-sharp M lobe */
    case 2: m.proxy = {0.0, 3.0, 60.0, 0.0}; break;    /* no R, uniform M */
    default: m.proxy = {U(rng), 0.001 + 1.5 * U(rng), 0.001 + 3.0 * U(rng), U(rng)}; break;
  }
  return m;
}

inline FuzzResult fuzz_yarn_bsdf(long iterations, uint64_t seed, const std::function<void(long)> &progress = {})
{
  const long chunks = (iterations + kFuzzChunk - 1) / kFuzzChunk;
  std::atomic<long> bad{0}, done{0};
  std::mutex mu;
  long first_chunk = chunks;
  std::string first;
  tbb::parallel_for(long(0), chunks, [&](long chunk) {
    const std::vector<float> flat = fuzz_model(seed, chunk).kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    std::mt19937_64 rng(seed * 0xD1B54A32D192ED03ull + uint64_t(chunk) * 7 + 1);
    std::uniform_real_distribution<float> U(0.0f, 1.0f), S(-1.0f, 1.0f);
    auto u = [&]() {
      const float v = U(rng);
      return v < 0.01f ? 0.0f : (v > 0.99f ? 0.99999994f : v);
    };
    const long n = std::min(kFuzzChunk, iterations - chunk * kFuzzChunk);
    for (long i = 0; i < n; i++) {
      ny::Vec3 wi = ny::normalize(ny::make_vec3(S(rng), S(rng), S(rng)));
      if (i % 97 == 0) {
        wi = ny::make_vec3(0.0f, 0.0f, 1.0f); /* exactly normal */
      }
      if (i % 89 == 0) {
        wi = ny::make_vec3(1.0f, 0.0f, 0.0f); /* exactly along the tangent, grazing */
      }
      const ny::Vec3 wo = ny::normalize(ny::make_vec3(S(rng), S(rng), S(rng)));
      float pdf = 0, pdf2 = 0;
      ny::Rgb f;
      ny::YarnSample s;
      const float u1 = u(), u2 = u(), u3 = u();
      bool ok;
      if (i % 3 == 2) { /* a renderer's glossy filter (Cycles' bsdf_blur, D61): the stored lobes widened */
        ny::YarnLobes l = ny::yarn_lobes(p, wi);
        ny::yarn_lobes_blur(l, ny::yarn_beta_of_ggx_alpha(0.5f * U(rng)));
        f = ny::yarn_eval_pdf_lobes(p, l, wo, &pdf);
        pdf2 = ny::yarn_pdf_lobes(p, l, wo);
        ok = ny::yarn_sample_lobes(p, l, u1, u2, u3, (i & 1) != 0, &s);
      }
      else {
        f = ny::yarn_eval(p, wi, wo, &pdf);
        pdf2 = ny::yarn_pdf(p, wi, wo);
        ok = ny::yarn_sample(p, wi, u1, u2, u3, (i & 1) != 0, &s);
      }
      const bool good = std::isfinite(f.r) && std::isfinite(f.g) && std::isfinite(f.b) && f.r >= 0 && f.g >= 0 &&
                        f.b >= 0 && std::isfinite(pdf) && pdf >= 0 && std::isfinite(pdf2) && pdf2 >= 0 &&
                        std::isfinite(s.weight.r) && std::isfinite(s.weight.g) && std::isfinite(s.weight.b) &&
                        s.weight.r >= 0 && s.weight.g >= 0 && s.weight.b >= 0 && std::isfinite(s.pdf) &&
                        s.pdf >= 0 && std::isfinite(s.wo.x) && std::isfinite(s.wo.y) && std::isfinite(s.wo.z) &&
                        (!ok || std::abs(ny::length(s.wo) - 1.0f) < 1e-3f);
      if (!good) {
        bad++;
        std::lock_guard<std::mutex> lock(mu);
        if (chunk < first_chunk) {
          char buf[512];
          std::snprintf(buf, sizeof(buf),
                        "chunk %ld iteration %ld: wi (%.9g %.9g %.9g) wo (%.9g %.9g %.9g) u (%.9g %.9g %.9g): "
                        "f (%g %g %g) pdf %g / %g, sample weight (%g %g %g) pdf %g",
                        chunk, i, wi.x, wi.y, wi.z, wo.x, wo.y, wo.z, u1, u2, u3, f.r, f.g, f.b, pdf, pdf2,
                        s.weight.r, s.weight.g, s.weight.b, s.pdf);
          first_chunk = chunk;
          first = buf;
        }
      }
    }
    const long d = done.fetch_add(n) + n;
    if (progress) {
      progress(d);
    }
  });
  FuzzResult r;
  r.calls = 4 * iterations;
  r.bad = bad.load();
  r.first_bad = first;
  return r;
}

}  // namespace neuralyarn::testing
