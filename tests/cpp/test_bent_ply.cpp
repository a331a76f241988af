// SPDX-License-Identifier: Apache-2.0
//
// A ply bent on a circle for the random walks (rdm/bent_ply.h, decisions D75): where paths enter, where they leave,
// and that its walks are the ply's where the bend vanishes.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include <unistd.h>

#include <Eigen/Dense>

#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/bent_ply.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/units.h"
#include "gather_checks.h"

using namespace neuralyarn;

namespace {

using neuralyarn::testing::expect_same_energies;
using neuralyarn::testing::small_gather;

std::vector<geometry::Ply> one_ply(const char *preset)
{
  const FiberPreset &p = find_preset(preset);
  const geometry::PlyParams pp{p.N, p.rho, p.alpha, 1.0};
  return {geometry::Ply(pp, geometry::pack_cross_section(pp, 1))};
}

}  // namespace

/* Entries lie on the bent tube with the frame of its surface there (n the outward normal, ex along the circle, ey =
 * n x ex), spread by area: the bend's inner half (cos psi < 0) takes (pi - 2 b / Rc) / 2 pi of them, not half; held
 * to a sector, every entry lies in it. On a grid of u_around the shares are the sampler's CDF itself, so the
 * tolerance is the grid's step. Entering uniformly in psi instead (no area weight) fails the share. */
TEST(BentPly, EntriesCoverTheTubeByArea)
{
  const double Rc = 3.0;
  const rdm::BentPlies whole(one_ply("polyester"), rdm::Bend{Rc, 0, 1});
  const rdm::BentPlies inner(one_ply("polyester"), rdm::Bend{Rc, 2, 4});
  const int n = 4000;
  int on_inner_half = 0;
  for (int i = 0; i < n; i++) {
    const double u = (i + 0.5) / n, v = std::fmod(0.618034 * i, 1.0);
    for (const rdm::BentPlies *m : {&whole, &inner}) {
      const rdm::EntryFrame e = m->entry_frame(u, v);
      const Eigen::Vector3d p(e.point.x, e.point.y, e.point.z);
      ASSERT_NEAR(m->inside(p, 0), 0.0, 2e-6) << i;
      /* The normal points from the circle to the point; the tangent runs along the circle. */
      const Eigen::Vector3d radial(p.x(), p.y(), 0.0);
      const Eigen::Vector3d centre = Rc * radial.normalized();
      const Eigen::Vector3d normal = (p - centre).normalized(), tangent(-p.y(), p.x(), 0.0);
      EXPECT_NEAR(normal.dot(Eigen::Vector3d(e.n.x, e.n.y, e.n.z)), 1.0, 1e-5) << i;
      EXPECT_NEAR(tangent.normalized().dot(Eigen::Vector3d(e.ex.x, e.ex.y, e.ex.z)), 1.0, 1e-5) << i;
      const ny::Vec3 ey = ny::cross(e.n, e.ex);
      EXPECT_NEAR(ny::dot(ey, e.ey), 1.0f, 1e-5f) << i;
      /* Away from the seam at phi = 0: on the half circle x < 0. */
      EXPECT_LT(p.x(), 1e-6) << i;
      if (m == &inner) {
        const double psi = m->psi(p, 0);
        EXPECT_GE(std::abs(psi), 0.75 * kPi - 1e-6) << i;
      }
      else if (normal.dot(radial.normalized()) < 0.0) {
        on_inner_half++;
      }
    }
  }
  const double kb = double(whole.bound_radius()) / Rc;
  EXPECT_NEAR(double(on_inner_half) / n, (kPi - 2.0 * kb) / (2.0 * kPi), 2.0 / n);
}

/* A ray from inside a tube stops where it leaves that tube: on its surface, inside all the way there, also for rays
 * toward the circle's centre that would cross the hole to the far side, and for a ray starting on the surface going
 * in. 2000 rays from random points of the tube in random directions, a fixed seed. */
