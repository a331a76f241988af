// SPDX-License-Identifier: Apache-2.0
//
// Angles on the host, written once: pi and the degree in radians, in double precision. The kernel headers
// (kernel/), which compile unchanged into Cycles, keep their float constants in kernel/platform.h.
#pragma once

namespace neuralyarn {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0; /* one degree in radians: x degrees = x * kDeg */

}  // namespace neuralyarn
