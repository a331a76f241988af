// SPDX-License-Identifier: Apache-2.0
//
// The yarn level (docs/decisions.md D27): random walks through an explicit K-ply yarn (rdm/yarn_tracer.h),
// its maps and models carrying the structure they were gathered through.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

#include "neuralyarn/geometry/yarn.h"
#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/rdm/yarn_grid_tracer.h"
#include "neuralyarn/rdm/yarn_tracer.h"
#include "gather_checks.h"

using namespace neuralyarn;

namespace {

using neuralyarn::testing::small_gather;

geometry::Yarn one_ply_yarn(const FiberPreset &p, uint64_t seed)
{
  geometry::YarnParams yp;
  yp.K = 1;
  yp.ply = geometry::PlyParams{p.N, p.rho, p.alpha, 1.0};
  return geometry::Yarn(yp, seed);
}

}  // namespace

/* A one-ply "yarn" walked through its explicit, finite fibers — Embree's round curves or the slabs of chord
 * tubes — is the ply that PlyTracer walks through exactly (same cross-section, same helices): the energies of T,
 * R and M agree within their noise. Guards the yarn tracers' crossing of a fiber (Embree reports the tube's
 * exit, which the tracer culls), normals, mirror image and entry region; a tracer that stopped at the exit (a
 * path into the fiber scattering again inside it) fails, and so does a slab tracer whose chords miss the
 * fibers' points on its faces (gaps between slabs). */
void expect_one_ply_yarn_walks_like_the_ply(bool grid)
{
  const FiberPreset p = find_preset("polyester");
  const rdm::GatherOptions o = small_gather(400000);
  const rdm::RdmMaps ply = rdm::gather(p, o);
  const geometry::Yarn yarn = one_ply_yarn(p, o.packing_seed);
  const double entry = 8.0, half = 0.5 * entry + rdm::kYarnEndMargin;
  geometry::YarnStructure s; /* recorded as a ply: the geometry is one */
  s.surface_alpha = p.alpha;
  rdm::RdmMaps yarn_maps;
  if (grid) {
    const auto slabs = std::make_shared<const rdm::YarnSlabs>(yarn, half);
    const rdm::YarnGridTracer plain(slabs, entry, false), mirror(slabs, entry, true);
    yarn_maps = rdm::gather_through(p, s, o, plain, mirror);
  }
  else {
    const rdm::YarnTracer plain(yarn, entry, half, false), mirror(yarn, entry, half, true);
    yarn_maps = rdm::gather_through(p, s, o, plain, mirror);
  }
  EXPECT_EQ(yarn_maps.stats.paths_past_ends, 0u);
  /* Plus 1 % for chords against Embree's polylines. */
  neuralyarn::testing::expect_same_energies(yarn_maps.stats, ply.stats, 0.01);
}

TEST(YarnTracer, OnePlyYarnWalksLikeThePly) { expect_one_ply_yarn_walks_like_the_ply(false); }
TEST(YarnGridTracer, OnePlyYarnWalksLikeThePly) { expect_one_ply_yarn_walks_like_the_ply(true); }

/* The slab tracer answers what a test of every chord of every slab the ray crosses answers (tube entries within
 * each slab's x range, the excluded fiber skipped within its distance), on rays that enter the 3-ply yarn and
 * leave fibers in random directions, plain and mirrored. The tracer's distance is summed slab by slab from the
 * faces, so it may differ from the brute force's in the last digits; the fiber must be the same but where two
 * entries lie within 1e-4 fiber radii. */
