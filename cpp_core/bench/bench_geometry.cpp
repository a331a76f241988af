// SPDX-License-Identifier: Apache-2.0
//
// Cost of packing a ply cross-section (relaxation packer) as a function of N and rho; the counter
// "sweeps" is the number of relaxation sweeps until no two fibers overlapped. Seed 1.
//
//   build/cpp_core/bench_geometry --benchmark_min_time=0.1
#include <benchmark/benchmark.h>

#include "neuralyarn/geometry/ply.h"

namespace {

void BM_pack(benchmark::State &state)
{
  neuralyarn::geometry::PlyParams p;
  p.N = int(state.range(0));
  p.rho = double(state.range(1)) / 100.0;
  p.alpha = 0.2;
  p.R = 1.0;
  int sweeps = 0;
  for (auto _ : state) {
    const auto cs = neuralyarn::geometry::pack_cross_section(p, 1);
    sweeps = cs.stats.iterations;
    benchmark::DoNotOptimize(cs.centers.data());
  }
  state.counters["sweeps"] = sweeps;
}

BENCHMARK(BM_pack)
    ->ArgsProduct({{200, 300, 450, 600}, {30, 50, 70, 80}})
    ->ArgNames({"N", "rho_percent"})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
