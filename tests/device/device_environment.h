// SPDX-License-Identifier: Apache-2.0
//
// What a GPU device gives the kernel headers in device mode, standing in for Cycles' util headers and the
// kernel languages: float math functions, uint32_t and the bit cast, and no system header. The global
// address space (Cycles' ccl_global: the lookup table that holds the model) is a distinct clang address
// space, so that handing a pointer into the model to a function that takes the thread's own data (or the
// other way round) does not compile, as in Metal; the thread's space is the default (Metal's `thread`,
// Cycles' ccl_private).
#pragma once

typedef unsigned int uint32_t;
extern "C" {
float sqrtf(float), expf(float), logf(float), sinf(float), cosf(float), tanf(float), asinf(float),
    acosf(float), atanf(float), atan2f(float, float), fabsf(float), fminf(float, float), fmaxf(float, float),
    fmodf(float, float), erfcf(float), rintf(float);
}
#define NY_KERNEL_DEVICE
#define NY_KERNEL_FN inline
#define NY_GLOBAL __attribute__((address_space(1)))
#define NY_PRIVATE
#define NY_CONSTANT static constexpr __attribute__((address_space(2))) /* Metal: static constant constexpr */
#define NY_FLOAT_AS_UINT(f) __builtin_bit_cast(uint32_t, f)
#define NY_UINT_AS_FLOAT(u) __builtin_bit_cast(float, u)