TEST(YarnGridTracer, AnswersAsATestOfEveryChord)
{
  geometry::YarnStructure plying;
  plying.plies = 3;
  plying.ply_twist = 0.5;
  const geometry::Yarn yarn(geometry::yarn_params(find_preset("polyester"), plying), 1);
  const double half = 6.0;
  const auto slabs = std::make_shared<const rdm::YarnSlabs>(yarn, half);
  const rdm::YarnGridTracer plain(slabs, 4.0, false), mirror(slabs, 4.0, true);
  const float r = slabs->fiber_radius(), exclude_distance = 2.0f * r;
  const int fibers = 3 * int(yarn.cross_section(0).centers.size());
  auto flip = [](ny::Vec3 v) { return ny::make_vec3(-v.x, v.y, -v.z); };
  /* The nearest entry over every chord of the slabs the ray (in the unmirrored yarn) crosses before the bound. */
  auto brute = [&](ny::Vec3 o, ny::Vec3 d, int exclude, int *fiber, float *second) {
    const float t_cyl = rdm::cylinder_exit(o, d, slabs->bound_radius());
    const float xa = std::min(o.x, o.x + t_cyl * d.x), xb = std::max(o.x, o.x + t_cyl * d.x);
    float best = std::numeric_limits<float>::infinity();
    *second = best;
    *fiber = -1;
    for (int j = 0; j < slabs->num_slabs(); j++) {
      const float x0 = slabs->slab_face(j), x1 = slabs->slab_face(j + 1);
      if (x1 < xa || x0 > xb) {
        continue;
      }
      for (int f = 0; f < fibers; f++) {
        const float t = slabs->intersect_chord(j, f, o, d);
        const float x = o.x + t * d.x;
        if (!(t <= t_cyl) || x < x0 || x > x1 || (f == exclude && t < exclude_distance)) {
          continue;
        }
        if (t < best) {
          *second = best;
          best = t;
          *fiber = f;
        }
        else if (t < *second && f != *fiber) {
          *second = t;
        }
      }
    }
    return best;
  };
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto random_dir = [&] {
    const float z = 2.0f * u(rng) - 1.0f, a = 6.2831853f * u(rng), s = std::sqrt(std::max(1.0f - z * z, 0.0f));
    return ny::make_vec3(z, s * std::cos(a), s * std::sin(a));
  };
  int queries = 0, hits = 0, same = 0, near_ties = 0;
  for (int path = 0; path < 600; path++) {
    const bool mirrored = path % 2 == 1;
    const rdm::YarnGridTracer &tracer = mirrored ? mirror : plain;
    const float a = 6.2831853f * u(rng);
    rdm::SlabRay ray;
    ray.o = ny::make_vec3(4.0f * u(rng) - 2.0f, slabs->bound_radius() * std::cos(a), slabs->bound_radius() * std::sin(a));
    ray.d = random_dir();
    if (ray.d.y * ray.o.y + ray.d.z * ray.o.z > 0.0f) {
      ray.d = -ray.d; /* inward */
    }
    int exclude = -1;
    for (int event = 0; event < 8; event++) {
      const ny::Vec3 o = ray.o, d = ray.d;
      int expected = -1;
      float second = 0.0f;
      const float t_brute = mirrored ? brute(flip(o), flip(d), exclude, &expected, &second)
                                     : brute(o, d, exclude, &expected, &second);
      rdm::TubeHit hit;
      const bool found = tracer.trace(&ray, exclude, exclude_distance, &hit);
      queries++;
      if (found) {
        hits++;
      }
      if ((found ? hit.fiber : -1) == expected) {
        same++;
        if (found) {
          /* The distance summed over slabs, from origins a few ulps apart: a grazing entry moves along the ray
           * by that over the sine of its angle. The point itself lies on the fiber's tube. */
          EXPECT_NEAR(hit.t, t_brute, 1e-3f * std::max(t_brute, r));
          const ny::Vec3 p = o + d * hit.t;
          EXPECT_NEAR(ny::length(hit.point - p), 0.0f, 1e-3f * r);
          const ny::Vec3 q = mirrored ? flip(hit.point) : hit.point;
          int j = 0;
          while (j + 1 < slabs->num_slabs() && q.x > slabs->slab_face(j + 1)) {
            j++;
          }
          EXPECT_NEAR(slabs->distance_from_chord(j, hit.fiber, q), r, 1e-3f * r);
          EXPECT_GT(hit.axis.x, 0.0f);
          EXPECT_LT(ny::dot(hit.normal, d), 0.0f); /* an entry faces the ray */
        }
      }
      else if (std::abs(second - t_brute) < 1e-4f * r) {
        near_ties++;
      }
      else {
        ADD_FAILURE() << "query " << queries << (mirrored ? " (mirrored)" : "") << ": tracer fiber "
                      << (found ? hit.fiber : -1) << " at " << (found ? hit.t : -1.0f) << ", chords " << expected
                      << " at " << t_brute;
      }
      if (!found) {
        break;
      }
      exclude = hit.fiber;
      ny::Vec3 wo = random_dir();
      tracer.leave_fiber(hit, wo, &ray);
    }
  }
  EXPECT_GT(hits, queries / 2);
  EXPECT_LE(near_ties, queries / 1000 + 1);
  EXPECT_EQ(same + near_ties, queries);
}

