// SPDX-License-Identifier: Apache-2.0
//
// The standard normal by the ziggurat method (Marsaglia & Tsang 2000, "The Ziggurat Method for Generating
// Random Variables", J. Stat. Softw. 5(8)), for the random walk's longitudinal lobes.
//
// The half density f(z) = exp(-z^2 / 2), z >= 0, is covered by 128 layers of equal area v: layer 0 is the
// rectangle [0, x_0] x [0, f(r)] (x_0 = v / f(r)), holding the tail beyond r = x_1 in its part past r;
// layer i >= 1 is [0, x_i] x [f(x_i), f(x_{i+1})], x_128 = 0. A draw picks a layer and a point z = U x_i in
// it: where z < x_{i+1} the point lies under f and is returned (about 98.8 % of draws, a table read and a
// multiply); otherwise the wedge is tested against f (one exp) or, in layer 0, the tail is sampled by
// Marsaglia's exponential rejection. The result is exactly the normal, up to the random numbers'
// resolution — unlike an inverse CDF, no erfc for the truncation bounds and no quantile per draw
// (docs/benchmarks.md has the gather's speed-up).
//
// The layer and the sign come from one uniform's top eight bits and U from a second uniform, never from
// the same bits (Doornik 2005 shows the correlation the original's shared integer leaves). Host code only:
// the renderer's closures sample by inverse CDF from their Cycles-given random numbers (kernel/sampling.h).
#pragma once

#include <cmath>

namespace neuralyarn::rdm {

struct NormalZiggurat {
  static constexpr int kLayers = 128;
  static constexpr double kR = 3.442619855899;         /* x_1: where the tail begins       */
  static constexpr double kArea = 9.91256303526217e-3; /* v: each layer's area             */
  double x[kLayers + 1]; /* right edges, x[128] = 0        */
  double f[kLayers + 1]; /* exp(-x^2 / 2) at them          */
  NormalZiggurat();
  /* The tables, built once; a caller in a hot loop keeps the reference (no guard check per draw). */
  static const NormalZiggurat &get();
};

/* A standard normal variate from the tables `zig`; `uniform()` returns numbers in [0, 1) (24 bits or more). */
template<class Uniform> double sample_standard_normal(const NormalZiggurat &zig, Uniform &&uniform)
{
  for (;;) {
    const int bits = int(double(uniform()) * 256.0); /* top eight bits: layer and sign */
    const int i = bits >> 1;
    const double sign = (bits & 1) ? -1.0 : 1.0;
    const double z = double(uniform()) * zig.x[i];
    if (z < zig.x[i + 1]) {
      return sign * z;
    }
    if (i == 0) {
      /* The tail beyond r: x = -ln(u1) / r accepted when -2 ln(u2) > x^2 (1 - u keeps the logs finite). */
      double t, y;
      do {
        t = -std::log(1.0 - double(uniform())) / NormalZiggurat::kR;
        y = -std::log(1.0 - double(uniform()));
      } while (2.0 * y < t * t);
      return sign * (NormalZiggurat::kR + t);
    }
    /* The wedge between x_{i+1} and x_i: a uniform height in the layer, under f or not. */
    const double height = zig.f[i] + double(uniform()) * (zig.f[i + 1] - zig.f[i]);
    if (height < std::exp(-0.5 * z * z)) {
      return sign * z;
    }
  }
}

}  // namespace neuralyarn::rdm
