// SPDX-License-Identifier: Apache-2.0
//
// Inference cost of the model's MLPs: the kernel's loops (kernel/mlp.h, one sample at a time: the generic one
// with runtime widths, and the compile-time-width one that the yarn BSDF runs for the trainer's shapes) against
// Eigen (the trainer's forward, single sample and batched per sample).
//
//   build/cpp_core/bench_mlp --benchmark_min_time=0.2
//   build/cpp_core/bench_mlp_cycles_flags --benchmark_min_time=0.2   (compiled as Cycles' CPU kernel is)
#include <benchmark/benchmark.h>

#include <random>

#include "neuralyarn/kernel/mlp.h"
#include "neuralyarn/train/mlp.h"

namespace {

using neuralyarn::train::Mlp;
using neuralyarn::train::MlpShape;

MlpShape shape_of(int which)
{
  if (which == 0) {
    return MlpShape{{3, 7, 7, 1}, ny::kMlpHeadSigmoid};
  }
  if (which == 1) {
    return MlpShape{{6, 21, 21, 3}, ny::kMlpHeadExp};
  }
  if (which == 2) {
    return MlpShape{{6, 21, 21, 21, 3}, ny::kMlpHeadExp};
  }
  if (which == 3) {
    return MlpShape{{6, 32, 32, 3}, ny::kMlpHeadExp};
  }
  return MlpShape{{6, 21, 21, 6}, ny::kMlpHeadExp}; /* two-sided M (D45) */
}

const char *name_of(int which)
{
  const char *names[] = {"T 3-7-7-1", "M 6-21-21-3", "M 6-21-21-21-3", "M 6-32-32-3", "M 6-21-21-6"};
  return names[which];
}

/* One kernel forward per iteration over 1024 fixed random inputs. */
template<class Forward> void run_kernel(benchmark::State &state, Forward forward)
{
  const int which = int(state.range(0));
  const Mlp<float> m(shape_of(which), 1);
  const std::vector<float> flat = m.to_flat();
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  std::vector<float> inputs(6 * 1024);
  for (float &v : inputs) {
    v = U(rng);
  }
  float out[ny::kMlpMaxWidth];
  size_t i = 0;
  for (auto _ : state) {
    forward(flat.data(), &inputs[(i++ & 1023) * 6], out);
    benchmark::DoNotOptimize(out[0]);
  }
  state.SetLabel(name_of(which));
}

/* The generic loop, runtime widths. */
void BM_kernel(benchmark::State &state) { run_kernel(state, ny::mlp_forward); }

/* mlp_forward_io: what yarn_bsdf.h calls (compile-time widths for 3-7-7-1, 6-21-21-3, 6-32-32-3 and
 * 6-21-21-6; the deeper shape falls back to the generic loop). */
void BM_kernel_io(benchmark::State &state)
{
  if (state.range(0) == 0) {
    run_kernel(state, ny::mlp_forward_io<3, 1>);
  }
  else if (state.range(0) == 4) {
    run_kernel(state, ny::mlp_forward_io<6, 6>);
  }
  else {
    run_kernel(state, ny::mlp_forward_io<6, 3>);
  }
}

void BM_eigen_single(benchmark::State &state)
{
  const Mlp<float> m(shape_of(int(state.range(0))), 1);
  const int n_in = m.shape().widths.front();
  Mlp<float>::Mat x = Mlp<float>::Mat::Random(n_in, 1);
  for (auto _ : state) {
    const Mlp<float>::Mat y = m.forward(x);
    benchmark::DoNotOptimize(y.data());
  }
  state.SetLabel(name_of(int(state.range(0))));
}

void BM_eigen_batch1024(benchmark::State &state)
{
  const Mlp<float> m(shape_of(int(state.range(0))), 1);
  const int n_in = m.shape().widths.front();
  Mlp<float>::Mat x = Mlp<float>::Mat::Random(n_in, 1024);
  for (auto _ : state) {
    const Mlp<float>::Mat y = m.forward(x);
    benchmark::DoNotOptimize(y.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * 1024);
  state.SetLabel(name_of(int(state.range(0))));
}

BENCHMARK(BM_kernel)->DenseRange(0, 4);
BENCHMARK(BM_kernel_io)->DenseRange(0, 4);
BENCHMARK(BM_eigen_single)->DenseRange(0, 4);
BENCHMARK(BM_eigen_batch1024)->DenseRange(0, 4);

}  // namespace

BENCHMARK_MAIN();
