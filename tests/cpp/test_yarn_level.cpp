// SPDX-License-Identifier: Apache-2.0
//
// The yarn level (docs/decisions.md D27): random walks through an explicit K-ply yarn (rdm/yarn_tracer.h),
// its maps and models carrying the structure they were gathered through.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "neuralyarn/geometry/yarn.h"
#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/rdm/yarn_tracer.h"

using namespace neuralyarn;

namespace {

rdm::GatherOptions small_gather(uint64_t paths)
{
  rdm::GatherOptions o;
  o.paths = paths;
  o.bins = rdm::parse_resolution("6x12x12x12");
  o.threads = 2;
  return o;
}

geometry::Yarn one_ply_yarn(const FiberPreset &p, uint64_t seed)
{
  geometry::YarnParams yp;
  yp.K = 1;
  yp.ply = geometry::PlyParams{p.N, p.rho, p.alpha, 1.0};
  return geometry::Yarn(yp, seed);
}

}  // namespace

/* A one-ply "yarn" walked through Embree's explicit, finite fibers is the ply that PlyTracer walks through
 * exactly (same cross-section, same helices): the energies of T, R and M agree within their noise. Guards the
 * yarn tracer's crossing of a fiber (Embree reports the tube's exit, which the tracer culls), normals, mirror
 * image and entry region; a tracer that stopped at the exit (a path into the fiber scattering again inside
 * it) fails. */
TEST(YarnTracer, OnePlyYarnWalksLikeThePly)
{
  const FiberPreset p = find_preset("polyester");
  const rdm::GatherOptions o = small_gather(400000);
  const rdm::RdmMaps ply = rdm::gather(p, o);
  const geometry::Yarn yarn = one_ply_yarn(p, o.packing_seed);
  const double entry = 8.0, half = 0.5 * entry + rdm::kYarnEndMargin;
  const rdm::YarnTracer plain(yarn, entry, half, false), mirror(yarn, entry, half, true);
  geometry::YarnStructure s; /* recorded as a ply: the geometry is one */
  s.surface_alpha = p.alpha;
  const rdm::RdmMaps emb = rdm::gather_through(p, s, o, plain, mirror);
  EXPECT_EQ(emb.stats.paths_past_ends, 0u);
  const double n = double(o.paths);
  for (int c = 0; c < 3; c++) {
    /* Per-path exit weights are below ~1.5 (roulette keeps them near 1), so Var <= 1.5 E: 4 sigma of a
     * difference of two independent means, plus 1 % for chords against Embree's polylines. */
    auto tol = [&](double a, double b) { return 4.0 * std::sqrt(1.5 * (a + b) / n) + 0.01 * std::max(a, b); };
    EXPECT_NEAR(emb.stats.energy_T[c], ply.stats.energy_T[c], tol(emb.stats.energy_T[c], ply.stats.energy_T[c])) << c;
    EXPECT_NEAR(emb.stats.energy_R[c], ply.stats.energy_R[c], tol(emb.stats.energy_R[c], ply.stats.energy_R[c])) << c;
    EXPECT_NEAR(emb.stats.energy_M[c], ply.stats.energy_M[c], tol(emb.stats.energy_M[c], ply.stats.energy_M[c])) << c;
  }
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
