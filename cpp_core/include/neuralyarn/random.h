// SPDX-License-Identifier: Apache-2.0
//
// Host-side random numbers: a seeded 64-bit Mersenne twister and a float in [0, 1) that is never 1.
// (std::generate_canonical<float> may return exactly 1.0 on libstdc++, LWG 2524.)
#pragma once

#include <cstdint>
#include <random>

namespace neuralyarn {

using Rng = std::mt19937_64;

/* 24 random bits: every value exactly representable, the largest is 1 - 2^-24. */
inline float uniform_float(Rng &rng) { return float(rng() >> 40) * (1.0f / 16777216.0f); }

}  // namespace neuralyarn
