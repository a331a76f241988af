// SPDX-License-Identifier: Apache-2.0
//
// Portability layer of the kernel headers.
//
// Everything under neuralyarn/kernel/ compiles unchanged in three places: the cpp_core library, the
// tests, and (through cycles_patch/) the Cycles kernel. The rules that make that possible:
//   * plain float math, no STL containers, no heap, no exceptions, no virtual calls, no globals but
//     constant tables (NY_CONSTANT);
//   * every function is declared with NY_KERNEL_FN (one macro; Cycles maps it to ccl_device_inline);
//   * vectors and colours are the tiny POD types below, converted at the boundary by the host code.
//
// On the host and in Cycles' CPU kernel the only library this layer touches is the C math library (<cmath>
// float functions: sqrtf, expf, ...). A GPU device (NY_KERNEL_DEVICE, which Cycles' __KERNEL_GPU__ sets)
// includes no library header at all: the kernel language, or Cycles' util headers included before these,
// give those functions and uint32_t, and NY_FLOAT_AS_UINT / NY_UINT_AS_FLOAT the bit casts. Pointers and references say where
// their data lives: NY_GLOBAL (the model's array in device memory: Cycles' ccl_global) or NY_PRIVATE (the
// thread's own values: ccl_private), so that address-space languages (Metal, OpenCL-style oneAPI) take them;
// on the host both are empty. tests/device compiles every header in device mode with clang, the global
// space a distinct address space, and no system header.
#pragma once

#if defined(__KERNEL_GPU__) && !defined(NY_KERNEL_DEVICE)
#  define NY_KERNEL_DEVICE
#  define NY_FLOAT_AS_UINT(f) __float_as_uint(f)
#  define NY_UINT_AS_FLOAT(u) __uint_as_float(u)
#endif
#if defined(ccl_global) && !defined(NY_GLOBAL)
#  define NY_GLOBAL ccl_global
#  define NY_PRIVATE ccl_private
#endif
#ifndef NY_GLOBAL
#  define NY_GLOBAL
#endif
#ifndef NY_PRIVATE
#  define NY_PRIVATE
#endif

#ifndef NY_KERNEL_DEVICE
#  include <cmath>
#  include <cstdint>
#  include <cstring>
#  define NY_INFINITY INFINITY
#else
#  define NY_INFINITY __builtin_inff() /* the device compilers are clang (Metal, HIP, oneAPI) or NVCC */
#endif

#ifndef NY_KERNEL_FN
#  define NY_KERNEL_FN inline
#endif

/* A constant table at namespace scope (cos2_table.h), as Cycles' kernel/tables.h declares its own: Cycles'
 * ccl_inline_constant (the constant address space on a GPU), inline constexpr on the host. Functions index
 * it directly; no pointer to it is passed around. */
#ifndef NY_CONSTANT
#  if defined(ccl_inline_constant)
#    define NY_CONSTANT ccl_inline_constant
#  else
#    define NY_CONSTANT inline constexpr
#  endif
#endif

/* Marks a loop without a reduction (each iteration writes its own element) for SIMD: the networks' inner
 * loops. Cycles' CPU kernel is built at -O2, where GCC 12 vectorises almost nothing by itself; OpenMP's simd
 * pragma (Cycles builds with -fopenmp, cpp_core with -fopenmp-simd) vectorises it at any level. A compiler
 * without OpenMP ignores it. */
#if defined(_OPENMP) || defined(NY_OPENMP_SIMD)
#  define NY_SIMD_LOOP _Pragma("omp simd")
#else
#  define NY_SIMD_LOOP
#endif

