// SPDX-License-Identifier: Apache-2.0
//
// The bend of a ply at a shading point (docs/decisions.md D75-D77): the two numbers a bent ply's far field depends on,
//
//   b = (kappa R cos psi, kappa R sin psi),
//
// kappa the curvature of the ply's centreline there, R the ply radius, psi the angle of the surface normal n about the
// tangent T from the bend's outward direction (away from the centre of curvature) toward outward x T. With k the
// curvature vector (toward the centre of curvature, |k| = kappa) both are projections and no angle is needed:
//
//   kappa R cos psi = -R n.k,   kappa R sin psi = -R n.(k x T).
//
// b is zero on a straight ply and continuous everywhere (psi alone is undefined there). T is the shading frame's x,
// whichever way the renderer orients it: reversing T keeps the first component and negates the second, as the frame
// (x, y = n x x) turns half a turn about n with it. The centreline is the curve Cycles draws through a ply's keys: the
// uniform Catmull-Rom segment between keys P1 (u = 0) and P2 (u = 1), P0 and P3 its neighbours (the end keys
// repeated), as Cycles' catmull_rom_basis_* and geometry/sweep.h's catmull_rom_polyline evaluate it; its curvature
// vector is k = (P'' - (P''.T) T) / |P'|^2.
#pragma once

#include "platform.h"

namespace ny {

struct YarnBend {
  float c; /* kappa R cos psi */
  float s; /* kappa R sin psi */
};

/* First and second derivatives in u of the uniform Catmull-Rom segment through P[0..3] (Cycles' basis). */
NY_KERNEL_FN void catmull_rom_derivatives(NY_PRIVATE const Vec3 *P, float u, NY_PRIVATE Vec3 *d1, NY_PRIVATE Vec3 *d2)
{
  const float t = u, s = 1.0f - u;
  const float a0 = -s * s + 2.0f * s * t, a1 = 2.0f * t * (3.0f * t - 5.0f) + 3.0f * t * t,
              a2 = 2.0f * s * (3.0f * t + 2.0f) - 3.0f * s * s, a3 = -2.0f * s * t + t * t;
  *d1 = (P[0] * a0 + P[1] * a1 + P[2] * a2 + P[3] * a3) * 0.5f;
  const float b0 = 2.0f - 3.0f * t, b1 = 9.0f * t - 5.0f, b2 = 4.0f - 9.0f * t, b3 = 3.0f * t - 1.0f;
  *d2 = P[0] * b0 + P[1] * b1 + P[2] * b2 + P[3] * b3;
}

/* The segment's curvature vector at u (toward the centre of curvature, length kappa in inverse key units); zero
 * where the segment has no tangent (coincident keys). */
NY_KERNEL_FN Vec3 catmull_rom_curvature(NY_PRIVATE const Vec3 *P, float u)
{
  Vec3 d1, d2;
  catmull_rom_derivatives(P, u, &d1, &d2);
  const float l2 = dot(d1, d1);
  if (!(l2 > 0.0f)) {
    return make_vec3(0.0f, 0.0f, 0.0f);
  }
  return (d2 - d1 * (dot(d2, d1) / l2)) * (1.0f / l2);
}

/* b at a point of normal n (unit, normal to T) on a ply of radius R whose centreline has curvature vector k and unit
 * tangent T there. */
NY_KERNEL_FN YarnBend yarn_bend(Vec3 k, Vec3 T, Vec3 n, float R)
{
  return YarnBend{-R * dot(n, k), -R * dot(n, cross(k, T))};
}

}  // namespace ny
