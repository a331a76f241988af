// SPDX-License-Identifier: Apache-2.0
//
// Frame and angle conventions (docs/conventions.md), and the handedness of the surface-fiber rotation
// against the helix that the geometry generator builds.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "neuralyarn/kernel/frames.h"
#include "neuralyarn/random.h"
#include "neuralyarn/units.h"

using neuralyarn::kPi;

namespace {

/* The kernel's atan2 (platform.h: Cephes' polynomial after an octant reduction, no library call) against
 * double atan2: every quadrant, near both axes (one coordinate 1e-4 or 1e-8 of the other) and at the
 * reduction's switch tan(pi/8). Cephes states 1.9e-7 relative for the polynomial; with the reduction's
 * rounding the worst measured over 2e7 points is 3.1 ulps of the result, hence 4. Fixed seed. */
TEST(Frames, FastAtan2IsWithinFourUlpsOfAtan2)
{
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  double worst = 0.0;
  for (int k = 0; k < 400000; k++) {
    float x = float(g(rng)), y = float(g(rng));
    if (k % 5 == 1) y *= 1e-4f;
    if (k % 5 == 2) x *= 1e-8f;
    if (k % 5 == 3) y = x * float(0.41421356 * (1.0 + 1e-6 * g(rng)));
    const double want = std::atan2(double(y), double(x));
    const double ulp = std::fabs(double(std::nextafter(float(want), INFINITY)) - double(float(want)));
    const double err = std::fabs(double(ny::fast_atan2(y, x)) - want) / ulp;
    worst = std::max(worst, err);
    ASSERT_LE(err, 4.0) << "atan2(" << y << ", " << x << ")";
  }
  RecordProperty("worst_ulps", std::to_string(worst));
  EXPECT_EQ(ny::fast_atan2(0.0f, 0.0f), 0.0f);
  EXPECT_NEAR(ny::fast_atan2(0.0f, -1.0f), kPi, 1e-7);
  EXPECT_NEAR(ny::fast_atan2(-1.0f, 0.0f), -kPi / 2, 1e-7);
  EXPECT_TRUE(std::isnan(ny::fast_atan2(NAN, 1.0f)));
  EXPECT_TRUE(std::isnan(ny::fast_atan2(1.0f, NAN)));
}

void expect_vec_near(ny::Vec3 a, ny::Vec3 b, float tol, const char *what)
{
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

TEST(Frames, AnglesFollowTheDocumentedConvention)
{
  /* phi = 0 on the normal, +pi/2 on +y, theta positive toward +tangent. */
  EXPECT_NEAR(ny::phi_of(ny::make_vec3(0, 0, 1)), 0.0f, 1e-7f);
  EXPECT_NEAR(ny::phi_of(ny::make_vec3(0, 1, 0)), float(kPi / 2), 1e-7f);
  EXPECT_NEAR(ny::theta_of(ny::make_vec3(1, 0, 0)), float(kPi / 2), 1e-7f);
  EXPECT_NEAR(ny::theta_of(ny::make_vec3(-1, 0, 0)), float(-kPi / 2), 1e-7f);
  expect_vec_near(ny::direction_from_angles(0.3f, 0.0f), ny::make_vec3(std::sin(0.3f), 0, std::cos(0.3f)), 1e-7f,
                  "theta=0.3, phi=0 lies in the x-z plane");
}

TEST(Frames, AngleRoundTrip)
{
  neuralyarn::Rng rng(11);
  for (int i = 0; i < 100000; i++) {
    const float th = float(kPi) * (neuralyarn::uniform_float(rng) - 0.5f);
    const float ph = float(2 * kPi) * (neuralyarn::uniform_float(rng) - 0.5f);
    const ny::Vec3 w = ny::direction_from_angles(th, ph);
    EXPECT_NEAR(ny::length(w), 1.0f, 1e-6f);
    expect_vec_near(ny::direction_from_angles(ny::theta_of(w), ny::phi_of(w)), w, 2e-6f, "round trip");
  }
}

TEST(Frames, MakeFrameIsRightHandedWithTangentAndNormal)
{
  ny::Frame f;
  /* A tangent that is not orthogonal to the normal: the normal is kept, the tangent projected. */
  ASSERT_TRUE(ny::make_frame(ny::make_vec3(1.0f, 0.2f, 0.3f), ny::make_vec3(0.0f, 0.0f, 2.0f), &f));
  expect_vec_near(f.z, ny::make_vec3(0, 0, 1), 1e-7f, "normal kept");
  expect_vec_near(ny::cross(f.x, f.y), f.z, 1e-6f, "x cross y = z");
  expect_vec_near(ny::cross(f.z, f.x), f.y, 1e-6f, "y = z cross x");
  const ny::Vec3 v = ny::make_vec3(0.3f, -0.4f, 0.5f);
  expect_vec_near(ny::to_world(f, ny::to_local(f, v)), v, 1e-6f, "to_world inverts to_local");
  /* Degenerate input is reported, and still yields an orthonormal frame. */
  EXPECT_FALSE(ny::make_frame(ny::make_vec3(0, 0, 1), ny::make_vec3(0, 0, 1), &f));
  EXPECT_NEAR(ny::dot(f.x, f.z), 0.0f, 1e-6f);
  EXPECT_NEAR(ny::length(f.y), 1.0f, 1e-6f);
}

TEST(Frames, SurfaceFiberAngleIsAtanPiAlpha)
{
  /* Appendix A of the paper; the reference values are the ones listed for the presets. */
  EXPECT_NEAR(ny::surface_fiber_angle(0.24f) * 180.0 / kPi, 37.02, 0.01);  /* fleece */
  EXPECT_NEAR(ny::surface_fiber_angle(0.12f) * 180.0 / kPi, 20.66, 0.01);  /* gabardine */
  EXPECT_NEAR(ny::surface_fiber_angle(0.20f) * 180.0 / kPi, 32.14, 0.01);  /* polyester */
  EXPECT_NEAR(ny::surface_fiber_angle(0.06f) * 180.0 / kPi, 10.67, 0.01);  /* cotton */
  EXPECT_EQ(ny::surface_fiber_angle(0.0f), 0.0f);                          /* silk */
  const ny::TwistRotation r = ny::make_twist_rotation(0.24f);
  EXPECT_NEAR(std::atan2(r.s, r.c), ny::surface_fiber_angle(0.24f), 1e-6f);
}

TEST(Frames, RotationMapsAnalyticHelixTangentToFiberAxis)
{
  /* The check: M (1, -pi alpha, 0) / sqrt(1 + pi^2 alpha^2) = e_x. */
  for (float alpha : {0.0f, 0.06f, 0.12f, 0.2f, 0.24f, 1.0f, 5.0f}) {
    const float a = float(kPi) * alpha;
    const ny::Vec3 t = ny::normalize(ny::make_vec3(1.0f, -a, 0.0f));
    const ny::TwistRotation r = ny::make_twist_rotation(alpha);
    expect_vec_near(ny::yarn_to_surface_fiber(r, t), ny::make_vec3(1, 0, 0), 1e-6f, "M t_f = e_x");
    expect_vec_near(ny::surface_fiber_tangent(r), t, 1e-6f, "surface_fiber_tangent");
    /* The inverse really is the inverse. */
    const ny::Vec3 v = ny::normalize(ny::make_vec3(0.2f, 0.7f, -0.4f));
    expect_vec_near(ny::surface_fiber_to_yarn(r, ny::yarn_to_surface_fiber(r, v)), v, 1e-6f, "M^T M = I");
  }
}

TEST(Frames, RotationMatchesAGeometricHelixAtEveryAzimuth)
{
  /* A fiber on the yarn surface, p(l) = (l, R cos psi(l), R sin psi(l)), psi(l) = psi0 + (pi alpha / R) l:
   * the right-handed (Z-twist) helix the geometry generator builds (docs/conventions.md). Its tangent,
   * by central differences, expressed in the local yarn frame (x = yarn axis, z = outward normal),
   * must be the surface-fiber axis M^T e_x at every point of the surface. */
  const double R = 0.5;
  for (double alpha : {0.06, 0.12, 0.2, 0.24, 0.8}) {
    const ny::TwistRotation rot = ny::make_twist_rotation(float(alpha));
    for (int k = 0; k < 16; k++) {
      const double psi0 = 2 * kPi * k / 16.0;
      const double rate = kPi * alpha / R, l = 0.37, h = 1e-5;
      auto p = [&](double s) {
        const double psi = psi0 + rate * s;
        return std::array<double, 3>{s, R * std::cos(psi), R * std::sin(psi)};
      };
      const auto p1 = p(l + h), p0 = p(l - h);
      const ny::Vec3 tangent = ny::normalize(
          ny::make_vec3(float(p1[0] - p0[0]), float(p1[1] - p0[1]), float(p1[2] - p0[2])));
      const double psi = psi0 + rate * l;
      const ny::Vec3 normal = ny::make_vec3(0.0f, float(std::cos(psi)), float(std::sin(psi)));
      ny::Frame yarn;
      ASSERT_TRUE(ny::make_frame(ny::make_vec3(1, 0, 0), normal, &yarn));
      const ny::Vec3 local = ny::to_local(yarn, tangent);
      expect_vec_near(local, ny::surface_fiber_tangent(rot), 2e-5f, "helix tangent in yarn frame");
      expect_vec_near(ny::yarn_to_surface_fiber(rot, local), ny::make_vec3(1, 0, 0), 2e-5f, "M t = e_x");
    }
  }
}

}  // namespace
