// SPDX-License-Identifier: Apache-2.0
//
// Cost of packing a ply cross-section (relaxation packer) as a function of N, rho and the twist alpha
// (the packer keeps the tilted helical tubes disjoint in 3D, so twist raises the effective density); the
// counter "sweeps" is the number of relaxation sweeps until no two fibers overlapped. Seed 1. A density
// that cannot be packed is reported as an error row.
//
//   build/cpp_core/bench_geometry --benchmark_min_time=0.1
#include <benchmark/benchmark.h>

#include <exception>

#include "neuralyarn/geometry/ply.h"

namespace {

void BM_pack(benchmark::State &state)
{
  neuralyarn::geometry::PlyParams p;
  p.N = int(state.range(0));
  p.rho = double(state.range(1)) / 100.0;
  p.alpha = double(state.range(2)) / 100.0;
  p.R = 1.0;
  int sweeps = 0;
  for (auto _ : state) {
    try {
      const auto cs = neuralyarn::geometry::pack_cross_section(p, 1);
      sweeps = cs.stats.iterations;
      benchmark::DoNotOptimize(cs.centers.data());
    }
    catch (const std::exception &e) {
      state.SkipWithError(e.what());
      break;
    }
  }
  state.counters["sweeps"] = sweeps;
}

BENCHMARK(BM_pack)
    ->ArgsProduct({{200, 300, 450, 600}, {30, 50, 70, 80}, {0, 24}})
    ->ArgNames({"N", "rho_percent", "alpha_percent"})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
