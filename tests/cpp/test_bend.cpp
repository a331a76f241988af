// SPDX-License-Identifier: Apache-2.0
//
// The bend at a shading point (kernel/bend.h, decisions D77): b = (kappa R cos psi, kappa R sin psi) from the curve
// Cycles draws through a ply's keys, against curves whose curvature is known.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "neuralyarn/kernel/bend.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

namespace {

ny::Vec3 v3(const Eigen::Vector3d &v) { return ny::make_vec3(float(v.x()), float(v.y()), float(v.z())); }

/* The uniform Catmull-Rom segment through P0..P3 at u, in double (geometry/sweep.h's form). */
Eigen::Vector3d spline(const Eigen::Vector3d *P, double t)
{
  const Eigen::Vector3d c1 = 0.5 * (P[2] - P[0]), c2 = 0.5 * (2.0 * P[0] - 5.0 * P[1] + 4.0 * P[2] - P[3]),
                        c3 = 0.5 * (3.0 * P[1] - P[0] - 3.0 * P[2] + P[3]);
  return P[1] + t * (c1 + t * (c2 + t * c3));
}

struct Segment {
  ny::Vec3 P[4];
  Eigen::Vector3d Pd[4];
};

Segment segment_of(const std::vector<Eigen::Vector3d> &keys, size_t k)
{
  const size_t n = keys.size();
  Segment s;
  const size_t at[4] = {k ? k - 1 : 0, k, k + 1, std::min(k + 2, n - 1)};
  for (int i = 0; i < 4; i++) {
    s.Pd[i] = keys[at[i]];
    s.P[i] = v3(s.Pd[i]);
  }
  return s;
}

/* The bend at u of the segment for the normal at angle psi about the tangent from `out` toward out x T. */
ny::YarnBend bend_at(const Segment &s, float u, const Eigen::Vector3d &out, double psi, float R)
{
  ny::Vec3 d1, d2;
  ny::catmull_rom_derivatives(s.P, u, &d1, &d2);
  const ny::Vec3 T = ny::normalize(d1);
  const Eigen::Vector3d Td(T.x, T.y, T.z), o = (out - out.dot(Td) * Td).normalized();
  const Eigen::Vector3d n = std::cos(psi) * o + std::sin(psi) * o.cross(Td);
  return ny::yarn_bend(ny::catmull_rom_curvature(s.P, u), T, v3(n), R);
}

}  // namespace

/* A ply on a circle of radius 3 (keys as bench_near_field's rings: 65 over the turn): kappa R = R / 3 wherever the
 * normal points, its angle psi from the circle's outward direction. The spline through the keys is not the circle:
 * its curvature is 1/3 within -0.36 % (mid-segment) and +0.72 % (at the keys; the chords subtend 5.6 degrees), so
 * 1 % bounds it; the bend's direction is the circle's within 0.01. */
TEST(Bend, ACircleGivesItsCurvatureWhereverTheNormalPoints)
{
  const double rho = 3.0;
  const int n = 65;
  std::vector<Eigen::Vector3d> keys;
  for (int i = 0; i < n; i++) {
    const double a = 2.0 * kPi * i / (n - 1);
    keys.emplace_back(rho * std::cos(a), rho * std::sin(a), 0.0);
  }
  const float R = 0.8f;
  for (size_t k = 1; k + 2 < keys.size(); k += 7) {
    const Segment s = segment_of(keys, k);
    for (const float u : {0.0f, 0.3f, 0.75f}) {
      const Eigen::Vector3d out = spline(s.Pd, u).normalized(); /* away from the circle's centre */
      for (const double psi : {0.0, 0.7, 1.6, 3.1, -2.2}) {
        const ny::YarnBend b = bend_at(s, u, out, psi, R);
        const double kR = std::hypot(b.c, b.s);
        EXPECT_NEAR(kR, R / rho, 0.01 * R / rho) << "segment " << k << " u " << u << " psi " << psi;
        EXPECT_NEAR(b.c / kR, std::cos(psi), 0.01) << "segment " << k << " u " << u << " psi " << psi;
        EXPECT_NEAR(b.s / kR, std::sin(psi), 0.01) << "segment " << k << " u " << u << " psi " << psi;
      }
    }
  }
}

/* The curvature vector against the spline's own, by central differences in double: the same curve's, to float
 * precision (1e-3 of kappa: the differences' step 1e-4 leaves 1e-7 truncation, float derivatives ~1e-6). */
