// SPDX-License-Identifier: Apache-2.0
// On-demand fuzzing of the aggregated yarn BSDF (issue 19; tests/cpp/yarn_fuzz.h says what is drawn):
//
//   build/tests/fuzz_yarn_bsdf [--calls 1e8] [--seed 1] [--threads 0]
//
// prints the number of calls, random models and bad outputs (NaN, Inf, negative, a sampled direction that
// is not a unit vector) and the first bad case; exits 1 if there is any. The same numbers at any thread
// count. CI runs a 10^7-call slice (YarnBsdf.TenMillionFuzzedCallsAreFiniteAndNonNegative).
#include <chrono>
#include <cstdio>
#include <memory>

#include <tbb/global_control.h>

#include "cli_common.h"
#include "yarn_fuzz.h"

using namespace neuralyarn;
using neuralyarn::cli::ProgressBar;
using neuralyarn::cli::parse_count;

int main(int argc, char **argv)
{
  CLI::App app{"Fuzz the aggregated yarn BSDF's eval, pdf and sample with random models and directions"};
  std::string calls_text = "1e8";
  uint64_t seed = 1;
  int threads = 0;
  bool quiet = false;
  app.add_option("--calls", calls_text, "Calls in all (4 per iteration: eval, pdf, sample with and without T), e.g. 1e8 or 100M");
  app.add_option("--seed", seed, "Seed of the models and the random numbers");
  app.add_option("--threads", threads, "Worker threads (0: all cores); the result does not depend on it")->check(CLI::Range(0, 1024));
  app.add_flag("--quiet", quiet, "No progress bar");
  CLI11_PARSE(app, argc, argv);
  try {
    const uint64_t calls = parse_count(calls_text);
    const long iterations = long((calls + 3) / 4);
    std::unique_ptr<tbb::global_control> limit;
    if (threads > 0) {
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
    }
    ProgressBar bar(!quiet, "calls");
    const auto t0 = std::chrono::steady_clock::now();
    const testing::FuzzResult r = testing::fuzz_yarn_bsdf(
        iterations, seed, [&](long done) { bar.update(uint64_t(4 * done), uint64_t(4 * iterations)); });
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const long models = (iterations + testing::kFuzzChunk - 1) / testing::kFuzzChunk;
    std::printf("fuzz_yarn_bsdf: %ld calls on %ld random models (seed %llu): %ld bad (NaN, Inf, negative or "
                "not a unit direction) in %.1f s, %.2f M calls/s\n",
                r.calls, models, (unsigned long long)seed, r.bad, secs, double(r.calls) / secs / 1e6);
    if (r.bad > 0) {
      std::printf("first bad case: %s\n", r.first_bad.c_str());
      return 1;
    }
    return 0;
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "fuzz_yarn_bsdf: %s\n", e.what());
    return 1;
  }
}
