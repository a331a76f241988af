// SPDX-License-Identifier: Apache-2.0
//
// Per-call cost of the aggregated yarn BSDF (kernel/yarn_bsdf.h) with a shipped model: eval (+pdf), pdf,
// sample, over 4096 random pairs with w_i on the upper hemisphere (seed 7). The fiber BSDF it replaces is
// measured by bench_fiber_bsdf; both tables are in docs/benchmarks.md.
//
//   build/cpp_core/bench_yarn_bsdf --benchmark_min_time=0.3
//   build/cpp_core/bench_yarn_bsdf_cycles_flags --benchmark_min_time=0.3   (compiled as Cycles compiles its kernel)
#include <cmath>
#include <vector>

#include <benchmark/benchmark.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/random.h"

namespace {

constexpr int kPairs = 4096;

struct Inputs {
  std::vector<ny::Vec3> wi, wo;
  std::vector<float> u;
};

const Inputs &inputs()
{
  static const Inputs in = [] {
    Inputs r;
    neuralyarn::Rng rng(7);
    for (int i = 0; i < kPairs; i++) {
      ny::Vec3 wi = ny::sample_uniform_sphere(neuralyarn::uniform_float(rng), neuralyarn::uniform_float(rng));
      wi.z = std::fabs(wi.z) + 1e-4f;
      r.wi.push_back(ny::normalize(wi));
      r.wo.push_back(ny::sample_uniform_sphere(neuralyarn::uniform_float(rng), neuralyarn::uniform_float(rng)));
      for (int k = 0; k < 3; k++) {
        r.u.push_back(neuralyarn::uniform_float(rng));
      }
    }
    return r;
  }();
  return in;
}

const std::vector<float> &flat(const char *preset)
{
  static std::vector<std::vector<float>> cache(5);
  static const char *names[] = {"fleece", "silk", "polyester", "cotton", "gabardine"};
  for (int k = 0; k < 5; k++) {
    if (std::string(names[k]) == preset) {
      if (cache[size_t(k)].empty()) {
        cache[size_t(k)] = neuralyarn::model::load_model(neuralyarn::model::builtin_model_path(preset)).kernel_flat();
      }
      return cache[size_t(k)];
    }
  }
  throw std::runtime_error("unknown preset");
}

void BM_yarn_eval_and_pdf(benchmark::State &state, const char *preset)
{
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat(preset).data());
  const Inputs &in = inputs();
  int i = 0;
  float pdf;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::yarn_eval(p, in.wi[i], in.wo[i], &pdf));
    benchmark::DoNotOptimize(pdf);
    i = (i + 1) & (kPairs - 1);
  }
}

void BM_yarn_pdf(benchmark::State &state, const char *preset)
{
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat(preset).data());
  const Inputs &in = inputs();
  int i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::yarn_pdf(p, in.wi[i], in.wo[i]));
    i = (i + 1) & (kPairs - 1);
  }
}

/* The per-w_i part alone (what a renderer can compute once per shading point) and the rest given it. */
void BM_yarn_lobes(benchmark::State &state, const char *preset)
{
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat(preset).data());
  const Inputs &in = inputs();
  int i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::yarn_lobes(p, in.wi[i]));
    i = (i + 1) & (kPairs - 1);
  }
}

/* The lobes of every input's w_i, as a renderer keeps them per shading point. */
std::vector<ny::YarnLobes> lobes_of(const ny::YarnBsdfParams &p, const Inputs &in)
{
  std::vector<ny::YarnLobes> lobes;
  for (const ny::Vec3 &wi : in.wi) {
    lobes.push_back(ny::yarn_lobes(p, wi));
  }
  return lobes;
}

void BM_yarn_eval_and_pdf_given_lobes(benchmark::State &state, const char *preset)
{
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat(preset).data());
  const Inputs &in = inputs();
  const std::vector<ny::YarnLobes> lobes = lobes_of(p, in);
  int i = 0;
  for (auto _ : state) {
    /* As the Cycles closure's eval: both at once. */
    float pdf;
    benchmark::DoNotOptimize(ny::yarn_eval_pdf_lobes(p, lobes[size_t(i)], in.wo[i], &pdf));
    benchmark::DoNotOptimize(pdf);
    i = (i + 1) & (kPairs - 1);
  }
}

/* As the Cycles closure's sample: given the lobes of w_i, without the T lobe (Cycles' transparent closure). */
void BM_yarn_sample_given_lobes(benchmark::State &state, const char *preset)
{
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat(preset).data());
  const Inputs &in = inputs();
  const std::vector<ny::YarnLobes> lobes = lobes_of(p, in);
  int i = 0;
  ny::YarnSample s;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::yarn_sample_lobes(p, lobes[size_t(i)], in.u[3 * i], in.u[3 * i + 1],
                                                   in.u[3 * i + 2], false, &s));
    benchmark::DoNotOptimize(s);
    i = (i + 1) & (kPairs - 1);
  }
}

void BM_yarn_sample(benchmark::State &state, const char *preset)
{
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat(preset).data());
  const Inputs &in = inputs();
  int i = 0;
  ny::YarnSample s;
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        ny::yarn_sample(p, in.wi[i], in.u[3 * i], in.u[3 * i + 1], in.u[3 * i + 2], true, &s));
    benchmark::DoNotOptimize(s);
    i = (i + 1) & (kPairs - 1);
  }
}

}  // namespace

BENCHMARK_CAPTURE(BM_yarn_eval_and_pdf, fleece, "fleece");
BENCHMARK_CAPTURE(BM_yarn_pdf, fleece, "fleece");
BENCHMARK_CAPTURE(BM_yarn_lobes, fleece, "fleece");
BENCHMARK_CAPTURE(BM_yarn_eval_and_pdf_given_lobes, fleece, "fleece");
BENCHMARK_CAPTURE(BM_yarn_sample, fleece, "fleece");
BENCHMARK_CAPTURE(BM_yarn_eval_and_pdf, cotton, "cotton");
BENCHMARK_CAPTURE(BM_yarn_lobes, cotton, "cotton");
BENCHMARK_CAPTURE(BM_yarn_eval_and_pdf_given_lobes, cotton, "cotton");
BENCHMARK_CAPTURE(BM_yarn_sample, cotton, "cotton");
BENCHMARK_CAPTURE(BM_yarn_sample_given_lobes, cotton, "cotton");
BENCHMARK_CAPTURE(BM_yarn_lobes, silk, "silk");
BENCHMARK_CAPTURE(BM_yarn_eval_and_pdf_given_lobes, silk, "silk");  // one R node (beta_R = 1 degree)
BENCHMARK_CAPTURE(BM_yarn_sample, silk, "silk");
BENCHMARK_CAPTURE(BM_yarn_eval_and_pdf, gabardine, "gabardine");  // M 6-32-32-3 (D22)
BENCHMARK_CAPTURE(BM_yarn_sample, gabardine, "gabardine");

BENCHMARK_MAIN();
