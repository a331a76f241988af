// SPDX-License-Identifier: Apache-2.0
//
// Shading frames and spherical angles. docs/conventions.md is the prose version of this file.
//
// Local frame (used for the yarn frame, the surface-fiber frame and a fiber's own frame alike):
//   x = tangent (along the yarn / fiber, in the direction its control points are listed),
//   z = surface normal (outward normal of the yarn's bounding cylinder; for a lone fiber any unit vector
//       perpendicular to the tangent: the fiber BSDF depends only on azimuth differences),
//   y = z × x (so x × y = z: right-handed).
//
// Spherical angles (Marschner et al. 2003, with phi = 0 on the normal as the paper's Sec. 2.2 states):
//   theta = asin(x)       in [-pi/2, pi/2], the longitudinal angle measured from the normal plane,
//                         positive toward +tangent;
//   phi   = atan2(y, z)   in [-pi, pi], the azimuth about the tangent; phi = 0 points along the normal,
//                         phi = +pi/2 along +y. The upper hemisphere (z > 0) is |phi| < pi/2.
//   direction(theta, phi) = (sin theta, cos theta sin phi, cos theta cos phi).
//   The solid-angle element is d(omega) = cos(theta) d(theta) d(phi).
//
// Surface-fiber frame (paper Sec. 2.2 and Appendix A): the fibers on the yarn surface run along a helix
// and are therefore tilted against the yarn tangent by phi~ = atan(pi * alpha) about the normal:
//   omega~ = M omega,  M = [[cos phi~, -sin phi~, 0], [sin phi~, cos phi~, 0], [0, 0, 1]].
// The x axis of the surface-fiber frame, written in yarn coordinates, is therefore
//   t_f = M^T e_x = (cos phi~, -sin phi~, 0) = (1, -pi alpha, 0) / sqrt(1 + pi^2 alpha^2),
// which is the tangent of a fiber on the helix  p(l) = (l, R cos psi(l), R sin psi(l)) with
// psi(l) = psi_0 + (pi alpha / R) l, i.e. a helix that turns right-handed about +x (a "Z" twist). The
// geometry generator must build exactly this handedness; tests/cpp/test_frames.cpp checks it.
#pragma once

#include "platform.h"

namespace ny {

/* ------------------------------------------------------------------------------------------------ */
/* Orthonormal frame.                                                                                 */
/* ------------------------------------------------------------------------------------------------ */

struct Frame {
  Vec3 x; /* tangent */
  Vec3 y; /* z × x   */
  Vec3 z; /* normal  */
};

/* Build the yarn frame from a curve tangent and a surface normal that need not be exactly orthogonal:
 * the normal is kept, the tangent is made orthogonal to it (Gram-Schmidt), y completes the frame.
 * Returns false (and an arbitrary frame) when the tangent is parallel to the normal. */
NY_KERNEL_FN bool make_frame(Vec3 tangent, Vec3 normal, NY_PRIVATE Frame *frame)
{
  const Vec3 n = normalize(normal);
  const Vec3 t_ortho = tangent - n * dot(tangent, n);
  const float len = length(t_ortho);
  frame->z = n;
  if (!(len > 1e-12f)) {
    /* Degenerate: pick any tangent perpendicular to n. */
    const Vec3 a = (fabsf(n.x) < 0.9f) ? make_vec3(1.0f, 0.0f, 0.0f) : make_vec3(0.0f, 1.0f, 0.0f);
    frame->x = normalize(a - n * dot(a, n));
    frame->y = cross(frame->z, frame->x);
    return false;
  }
  frame->x = t_ortho * (1.0f / len);
  frame->y = cross(frame->z, frame->x);
  return true;
}

NY_KERNEL_FN Vec3 to_local(NY_PRIVATE const Frame &f, Vec3 v)
{
  return make_vec3(dot(v, f.x), dot(v, f.y), dot(v, f.z));
}
NY_KERNEL_FN Vec3 to_world(NY_PRIVATE const Frame &f, Vec3 v) { return f.x * v.x + f.y * v.y + f.z * v.z; }

/* ------------------------------------------------------------------------------------------------ */
/* Marschner angles.                                                                                  */
/* ------------------------------------------------------------------------------------------------ */

/* sin(theta): the component along the tangent. */
NY_KERNEL_FN float sin_theta(Vec3 w) { return clampf(w.x, -1.0f, 1.0f); }
/* cos(theta) >= 0, computed from the normal-plane components: accurate near the poles, where
 * sqrt(1 - x^2) would lose all digits. */
NY_KERNEL_FN float cos_theta(Vec3 w) { return minf(sqrtf(w.y * w.y + w.z * w.z), 1.0f); }
NY_KERNEL_FN float theta_of(Vec3 w) { return fast_atan2(w.x, cos_theta(w)); }
NY_KERNEL_FN float phi_of(Vec3 w) { return fast_atan2(w.y, w.z); }

NY_KERNEL_FN Vec3 direction_from_angles(float theta, float phi)
{
  const float ct = cosf(theta);
  return make_vec3(sinf(theta), ct * sinf(phi), ct * cosf(phi));
}

/* ------------------------------------------------------------------------------------------------ */
/* Surface-fiber rotation.                                                                            */
/* ------------------------------------------------------------------------------------------------ */

/* phi~ = atan(pi alpha), the angle between the yarn tangent and the surface fibers (Appendix A). */
NY_KERNEL_FN float surface_fiber_angle(float alpha) { return atanf(kPi * alpha); }

/* The rotation M by phi~ about the normal, stored as its cosine and sine. */
struct TwistRotation {
  float c, s;
};

NY_KERNEL_FN TwistRotation make_twist_rotation(float alpha)
{
  /* cos(atan(a)) = 1/sqrt(1+a^2), sin(atan(a)) = a/sqrt(1+a^2): no trigonometric calls needed. */
  const float a = kPi * alpha;
  const float inv = 1.0f / sqrtf(1.0f + a * a);
  TwistRotation r;
  r.c = inv;
  r.s = a * inv;
  return r;
}

/* omega~ = M omega: yarn frame -> surface-fiber frame. */
NY_KERNEL_FN Vec3 yarn_to_surface_fiber(NY_PRIVATE const TwistRotation &r, Vec3 w)
{
  return make_vec3(r.c * w.x - r.s * w.y, r.s * w.x + r.c * w.y, w.z);
}

/* omega = M^T omega~: surface-fiber frame -> yarn frame. */
NY_KERNEL_FN Vec3 surface_fiber_to_yarn(NY_PRIVATE const TwistRotation &r, Vec3 w)
{
  return make_vec3(r.c * w.x + r.s * w.y, -r.s * w.x + r.c * w.y, w.z);
}

/* The surface fibers' tangent in yarn coordinates, t_f = M^T e_x. */
NY_KERNEL_FN Vec3 surface_fiber_tangent(NY_PRIVATE const TwistRotation &r) { return make_vec3(r.c, -r.s, 0.0f); }

}  // namespace ny
