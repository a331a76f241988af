// SPDX-License-Identifier: Apache-2.0
//
// Per-call cost of the Khungurn fiber BSDF: eval (with and without the pdf), pdf and sample, for every
// preset, over a fixed set of 4096 uniformly random direction pairs (seed 7). Results go to
// docs/benchmarks.md together with the command line.
//
//   build/cpp_core/bench_fiber_bsdf --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <vector>

#include <benchmark/benchmark.h>

#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/presets.h"
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
      r.wi.push_back(ny::sample_uniform_sphere(neuralyarn::uniform_float(rng), neuralyarn::uniform_float(rng)));
      r.wo.push_back(ny::sample_uniform_sphere(neuralyarn::uniform_float(rng), neuralyarn::uniform_float(rng)));
      for (int k = 0; k < 3; k++) {
        r.u.push_back(neuralyarn::uniform_float(rng));
      }
    }
    return r;
  }();
  return in;
}

void BM_eval(benchmark::State &state, const char *preset)
{
  const ny::FiberBsdfParams p = neuralyarn::find_preset(preset).fiber_params();
  const Inputs &in = inputs();
  int i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::fiber_eval(p, in.wi[i], in.wo[i], nullptr));
    i = (i + 1) & (kPairs - 1);
  }
}

void BM_eval_and_pdf(benchmark::State &state, const char *preset)
{
  const ny::FiberBsdfParams p = neuralyarn::find_preset(preset).fiber_params();
  const Inputs &in = inputs();
  int i = 0;
  float pdf;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::fiber_eval(p, in.wi[i], in.wo[i], &pdf));
    benchmark::DoNotOptimize(pdf);
    i = (i + 1) & (kPairs - 1);
  }
}

void BM_pdf(benchmark::State &state, const char *preset)
{
  const ny::FiberBsdfParams p = neuralyarn::find_preset(preset).fiber_params();
  const Inputs &in = inputs();
  int i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::fiber_pdf(p, in.wi[i], in.wo[i]));
    i = (i + 1) & (kPairs - 1);
  }
}

void BM_sample(benchmark::State &state, const char *preset)
{
  const ny::FiberBsdfParams p = neuralyarn::find_preset(preset).fiber_params();
  const Inputs &in = inputs();
  int i = 0;
  ny::Vec3 wo;
  ny::Rgb w;
  float pdf;
  for (auto _ : state) {
    /* Further numbers for the rejection loop: the inputs that follow (fixed, as the first three). */
    int k = 3 * i;
    auto next = [&] { k = (k + 1) % (3 * kPairs); return in.u[k]; };
    benchmark::DoNotOptimize(ny::fiber_sample(p, in.wi[i], in.u[3 * i], in.u[3 * i + 1], in.u[3 * i + 2], next, &wo, &w, &pdf));
    benchmark::DoNotOptimize(w);
    i = (i + 1) & (kPairs - 1);
  }
}

/* The closure path: fiber_lobes once per shading point (w_i), then eval + pdf per w_o. */
void BM_setup(benchmark::State &state, const char *preset)
{
  const ny::FiberBsdfParams p = neuralyarn::find_preset(preset).fiber_params();
  const Inputs &in = inputs();
  int i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::fiber_lobes(p, in.wi[i]));
    i = (i + 1) & (kPairs - 1);
  }
}

void BM_eval_pdf_given_lobes(benchmark::State &state, const char *preset)
{
  const ny::FiberBsdfParams p = neuralyarn::find_preset(preset).fiber_params();
  const Inputs &in = inputs();
  const ny::FiberLobes lobes = ny::fiber_lobes(p, in.wi[0]);
  int i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ny::fiber_eval_lobes(lobes, in.wo[i]));
    benchmark::DoNotOptimize(ny::fiber_pdf_lobes(lobes, in.wo[i]));
    i = (i + 1) & (kPairs - 1);
  }
}

#define NY_BENCH_PRESET(name)                                      \
  BENCHMARK_CAPTURE(BM_eval, name, #name);                         \
  BENCHMARK_CAPTURE(BM_eval_and_pdf, name, #name);                 \
  BENCHMARK_CAPTURE(BM_pdf, name, #name);                          \
  BENCHMARK_CAPTURE(BM_sample, name, #name);                       \
  BENCHMARK_CAPTURE(BM_setup, name, #name);                        \
  BENCHMARK_CAPTURE(BM_eval_pdf_given_lobes, name, #name);

NY_BENCH_PRESET(fleece)
NY_BENCH_PRESET(silk)
NY_BENCH_PRESET(polyester)
NY_BENCH_PRESET(cotton)
NY_BENCH_PRESET(gabardine)

}  // namespace

BENCHMARK_MAIN();