/* Slabs of chord tubes and Embree's round curves are two approximations of the same 3-ply yarn (each within
 * ~1 % of a fiber radius of the helices): walked through either, its energies agree within their noise. */
TEST(YarnGridTracer, WalksLikeEmbreesYarn)
{
  geometry::YarnStructure s;
  s.plies = 3;
  s.ply_twist = 0.5;
  const FiberPreset p = find_preset("fleece");
  const rdm::GatherOptions o = small_gather(300000);
  const rdm::RdmMaps grid = rdm::gather_yarn(p, s, o, rdm::YarnIntersector::kGrid);
  const rdm::RdmMaps embree = rdm::gather_yarn(p, s, o, rdm::YarnIntersector::kEmbree);
  /* Rays along the grooves between plies can run past the ends (16 yarn radii beyond the entry region): a few
   * in 10^5 paths, through either intersector (2 and 2 at this seed). */
  EXPECT_LE(grid.stats.paths_past_ends, o.paths / 10000);
  EXPECT_EQ(grid.structure.surface_alpha, embree.structure.surface_alpha);
  const double n = double(o.paths);
  auto tol = [&](double a, double b) { return 4.0 * std::sqrt(1.5 * (a + b) / n) + 0.01 * std::max(a, b); };
  for (int c = 0; c < 3; c++) {
    const rdm::GatherStats &g = grid.stats, &e = embree.stats;
    EXPECT_NEAR(g.energy_T[c], e.energy_T[c], tol(g.energy_T[c], e.energy_T[c])) << c;
    EXPECT_NEAR(g.energy_R[c], e.energy_R[c], tol(g.energy_R[c], e.energy_R[c])) << c;
    EXPECT_NEAR(g.energy_M[c], e.energy_M[c], tol(g.energy_M[c], e.energy_M[c])) << c;
  }
}

/* Slabs need fibers that cross every face once. Plies twisted so steeply that their outer fibers turn back along
 * the axis are refused by the slabs (rather than tubed by wrong chords) and told apart beforehand, so that
 * gather_yarn walks them through Embree's curves; the shipped plying and a one-ply yarn advance. */
TEST(YarnGridTracer, KnowsTheYarnsItCannotHold)
{
  const FiberPreset p = find_preset("polyester");
  geometry::YarnStructure steep;
  steep.plies = 2;
  steep.ply_twist = 8.0;
  const geometry::Yarn steep_yarn(geometry::yarn_params(p, steep), 1);
  EXPECT_FALSE(rdm::fibers_advance_along_axis(steep_yarn));
  EXPECT_THROW(rdm::YarnSlabs(steep_yarn, 2.0 * steep_yarn.yarn_radius()), std::runtime_error);
  geometry::YarnStructure shipped;
  shipped.plies = 3;
  shipped.ply_twist = 0.5;
  EXPECT_TRUE(rdm::fibers_advance_along_axis(geometry::Yarn(geometry::yarn_params(p, shipped), 1)));
  EXPECT_TRUE(rdm::fibers_advance_along_axis(one_ply_yarn(p, 1)));
}

TEST(YarnGridTracer, RefusesABadHalfLength)
{
  const geometry::Yarn yarn = one_ply_yarn(find_preset("silk"), 1);
  EXPECT_THROW(rdm::YarnSlabs(yarn, std::nan("")), ParameterError);
  EXPECT_THROW(rdm::YarnSlabs(yarn, 0.0), ParameterError);
  EXPECT_THROW(rdm::YarnSlabs(yarn, std::numeric_limits<double>::infinity()), ParameterError);
}