namespace ny {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kTwoPi = 6.28318530717958647693f;
constexpr float kHalfPi = 1.57079632679489661923f;
constexpr float kInvPi = 0.31830988618379067154f;
constexpr float kInvTwoPi = 0.15915494309189533577f;
constexpr float kInvFourPi = 0.07957747154594766788f;
constexpr float kSqrt2 = 1.41421356237309504880f;
constexpr float kInvSqrt2 = 0.70710678118654752440f;
constexpr float kInvSqrtTwoPi = 0.39894228040143267794f;
constexpr float kFloatMax = 3.40282347e38f; /* FLT_MAX, without <cfloat> */

/* ------------------------------------------------------------------------------------------------ */
/* Vec3: a direction or point in a local frame.                                                      */
/* ------------------------------------------------------------------------------------------------ */

struct Vec3 {
  float x, y, z;
};

NY_KERNEL_FN Vec3 make_vec3(float x, float y, float z)
{
  Vec3 v;
  v.x = x;
  v.y = y;
  v.z = z;
  return v;
}
NY_KERNEL_FN Vec3 operator+(Vec3 a, Vec3 b) { return make_vec3(a.x + b.x, a.y + b.y, a.z + b.z); }
NY_KERNEL_FN Vec3 operator-(Vec3 a, Vec3 b) { return make_vec3(a.x - b.x, a.y - b.y, a.z - b.z); }
NY_KERNEL_FN Vec3 operator-(Vec3 a) { return make_vec3(-a.x, -a.y, -a.z); }
NY_KERNEL_FN Vec3 operator*(Vec3 a, float s) { return make_vec3(a.x * s, a.y * s, a.z * s); }
NY_KERNEL_FN Vec3 operator*(float s, Vec3 a) { return a * s; }
NY_KERNEL_FN float dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
NY_KERNEL_FN Vec3 cross(Vec3 a, Vec3 b)
{
  return make_vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
NY_KERNEL_FN float length(Vec3 a) { return sqrtf(dot(a, a)); }
NY_KERNEL_FN Vec3 normalize(Vec3 a)
{
  const float len = length(a);
  return (len > 0.0f) ? a * (1.0f / len) : make_vec3(0.0f, 0.0f, 0.0f);
}

/* ------------------------------------------------------------------------------------------------ */
/* Rgb: a three-channel spectrum (Cycles' Spectrum when it is RGB).                                   */
/* ------------------------------------------------------------------------------------------------ */

struct Rgb {
  float r, g, b;
};

NY_KERNEL_FN Rgb make_rgb(float r, float g, float b)
{
  Rgb c;
  c.r = r;
  c.g = g;
  c.b = b;
  return c;
}
NY_KERNEL_FN Rgb make_rgb(float v) { return make_rgb(v, v, v); }
NY_KERNEL_FN Rgb operator+(Rgb a, Rgb b) { return make_rgb(a.r + b.r, a.g + b.g, a.b + b.b); }
NY_KERNEL_FN Rgb operator-(Rgb a, Rgb b) { return make_rgb(a.r - b.r, a.g - b.g, a.b - b.b); }
NY_KERNEL_FN Rgb operator*(Rgb a, Rgb b) { return make_rgb(a.r * b.r, a.g * b.g, a.b * b.b); }
NY_KERNEL_FN Rgb operator*(Rgb a, float s) { return make_rgb(a.r * s, a.g * s, a.b * s); }
NY_KERNEL_FN Rgb operator*(float s, Rgb a) { return a * s; }
NY_KERNEL_FN float average(Rgb a) { return (a.r + a.g + a.b) * (1.0f / 3.0f); }

/* ------------------------------------------------------------------------------------------------ */
/* Scalar helpers.                                                                                    */
/* ------------------------------------------------------------------------------------------------ */

/* max(a, b) and min(a, b) by a comparison, not fmaxf/fminf: GCC calls libm for those (NaN rules) unless math is
 * finite-only, and they sat in every R node's eval (docs/decisions.md D59). fmaxf's and fminf's value for every a
 * (a NaN a gives b) when b is not NaN, but for the sign of a zero against a zero: pass the bound second. */
NY_KERNEL_FN float maxf(float a, float b) { return a > b ? a : b; }
NY_KERNEL_FN float minf(float a, float b) { return a < b ? a : b; }
NY_KERNEL_FN float clampf(float x, float lo, float hi) { return minf(maxf(x, lo), hi); }
NY_KERNEL_FN float sqr(float x) { return x * x; }
NY_KERNEL_FN float safe_sqrtf(float x) { return sqrtf(maxf(x, 0.0f)); }
NY_KERNEL_FN float safe_asinf(float x) { return asinf(clampf(x, -1.0f, 1.0f)); }
NY_KERNEL_FN float pow5(float x)
{
  const float x2 = x * x;
  return x2 * x2 * x;
}

/* Wrap an angle to [-pi, pi). */
NY_KERNEL_FN float wrap_angle(float a)
{
  a = fmodf(a + kPi, kTwoPi);
  if (a < 0.0f) {
    a += kTwoPi;
  }
  const float w = a - kPi;
  /* fmodf can return exactly 2*pi - ulp; keep the result in range even then. */
  return (w >= kPi) ? w - kTwoPi : w;
}

/* wrap_angle(a) for a in [-pi, 3 pi) without fmodf, for loops that run lanes side by side: the same value (fmodf of
 * a + pi in [0, 4 pi) by 2 pi is a + pi or a + pi - 2 pi, the latter exact by Sterbenz's lemma). */
NY_KERNEL_FN float wrap_angle_lanes(float a)
{
  const float v = a + kPi;
  const float t = v >= kTwoPi ? v - kTwoPi : v;
  const float w = t - kPi;
  return (w >= kPi) ? w - kTwoPi : w;
}

/* atan2(y, x) in [-pi, pi] without a library call: the closures take two per direction and lobe frame, and
 * libm's atan2f was the largest single cost of a yarn render's shading (docs/benchmarks.md, D40). The
 * quotient of the smaller by the larger magnitude is reduced to |t| <= tan(pi/8) (t = (a - 1)/(a + 1) above
 * it, plus pi/4) and atan(t) is Cephes' atanf polynomial (relative error 1.9e-7); the octant is restored by
 * pi/2 - r, pi - r and the sign of y. Worst error against double atan2 over the sphere's directions: under
 * 3 float ulps of the result (tests/cpp/test_frames.cpp). atan2(0, 0) is 0; NaN in gives NaN. atan2_lanes is the
 * same without the NaN test, for loops that run lanes side by side (a NaN there gives some number). */
NY_KERNEL_FN float atan2_lanes(float y, float x)
{
  const float ax = fabsf(x), ay = fabsf(y);
  /* Comparisons, not fmaxf/fminf: GCC calls libm for those (NaN rules) unless math is finite-only. Every
   * quotient is taken whether or not it is used, and selected after: a loop of these has no branches. */
  const float mx = ax > ay ? ax : ay, mn = ax > ay ? ay : ax;
  const float a = mn / (mx > 0.0f ? mx : 1.0f);
  const bool upper = a > 0.41421356f; /* tan(pi/8) */
  const float t_upper = (a - 1.0f) / (a + 1.0f);
  const float t = upper ? t_upper : a;
  const float z = t * t;
  float r = (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z - 3.33329491539e-1f) * z * t + t;
  r = upper ? r + 0.78539816f : r; /* pi/4 */
  r = ay > ax ? kHalfPi - r : r;
  r = x < 0.0f ? kPi - r : r;
  return (y < 0.0f) ? -r : r;
}

NY_KERNEL_FN float fast_atan2(float y, float x)
{
  if (!(x == x && y == y)) {
    return x + y; /* NaN in, NaN out */
  }
  return atan2_lanes(y, x);
}

/* sin a and cos a for |a| <= 16 without a library call, for loops that run lanes side by side (the R nodes'
 * rotations and the cos^2 normaliser, yarn_lobes): a = j pi/2 + r with j the nearest integer to a 2/pi and pi/2
 * in three parts (Cephes' DP1..DP3 doubled: j times the first two is exact for |j| <= 10 here), then Cephes'
 * sinf and cosf polynomials on |r| <= pi/4 and the quadrant j mod 4 by selection. Within 2 float ulps of double
 * sin and cos, or 6e-8 absolute near their zeros (tests/cpp/test_special.cpp). */
NY_KERNEL_FN void sincos_lanes(float a, NY_PRIVATE float &s, NY_PRIVATE float &c)
{
  /* j = the nearest integer to a 2/pi, as fast_exp rounds (rintf on a device, 1.5 * 2^23 added and removed here). */
#ifdef NY_KERNEL_DEVICE
  const float fj = rintf(a * 0.63661977236758134f);
#else
  const float fj = (a * 0.63661977236758134f + 12582912.0f) - 12582912.0f;
#endif
  const int j = (int)fj;
  const float r = ((a - fj * 1.5703125f) - fj * 4.837512969970703125e-4f) - fj * 7.54978995489188216e-8f;
  const float r2 = r * r;
  const float sr = r + r * r2 * (-1.6666654611e-1f + r2 * (8.3321608736e-3f + r2 * -1.9515295891e-4f));
  const float cr = 1.0f - 0.5f * r2 + r2 * r2 * (4.166664568298827e-2f + r2 * (-1.388731625493765e-3f + r2 * 2.443315711809948e-5f));
  const int n = j & 3;
  const float s0 = (n & 1) ? cr : sr, c0 = (n & 1) ? sr : cr;
  s = (n & 2) ? -s0 : s0;
  c = ((n + 1) & 2) ? -c0 : c0;
}

/* True for a finite float (not NaN, not +-inf); written without std::isfinite so that it also works in
 * device compilers whose fast-math mode folds isfinite away. */
NY_KERNEL_FN bool is_finite(float x) { return (x - x) == 0.0f; }

/* The bits of a float: memcpy on the host (the defined way in C++17), the device's own cast there. */
NY_KERNEL_FN uint32_t float_bits(float f)
{
#ifdef NY_FLOAT_AS_UINT
  return NY_FLOAT_AS_UINT(f);
#else
  uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  return u;
#endif
}

/* The float with these bits: the inverse of float_bits. */
NY_KERNEL_FN float float_from_bits(uint32_t u)
{
#ifdef NY_UINT_AS_FLOAT
  return NY_UINT_AS_FLOAT(u);
#else
  float f;
  std::memcpy(&f, &u, sizeof(f));
  return f;
#endif
}

/* e^x without a library call: libm's expf cannot be vectorised or inlined, and the networks' heads and the
 * host's quadratures over them call it at every output (docs/benchmarks.md, D58). Cephes' expf: x = n ln 2 + r
 * with |r| <= ln 2 / 2 (ln 2 in two parts, the first exact times any n here), e^r by its degree-7 polynomial,
 * 2^n from exponent bits in two halves so that denormal results and those up to FLT_MAX need no branch. The
 * argument is clamped to [-104, 89], beyond which the float result is 0 or +inf anyway (the product rounds
 * there by itself). Worst error against double exp: under 2 float ulps over the finite range
 * (tests/cpp/test_special.cpp). NaN in gives NaN. */
NY_KERNEL_FN float fast_exp(float x)
{
  /* Comparisons, not fmaxf/fminf (see fast_atan2); a NaN takes the lower bound here and is restored below. */
  float xc = x > -104.0f ? x : -104.0f;
  xc = xc < 89.0f ? xc : 89.0f;
  const float t = xc * 1.44269504088896341f; /* log2(e) */
  /* t to the nearest integer: rintf where the device has it as an instruction; on the CPU, where GCC calls libm
   * for rintf below SSE4.1, by adding and removing 1.5 * 2^23 (exact while |t| < 2^22; the kernels' flags do
   * not reassociate). */
#ifdef NY_KERNEL_DEVICE
  const float fn = rintf(t);
#else
  const float fn = (t + 12582912.0f) - 12582912.0f;
#endif
  const int n = (int)fn;
  const float r = (xc - fn * 0.693359375f) + fn * 2.12194440e-4f;
  /* The polynomial in Estrin's form: a shorter chain of dependent operations than Horner's, for the scalar
   * calls whose latency shows. */
  const float r2 = r * r, r4 = r2 * r2;
  const float p = (1.0f + r) + r2 * ((5.0000001201e-1f + 1.6666665459e-1f * r) +
                                     r2 * (4.1665795894e-2f + 8.3334519073e-3f * r) +
                                     r4 * (1.3981999507e-3f + 1.9875691500e-4f * r));
  const int na = n / 2, nb = n - na; /* each in [-75, 64]: 2^na and 2^nb are normal floats */
  const float e = p * float_from_bits((uint32_t)(na + 127) << 23) * float_from_bits((uint32_t)(nb + 127) << 23);
  return (x == x) ? e : x;
}

}  // namespace ny