TEST(BentPly, ARayLeavesWhereItLeavesItsTube)
{
  const double Rc = 3.0;
  const rdm::BentPlies m(one_ply("polyester"), rdm::Bend{Rc, 0, 1});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g;
  for (int i = 0; i < 2000; i++) {
    const double phi = 2.0 * kPi * u(rng), psi = 2.0 * kPi * u(rng), r = 0.999 * std::sqrt(u(rng));
    const Eigen::Vector3d out(std::cos(phi), std::sin(phi), 0.0), z(0.0, 0.0, 1.0);
    const Eigen::Vector3d o = Rc * out + r * (std::cos(psi) * out + std::sin(psi) * z);
    const Eigen::Vector3d d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    const float t = m.exit_distance(ny::make_vec3(float(o.x()), float(o.y()), float(o.z())),
                                    ny::make_vec3(float(d.x()), float(d.y()), float(d.z())));
    ASSERT_NEAR(m.inside(o + double(t) * d, 0), 0.0, 1e-5) << i;
    for (int j = 1; j < 64; j++) {
      ASSERT_GT(m.inside(o + double(t) * j / 64.0 * d, 0), -1e-6) << i << " " << j;
    }
    /* Asked only as far as a fiber the ray hits first: the exit where it lies before; else none, or the same exit
     * when the step that passes the fiber also passes it. */
    const ny::Vec3 of = ny::make_vec3(float(o.x()), float(o.y()), float(o.z()));
    const ny::Vec3 df = ny::make_vec3(float(d.x()), float(d.y()), float(d.z()));
    ASSERT_EQ(m.exit_distance(of, df, 1.01f * t + 0.01f), t) << i;
    const float before = m.exit_distance(of, df, 0.99f * t - 0.01f);
    ASSERT_TRUE(!std::isfinite(before) || before == t) << i << " " << before << " " << t;
  }
  const rdm::EntryFrame e = m.entry_frame(0.3, 0.4);
  const float t = m.exit_distance(e.point, -e.n);
  EXPECT_NEAR(t, 2.0f * m.bound_radius(), 1e-4f);
}

/* A walk's ray that leaves the tube toward the circle's centre stops there: it does not go on across the hole into
 * the fibers of the circle's far side (4 ply radii away), which a ray across the tube hits ~90 % of the time. 41 rays
 * from 0.05 inside the inner side across the hole: each leaves (or hits a fiber before the surface, 0.05-0.09 away). */
TEST(BentPly, ARayLeavingTowardTheCentreDoesNotReachTheFarSide)
{
  const rdm::BentPlies m(one_ply("polyester"), rdm::Bend{3.0, 0, 1});
  int left = 0;
  for (int i = 0; i <= 40; i++) {
    rdm::SlabRay ray;
    const float z = -0.8f + 0.04f * float(i), rho = 3.0f - std::sqrt(1.0f - z * z) + 0.05f;
    ray.o = ny::make_vec3(-rho, 0.0f, z);
    ray.d = ny::make_vec3(1.0f, 0.0f, 0.0f);
    rdm::TubeHit hit;
    if (m.trace(&ray, -1, 0.0f, &hit)) {
      EXPECT_LT(hit.t, 0.2f) << i;
    }
    else {
      left++;
      EXPECT_NEAR(m.inside(Eigen::Vector3d(ray.o.x, ray.o.y, ray.o.z), 0), 0.0, 1e-5) << i;
      EXPECT_LT(ray.o.x, -1.5f) << i;
    }
  }
  EXPECT_GT(left, 20);
}

/* Straight (radius 0), the medium is the ply PlyTracer walks exactly, here as Embree's round curves: the energies of
 * T, R and M agree within their noise (plus 1 % for chords against helices). So do those of a wide bend (radius 40
 * ply radii: the bend's effect, ~ 1 / radius, is below the slack). */