TEST(Bend, CurvatureIsTheSplinesOwn)
{
  /* Uneven keys of a wandering curve, so that no symmetry hides a wrong basis weight. */
  const std::vector<Eigen::Vector3d> keys = {{0, 0, 0}, {1.0, 0.4, 0.1}, {1.7, 1.3, -0.2}, {2.1, 2.6, 0.4},
                                             {3.4, 3.0, 1.1}, {4.0, 2.2, 1.9}};
  for (size_t k = 0; k + 1 < keys.size(); k++) {
    const Segment s = segment_of(keys, k);
    for (const double u : {0.0, 0.2, 0.5, 0.9, 1.0}) {
      const double h = 1e-4;
      const Eigen::Vector3d d1 = (spline(s.Pd, u + h) - spline(s.Pd, u - h)) / (2.0 * h),
                            d2 = (spline(s.Pd, u + h) - 2.0 * spline(s.Pd, u) + spline(s.Pd, u - h)) / (h * h);
      const Eigen::Vector3d k_ref = (d2 - d2.dot(d1) / d1.squaredNorm() * d1) / d1.squaredNorm();
      const ny::Vec3 kv = ny::catmull_rom_curvature(s.P, float(u));
      const Eigen::Vector3d kd(kv.x, kv.y, kv.z);
      EXPECT_LT((kd - k_ref).norm(), 1e-3 * k_ref.norm() + 1e-5) << "segment " << k << " u " << u;
    }
  }
}

/* A helix of radius a and rise c per radian bends by a / (a^2 + c^2) toward its axis: a normal pointing away from the
 * axis has psi = 0. The spline through 48 keys a turn is not the helix: its curvature is the helix's within -0.5 %
 * (mid-segment) and +1.4 % (at the keys), and, the spline being only C1, its bend turns about the tangent away from the
 * axis toward a segment's ends (5 degrees at the keys, none mid-segment, where the segment is symmetric). Within
 * 0.1 of the middle: 2 % of kappa. (At 16 keys a turn the curvature swings from -4.5 to +12 %: the kernel takes the
 * curve Cycles draws, not the helix.) */
TEST(Bend, AHelixBendsTowardItsAxis)
{
  const double a = 1.0, c = 0.9;
  std::vector<Eigen::Vector3d> keys;
  for (int i = 0; i <= 96; i++) {
    const double t = 2.0 * kPi * i / 48.0;
    keys.emplace_back(a * std::cos(t), a * std::sin(t), c * t);
  }
  const double kappa = a / (a * a + c * c);
  for (size_t k = 2; k + 3 < keys.size(); k += 5) {
    const Segment s = segment_of(keys, k);
    for (const float u : {0.4f, 0.5f, 0.6f}) {
      const Eigen::Vector3d p = spline(s.Pd, u);
      const Eigen::Vector3d away(p.x(), p.y(), 0.0);
      const ny::YarnBend b = bend_at(s, u, away, 0.0, 1.0f);
      EXPECT_NEAR(b.c, kappa, 0.02 * kappa) << "segment " << k << " u " << u;
      EXPECT_NEAR(b.s, 0.0, 0.02 * kappa) << "segment " << k << " u " << u;
    }
  }
}

/* Straight keys, evenly spaced or not, ends included (the end keys repeated): no bend. */
TEST(Bend, StraightKeysHaveNoBend)
{
  const Eigen::Vector3d d = Eigen::Vector3d(1.0, -2.0, 0.5).normalized();
  const std::vector<Eigen::Vector3d> keys = {0.0 * d, 0.7 * d, 1.1 * d, 2.9 * d, 3.0 * d};
  for (size_t k = 0; k + 1 < keys.size(); k++) {
    const Segment s = segment_of(keys, k);
    for (const float u : {0.0f, 0.5f, 1.0f}) {
      const ny::YarnBend b = bend_at(s, u, Eigen::Vector3d(0.3, 0.2, 0.9), 0.4, 1.0f);
      EXPECT_LT(std::hypot(b.c, b.s), 1e-5) << "segment " << k << " u " << u;
    }
  }
}

/* The frame's x reversed (a renderer may orient the tangent either way): the frame turns half a turn about n, the
 * bend's outward part stays and its part along outward x T changes sign. */
TEST(Bend, AReversedTangentNegatesTheSecondComponentOnly)
{
  const ny::Vec3 k = ny::make_vec3(0.1f, -0.3f, 0.05f), T = ny::normalize(ny::make_vec3(0.9f, 0.2f, -0.1f));
  const ny::Vec3 n = ny::normalize(ny::cross(T, ny::make_vec3(0.2f, 0.5f, 0.8f)));
  const ny::YarnBend b = ny::yarn_bend(k, T, n, 1.3f), r = ny::yarn_bend(k, -T, n, 1.3f);
  EXPECT_FLOAT_EQ(r.c, b.c);
  EXPECT_FLOAT_EQ(r.s, -b.s);
  EXPECT_GT(std::abs(b.s), 0.01f); /* the case tells something */
}