/* The surface twist of a one-ply yarn is the ply's alpha, scaled by where the outer fibers sit (rho within
 * three fiber radii of R); a balanced yarn's S plying turns it down, here past zero. */
TEST(YarnGeometry, SurfaceTwist)
{
  const FiberPreset p = find_preset("fleece");
  const geometry::Yarn one = one_ply_yarn(p, 1);
  const double r = one.cross_section(0).r;
  const double a1 = geometry::surface_twist(one);
  EXPECT_LE(a1, p.alpha);
  EXPECT_GE(a1, p.alpha * (1.0 - 4.0 * r));
  geometry::YarnParams yp;
  yp.K = 3;
  yp.alpha_yarn = 0.5;
  yp.ply = geometry::PlyParams{p.N, p.rho, p.alpha, 1.0};
  const double a3 = geometry::surface_twist(geometry::Yarn(yp, 1));
  EXPECT_LT(a3, a1 - 0.1); /* the plies' S twist at the yarn's surface: atan(pi 0.5) ~ 58 degrees the other way */
  yp.alpha_yarn = 0.0;
  EXPECT_NEAR(geometry::surface_twist(geometry::Yarn(yp, 1)), a1, 0.15 * a1); /* untwisted plies: the fibers' own */
}

/* One ply on the axis: every point of its surface is visible, its normal is the yarn's radial, and its fibers
 * run as the kernel's surface fiber of twist alpha (kernel/frames.h), which ties the geometry's frame to the
 * kernel's convention (y = z x x, a Z twist tilts the tangent to -y). */
TEST(YarnGeometry, SurfaceFramesOfOnePlyAreTheKernelsSurfaceFiber)
{
  const FiberPreset p = find_preset("polyester");
  const ny::Vec3 t = ny::surface_fiber_tangent(ny::make_twist_rotation(float(p.alpha)));
  for (const geometry::SurfaceFrame &f : geometry::visible_surface_frames(one_ply_yarn(p, 1), 4, 1.0)) {
    EXPECT_NEAR(f.N.z(), 1.0, 1e-9);
    EXPECT_NEAR(f.turn, 0.0, 1e-9);
    EXPECT_NEAR(f.T.x(), t.x, 1e-5);
    EXPECT_NEAR(f.T.y(), t.y, 1e-5);
    EXPECT_NEAR(f.T.z(), t.z, 1e-5);
  }
}

/* Three plies (the shipped plying): the frames are the ridges' flanks, mirror images about the crest (the
 * surface's turn and the fibers' slope out of the envelope's plane change sign, their tilt in it does not); a
 * narrower share of the surface keeps them closer to the crest, whose fibers have the yarn's surface twist
 * (geometry::surface_twist averages the outermost fibers: 0.02 in alpha). */
TEST(YarnGeometry, SurfaceFramesOfThreePliesAreTheRidgesFlanks)
{
  geometry::YarnStructure plying;
  plying.plies = 3;
  plying.ply_twist = 0.5;
  const geometry::Yarn yarn(geometry::yarn_params(find_preset("polyester"), plying), 1);
  const std::vector<geometry::SurfaceFrame> wide = geometry::visible_surface_frames(yarn, 4, 1.0);
  const std::vector<geometry::SurfaceFrame> narrow = geometry::visible_surface_frames(yarn, 4, 0.2);
  ASSERT_EQ(wide.size(), 4u);
  for (int q = 0; q < 4; q++) {
    const geometry::SurfaceFrame &a = wide[size_t(q)], &b = wide[size_t(3 - q)];
    EXPECT_NEAR(a.turn, -b.turn, 0.02);
    EXPECT_NEAR(a.T.z(), -b.T.z(), 0.02);
    EXPECT_NEAR(a.T.y(), b.T.y(), 0.02);
    EXPECT_NEAR(a.T.norm(), 1.0, 1e-9);
    EXPECT_NEAR(a.N.norm(), 1.0, 1e-9);
    EXPECT_NEAR(a.T.dot(a.N), 0.0, 1e-9);
    EXPECT_LT(std::abs(narrow[size_t(q)].turn), std::abs(a.turn));
  }
  EXPECT_GT(wide[0].turn, -0.5 * kPi);
  EXPECT_LT(wide[0].turn, -0.3); /* the outer quantiles of a ridge's flanks, not the crest */
  const double crest_alpha = -narrow[1].T.y() / (kPi * narrow[1].T.x());
  EXPECT_NEAR(crest_alpha, geometry::surface_twist(yarn), 0.02);
}