TEST(BentPly, WalksLikeThePlyWhereTheBendVanishes)
{
  const FiberPreset &p = find_preset("polyester");
  const rdm::GatherOptions o = small_gather(300000);
  const rdm::RdmMaps ply = rdm::gather(p, o);
  const rdm::RdmMaps straight = rdm::gather_bent(p, rdm::Bend{0.0, 0, 1}, o);
  EXPECT_EQ(straight.stats.paths_past_ends, 0u);
  expect_same_energies(straight.stats, ply.stats, 0.01);
  const rdm::RdmMaps wide = rdm::gather_bent(p, rdm::Bend{40.0, 0, 1}, o);
  expect_same_energies(wide.stats, ply.stats, 0.03);
}

/* A sector on the bend's side is not its own half-turn image (psi goes to -psi), so symmetrising it would average it
 * with the other side's: refused; the outer and inner sectors are their own images. Radii that fold the tube and
 * sectors outside their count are refused too. */
TEST(BentPly, RefusesWhatItCannotGather)
{
  const FiberPreset &p = find_preset("polyester");
  rdm::GatherOptions o = small_gather(2000);
  EXPECT_THROW(rdm::gather_bent(p, rdm::Bend{3.0, 1, 4}, o), ParameterError);
  EXPECT_NO_THROW(rdm::gather_bent(p, rdm::Bend{3.0, 2, 4}, o));
  o.symmetrize = false;
  EXPECT_NO_THROW(rdm::gather_bent(p, rdm::Bend{3.0, 1, 4}, o));
  EXPECT_THROW(rdm::gather_bent(p, rdm::Bend{1.0, 0, 1}, o), ParameterError);
  EXPECT_THROW(rdm::gather_bent(p, rdm::Bend{std::nan(""), 0, 1}, o), ParameterError);
  EXPECT_THROW(rdm::gather_bent(p, rdm::Bend{3.0, 4, 4}, o), ParameterError);
  EXPECT_THROW(rdm::gather_bent(p, rdm::Bend{3.0, 0, 0}, o), ParameterError);
}

/* The straight ply is laid on the circle without stretching its centreline or mirroring it: at points along the
 * centreline, the images of the straight ply's x, y, z directions are the circle's unit tangent, its outward
 * direction and a unit normal to its plane, in a right-handed frame (a mirrored ply would turn its fibers' twist the
 * other way: Z-twisted fibers would render as S). */
