// SPDX-License-Identifier: Apache-2.0
//
// Fibers along curved plies (geometry/sweep.h): a straight centreline gives the straight ply's helices
// exactly; on a bent ply every fiber keeps its distance from the centreline and its twist relative to the
// ply, and degenerate centrelines are refused.
#include <cmath>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "neuralyarn/geometry/sweep.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/units.h"

using neuralyarn::kPi;

namespace {

using namespace neuralyarn::geometry;

Ply fleece_ply(uint64_t seed = 3)
{
  const auto &p = neuralyarn::find_preset("fleece");
  const PlyParams q{40, p.rho, p.alpha, 1.0};
  return Ply(q, pack_cross_section(q, seed));
}

TEST(SweepFibers, StraightCentrelineIsTheStraightPly)
{
  const Ply ply = fleece_ply();
  const CurveSet a = sweep_fibers(ply, {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(2, 0, 0), Eigen::Vector3d(12, 0, 0)});
  const CurveSet b = export_fibers(ply, 0.0, 12.0);
  ASSERT_EQ(a.offsets, b.offsets);
  ASSERT_EQ(a.radii, b.radii);
  for (size_t i = 0; i < a.points.size(); i++) {
    ASSERT_LT((a.points[i] - b.points[i]).norm(), 1e-5f) << "key " << i;
  }
}

TEST(SweepFibers, BentPlyKeepsEachFiberAtItsDistanceAndTwist)
{
  /* A half circle of radius 20 (bending radius 20 ply radii, tighter than a knit loop's ~3-5 yarn radii
   * in these units is not needed: the frame must only stay rotation-minimising). */
  const Ply ply = fleece_ply();
  std::vector<Eigen::Vector3d> arc;
  const double rho = 20.0, pi = kPi;
  for (int k = 0; k <= 400; k++) {
    const double t = pi * k / 400;
    arc.emplace_back(rho * std::sin(t), 0.0, rho * (1.0 - std::cos(t)));
  }
  const CurveSet c = sweep_fibers(ply, arc);
  ASSERT_EQ(c.num_curves(), ply.num_fibers());
  for (int f = 0; f < c.num_curves(); f++) {
    const double d = ply.cross_section().centers[size_t(f)].norm();
    for (int k = c.offsets[size_t(f)]; k < c.offsets[size_t(f) + 1]; k++) {
      /* Distance from the centreline (a circle in the xz plane about (0, 0, rho)). */
      const Eigen::Vector3d p = c.points[size_t(k)].cast<double>();
      const double in_plane = std::hypot(p.x(), p.z() - rho) - rho;
      ASSERT_NEAR(std::hypot(in_plane, p.y()), d, 2e-3) << "fiber " << f << " key " << k;
    }
  }
  /* A planar bend adds no twist: the fiber's angle about the centreline, measured in the plane's frame
   * (the bend's normal and the plane's normal +y), advances by w per unit length as in the straight ply. */
  const int n = c.offsets[1] - c.offsets[0];
  const double length = pi * rho, w = ply.twist_rate();
  const Eigen::Vector2d c0 = ply.cross_section().centers[0];
  for (int k = 0; k < n; k += 37) {
    const double t = pi * k / (n - 1);
    const Eigen::Vector3d centre(rho * std::sin(t), 0.0, rho * (1.0 - std::cos(t)));
    const Eigen::Vector3d T(std::cos(t), 0.0, std::sin(t)), N(0.0, 1.0, 0.0), B = T.cross(N);
    const Eigen::Vector3d off = c.points[size_t(k)].cast<double>() - centre;
    const double angle = std::atan2(off.dot(B), off.dot(N)) - std::atan2(c0.y(), c0.x());
    const double expected = w * length * k / (n - 1);
    EXPECT_NEAR(std::remainder(angle - expected, 2.0 * pi), 0.0, 2e-3) << "key " << k;
  }
}

/* The fibers follow the curve a renderer draws through the ply's keys (Cycles' Catmull-Rom), not the polygon of
 * the keys: with a ply sampled at 8 keys per turn of a circle the polygon cuts each span's middle 7.6 % of the
 * radius inside, the spline 0.9 % (the aggregated ply is rendered on the spline, the explicit fibers must be
 * swept along the same curve). A single fiber at the ply's centre traces the centreline itself. */
TEST(SweepFibers, FollowsTheCurveTheRendererDrawsThroughTheKeys)
{
  const auto &p = neuralyarn::find_preset("fleece");
  const PlyParams q{1, p.rho, p.alpha, 1.0};
  PlyCrossSection cs;
  cs.R = 1.0;
  cs.r = 0.1;
  cs.centers = {Eigen::Vector2d(0.0, 0.0)};
  const Ply ply(q, cs);
  const double rho = 5.0;
  std::vector<Eigen::Vector3d> keys;
  for (int k = 0; k <= 12; k++) { /* one and a half turns, 8 keys per turn (the garment's plies) */
    const double t = 2.0 * kPi * k / 8.0;
    keys.emplace_back(rho * std::cos(t), 0.05 * k, rho * std::sin(t));
  }
  const CurveSet c = sweep_fibers(ply, keys, 32);
  ASSERT_EQ(c.num_curves(), 1);
  /* Inside the second to the second-last span (the end spans repeat their end key, as Cycles does). */
  int checked = 0;
  for (int k = c.offsets[0]; k < c.offsets[1]; k++) {
    const Eigen::Vector3d x = c.points[size_t(k)].cast<double>();
    const double angle = std::atan2(x.z(), x.x()), span = 2.0 * kPi / 8.0;
    const double along = (x.y() / 0.05) * span; /* the key index times the span angle, from the height */
    if (along < span || along > 11.0 * span) {
      continue;
    }
    EXPECT_NEAR(std::remainder(angle - along, 2.0 * kPi), 0.0, 0.02) << "key " << k;
    EXPECT_NEAR(std::hypot(x.x(), x.z()), rho, 0.01 * rho) << "key " << k;
    checked++;
  }
  EXPECT_GT(checked, 100);
  /* The key estimate of a scene (centreline_length) is the length of the curve the fibers are swept along. */
  const double len = centreline_length(keys);
  double swept = 0.0;
  for (int k = c.offsets[0] + 1; k < c.offsets[1]; k++) {
    swept += (c.points[size_t(k)] - c.points[size_t(k - 1)]).cast<double>().norm();
  }
  EXPECT_NEAR(swept, len, 1e-3 * len);
}

TEST(SweepFibers, DegenerateCentrelinesAreRefused)
{
  const Ply ply = fleece_ply();
  EXPECT_THROW(sweep_fibers(ply, {Eigen::Vector3d(1, 2, 3)}), neuralyarn::ParameterError);
  EXPECT_THROW(sweep_fibers(ply, {Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, 2, 3)}), neuralyarn::ParameterError);
  EXPECT_THROW(sweep_fibers(ply, {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(NAN, 0, 0)}), neuralyarn::ParameterError);
  EXPECT_THROW(sweep_fibers(ply, {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0)}, 2), neuralyarn::ParameterError);
}

}  // namespace