TEST(YarnGeometry, SurfaceFramesRefuseBadRequests)
{
  const geometry::Yarn yarn = one_ply_yarn(find_preset("silk"), 1);
  EXPECT_THROW(geometry::visible_surface_frames(yarn, 0, 1.0), ParameterError);
  EXPECT_THROW(geometry::visible_surface_frames(yarn, 4, 0.0), ParameterError);
  EXPECT_THROW(geometry::visible_surface_frames(yarn, 4, 1.5), ParameterError);
  EXPECT_THROW(geometry::visible_surface_frames(yarn, 4, std::nan("")), ParameterError);
}

TEST(YarnTracer, OnePlyYarnIsRefusedForTheYarnLevel)
{
  geometry::YarnStructure s;
  s.plies = 1;
  try {
    rdm::gather_yarn(find_preset("silk"), s, small_gather(1000));
    FAIL() << "a one-ply yarn was gathered as a yarn";
  }
  catch (const ParameterError &e) {
    EXPECT_NE(std::string(e.what()).find("coincide"), std::string::npos) << e.what();
  }
}

/* Yarn maps are version 2 files that keep their structure; ply maps stay version 1. */
TEST(YarnMaps, KeepTheirStructureThroughTheFile)
{
  geometry::YarnStructure s;
  s.plies = 3;
  s.ply_twist = 0.5;
  const rdm::RdmMaps maps = rdm::gather_yarn(find_preset("silk"), s, small_gather(20000));
  EXPECT_EQ(maps.structure.plies, 3);
  EXPECT_TRUE(std::isfinite(maps.structure.surface_alpha));
  EXPECT_EQ(maps.stats.paths_past_ends, 0u);
  const std::string path = (std::filesystem::temp_directory_path() / "ny_yarn_maps.nyrdm").string();
  rdm::save_maps(maps, path);
  const rdm::RdmMaps back = rdm::load_maps(path);
  EXPECT_EQ(back.structure.plies, 3);
  EXPECT_EQ(back.structure.ply_twist, 0.5);
  EXPECT_EQ(back.structure.surface_alpha, maps.structure.surface_alpha);
  EXPECT_EQ(back.surface_alpha(), maps.structure.surface_alpha);
  EXPECT_EQ(maps.intersector, "slabs");
  EXPECT_EQ(back.intersector, "slabs");
  EXPECT_EQ(back.p_t, maps.p_t);
  std::filesystem::remove(path);
}

/* A yarn-level model is a version 5 file whose kernel array turns the R frame by the yarn's surface twist;
 * a version 5 file without its structure, or a version 4 file with one, is refused. */
TEST(YarnModel, StructureIsPartOfTheFile)
{
  model::YarnModel m = model::load_model(model::builtin_model_path("silk"));
  m.fallback.reset();
  m.structure.plies = 3;
  m.structure.ply_twist = 0.5;
  m.structure.surface_alpha = -0.3;
  const std::vector<float> flat = m.kernel_flat();
  EXPECT_FLOAT_EQ(flat[ny::kYarnFlatAlpha], -0.3f);
  nlohmann::json j = model::model_to_json(m);
  EXPECT_EQ(j["version"], model::kModelFormatVersionYarn);
  const model::YarnModel back = model::model_from_json(j, "yarn");
  EXPECT_EQ(back.structure.plies, 3);
  EXPECT_EQ(back.kernel_flat(), flat);
  nlohmann::json no_structure = j;
  no_structure.erase("structure");
  EXPECT_THROW(model::model_from_json(no_structure, "m"), model::ModelError);
  nlohmann::json old = j;
  old["version"] = model::kModelFormatVersion;
  EXPECT_THROW(model::model_from_json(old, "m"), model::ModelError);
  nlohmann::json nan = j;
  nan["structure"]["surface_alpha"] = nullptr;
  EXPECT_THROW(model::model_from_json(nan, "m"), model::ModelError);
}