TEST(BentPly, KeepsTheCentrelineAndTheTwistsHandedness)
{
  const double Rc = 3.0;
  const rdm::BentPlies m(one_ply("fleece"), rdm::Bend{Rc, 0, 1});
  const double h = 1e-5;
  for (double x : {0.3, 5.0, 11.0, 17.5}) {
    const Eigen::Vector3d p(x, 0.0, 0.0);
    Eigen::Matrix3d J;
    for (int a = 0; a < 3; a++) {
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(a) * h;
      J.col(a) = (m.place(p + e, 0) - m.place(p - e, 0)) / (2.0 * h);
    }
    EXPECT_NEAR(m.place(p, 0).norm(), Rc, 1e-12) << x;
    EXPECT_NEAR((J.transpose() * J - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-6) << x;
    EXPECT_GT(J.determinant(), 0.0) << x;
  }
}

/* The wedges (chord tubes within 1 % of a fiber radius of their fibers) and Embree's round curves (64 chords a helix
 * turn) are two tessellations of the same fibers: rays from points in the tube, in every direction, hit the same fiber
 * at the same distance (within a tenth of a fiber radius) or leave at the same point (within a fifth: the wedges'
 * tube is wider by their sagitta), but for the few that graze a fiber one tessellation touches and the other misses
 * (at most 1 %). A wedge frame with z not turned (a mirrored ply)
 * or the chords anchored off their plane hits other fibers. */
TEST(BentPly, WedgesHitWhatEmbreesCurvesHit)
{
  const double Rc = 3.0;
  const auto plies = one_ply("cotton");
  const rdm::BentPlies wedges(plies, rdm::Bend{Rc, 0, 1}, rdm::BentIntersector::kWedges);
  const rdm::BentPlies curves(plies, rdm::Bend{Rc, 0, 1}, rdm::BentIntersector::kEmbree);
  ASSERT_GT(wedges.num_wedges(), 0);
  EXPECT_EQ(curves.num_wedges(), 0);
  EXPECT_LE(wedges.wedge_sagitta(), 0.01);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g;
  const float r = wedges.fiber_radius();
  int n = 0, hits = 0, differ = 0;
  for (int i = 0; i < 4000; i++) {
    /* On the half circle where paths enter, away from the seam (where the ply's ends meet, the two tessellations
     * end differently). */
    const double phi = kPi * (0.5 + u(rng)), psi = 2.0 * kPi * u(rng), rho = 0.99 * std::sqrt(u(rng));
    const Eigen::Vector3d out(std::cos(phi), std::sin(phi), 0.0), z(0.0, 0.0, 1.0);
    const Eigen::Vector3d o = Rc * out + rho * (std::cos(psi) * out + std::sin(psi) * z);
    const Eigen::Vector3d d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    rdm::SlabRay a{ny::make_vec3(float(o.x()), float(o.y()), float(o.z())),
                   ny::make_vec3(float(d.x()), float(d.y()), float(d.z())), 0};
    rdm::SlabRay b = a;
    rdm::TubeHit ha, hb;
    const bool got_a = wedges.trace(&a, -1, 0.0f, &ha), got_b = curves.trace(&b, -1, 0.0f, &hb);
    n++;
    hits += got_a;
    const bool same = got_a == got_b && (got_a ? ha.fiber == hb.fiber && std::abs(ha.t - hb.t) < 0.1f * r &&
                                                     ny::dot(ha.normal, hb.normal) > 0.9f &&
                                                     ny::dot(ha.axis, hb.axis) > 0.99f
                                               : ny::length(a.o - b.o) < 0.2f * r);
    differ += !same;
  }
  EXPECT_GT(hits, n / 2);
  EXPECT_LE(differ, n / 100) << differ << " of " << n;
}

/* Gathered through the wedges and through Embree's curves, a bent ply's energies agree within their noise (plus 1 %
 * for the tessellations), and so do the straight (radius 0) gathers, which both walk Embree's. */
TEST(BentPly, WedgesWalkLikeEmbreesCurves)
{
  const FiberPreset &p = find_preset("cotton");
  rdm::GatherOptions o = small_gather(200000);
  o.symmetrize = false;
  const rdm::RdmMaps a = rdm::gather_bent(p, rdm::Bend{2.0, 1, 4}, o, rdm::BentIntersector::kWedges);
  const rdm::RdmMaps b = rdm::gather_bent(p, rdm::Bend{2.0, 1, 4}, o, rdm::BentIntersector::kEmbree);
  EXPECT_EQ(a.intersector, "wedges");
  EXPECT_EQ(b.intersector, "embree");
  expect_same_energies(a.stats, b.stats, 0.01);
  EXPECT_EQ(rdm::gather_bent(p, rdm::Bend{0.0, 0, 1}, small_gather(1000)).intersector, "embree");
}

/* A bent gather's maps record their bend, and the file keeps it: what bench_bent_m reads a map's bend from (a map
 * labelled by hand can be labelled wrong). A ply's own maps record none. */
TEST(BentPly, MapsRecordTheirBend)
{
  const FiberPreset &p = find_preset("polyester");
  rdm::GatherOptions o = small_gather(2000);
  o.symmetrize = false;
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("ny_bent_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "bent.nyrdm").string();
  rdm::save_maps(rdm::gather_bent(p, rdm::Bend{2.5, 3, 8}, o), path);
  const rdm::RdmMaps back = rdm::load_maps(path);
  EXPECT_EQ(back.bend_radius, 2.5);
  EXPECT_EQ(back.bend_sector, 3);
  EXPECT_EQ(back.bend_sectors, 8);
  EXPECT_EQ(back.intersector, "wedges");
  rdm::save_maps(rdm::gather(p, o), path);
  EXPECT_EQ(rdm::load_maps(path).bend_sectors, 0);
  std::filesystem::remove_all(dir);
}
