// SPDX-License-Identifier: Apache-2.0
//
// The close-up's light rigs (`neuralyarn cycles-scene --lights`): each rig writes the lights it names, read
// back from the scene file the way Cycles 4.3's XML reader reads them (a distant light's third transform
// column is the direction toward the light), and the integrator settings that keep references unbiased.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "neuralyarn/model/model.h"
#include "neuralyarn/model/surface_fit.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/scenes/ply_scene.h"
#include "neuralyarn/units.h"

using neuralyarn::kPi;
using neuralyarn::kDeg;

namespace {

namespace fs = std::filesystem;
using neuralyarn::scenes::find_light_rig;
using neuralyarn::scenes::light_rigs;
using neuralyarn::scenes::PlySceneOptions;
using neuralyarn::scenes::RigLight;

using Attributes = std::map<std::string, std::string>;

/* The attributes of every element `<tag ...>` in the text, in order. */
std::vector<Attributes> elements(const std::string &xml, const std::string &tag)
{
  std::vector<Attributes> out;
  const std::regex element("<" + tag + "\\s([^>]*)>"), attribute("([A-Za-z_]+)=\"([^\"]*)\"");
  for (auto e = std::sregex_iterator(xml.begin(), xml.end(), element); e != std::sregex_iterator(); ++e) {
    Attributes a;
    const std::string body = (*e)[1];
    for (auto m = std::sregex_iterator(body.begin(), body.end(), attribute); m != std::sregex_iterator(); ++m) {
      a[(*m)[1]] = (*m)[2];
    }
    out.push_back(a);
  }
  return out;
}

std::vector<double> numbers(const std::string &text)
{
  std::istringstream in(text);
  std::vector<double> v;
  double x;
  while (in >> x) {
    v.push_back(x);
  }
  return v;
}

/* The scene a rig writes (explicit fibers of a short fleece ply), as text. */
std::string scene_text(PlySceneOptions o)
{
  const fs::path path = fs::temp_directory_path() / ("ny_scene_test_" + std::to_string(::getpid()) + ".xml");
  o.ply_length = 1.0;
  neuralyarn::scenes::write_ply_scene(neuralyarn::find_preset("fleece"), o, path.string());
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  fs::remove(path);
  return ss.str();
}

std::string scene_text(const std::string &lights)
{
  PlySceneOptions o;
  o.lights = lights;
  return scene_text(o);
}

/* The distant light's direction toward the light: the third column of its 3x4 row-major transform. */
struct Dir {
  double x, y, z;
};
Dir distant_direction(const Attributes &light)
{
  const std::vector<double> t = numbers(light.at("tfm"));
  EXPECT_EQ(t.size(), 12u);
  /* Columns 0, 1, 2 orthonormal and right-handed (x cross y = z). */
  auto col = [&](int c) { return Dir{t[c], t[4 + c], t[8 + c]}; };
  auto dot = [](Dir a, Dir b) { return a.x * b.x + a.y * b.y + a.z * b.z; };
  const Dir u = col(0), v = col(1), z = col(2);
  EXPECT_NEAR(dot(u, u), 1.0, 1e-6);
  EXPECT_NEAR(dot(v, v), 1.0, 1e-6);
  EXPECT_NEAR(dot(z, z), 1.0, 1e-6);
  EXPECT_NEAR(dot(u, v), 0.0, 1e-6);
  EXPECT_NEAR(dot(u, z), 0.0, 1e-6);
  EXPECT_NEAR(u.y * v.z - u.z * v.y, z.x, 1e-6);
  EXPECT_NEAR(u.z * v.x - u.x * v.z, z.y, 1e-6);
  EXPECT_NEAR(u.x * v.y - u.y * v.x, z.z, 1e-6);
  return z;
}

/* Degrees between a direction and the view direction from the ply toward the camera (-z). */
double degrees_from_view(Dir d)
{
  return std::acos(-d.z) * 180.0 / kPi;
}

TEST(CyclesScene, RigNamesInOrderAndUnknownNameListsThem)
{
  std::vector<std::string> names;
  for (const auto &r : light_rigs()) {
    names.push_back(r.name);
    EXPECT_FALSE(r.description.empty());
  }
  EXPECT_EQ(names, (std::vector<std::string>{"key-rim", "environment", "front", "grazing", "back", "axis"}));
  EXPECT_EQ(PlySceneOptions().lights, "key-rim");
  try {
    find_light_rig("sun");
    FAIL() << "no exception";
  }
  catch (const std::runtime_error &e) {
    EXPECT_STREQ(e.what(), "unknown light rig 'sun' (known: key-rim, environment, front, grazing, back, axis, "
                           "sun-DEG-normal, sun-DEG-axis with DEG in [0, 180])");
  }
  EXPECT_THROW(scene_text("sun"), std::runtime_error);
}

TEST(CyclesScene, KeyRimIsTheTwoSphereLights)
{
  const std::string xml = scene_text("key-rim");
  const auto lights = elements(xml, "light");
  ASSERT_EQ(lights.size(), 2u);
  const double pos[2][3] = {{-3, 4, -8}, {2, -1, 9}};
  for (int i = 0; i < 2; i++) {
    EXPECT_EQ(lights[i].at("light_type"), "point");
    const std::vector<double> t = numbers(lights[i].at("tfm"));
    ASSERT_EQ(t.size(), 12u);
    EXPECT_EQ(t[3], pos[i][0]);
    EXPECT_EQ(t[7], pos[i][1]);
    EXPECT_EQ(t[11], pos[i][2]);
    EXPECT_EQ(numbers(lights[i].at("strength")), (std::vector<double>{2000, 2000, 2000}));
    EXPECT_EQ(lights[i].at("size"), "1");
  }
  EXPECT_EQ(elements(xml, "background").at(0).at("strength"), "0");
}

TEST(CyclesScene, EnvironmentIsAWhiteBackgroundWithoutLights)
{
  const std::string xml = scene_text("environment");
  EXPECT_TRUE(elements(xml, "light").empty());
  const auto bg = elements(xml, "background");
  ASSERT_EQ(bg.size(), 1u); /* the background node (the bare <background> element has no attributes) */
  EXPECT_EQ(bg[0].at("strength"), "1");
  EXPECT_EQ(bg[0].at("color"), "1 1 1");
  /* Roulette is on (min_bounce 0), unlike the white furnace. */
  EXPECT_EQ(elements(xml, "integrator").at(0).at("min_bounce"), "0");
}

TEST(CyclesScene, DistantRigsPointWhereTheyAreNamed)
{
  struct Expect {
    std::string rig;
    double degrees; /* from the view direction */
    char toward;    /* the axis the light leans to: 'y' (plane normal to the ply) or 'x' (along it) */
  };
  for (const Expect &e : {Expect{"front", 10, 'y'}, Expect{"grazing", 80, 'y'}, Expect{"back", 170, 'y'},
                          Expect{"axis", 80, 'x'}}) {
    SCOPED_TRACE(e.rig);
    const std::string xml = scene_text(e.rig);
    const auto lights = elements(xml, "light");
    ASSERT_EQ(lights.size(), 1u);
    EXPECT_EQ(lights[0].at("light_type"), "distant");
    const Dir d = distant_direction(lights[0]);
    EXPECT_NEAR(degrees_from_view(d), e.degrees, 1e-4);
    /* In the named plane, on its positive side. */
    EXPECT_NEAR(e.toward == 'y' ? d.x : d.y, 0.0, 1e-7);
    EXPECT_GT(e.toward == 'y' ? d.y : d.x, 0.1);
    /* Angular diameter 2 degrees, in radians; irradiance pi; MIS on; not seen by camera rays. */
    EXPECT_NEAR(std::stod(lights[0].at("angle")), 2.0 * kDeg, 1e-6);
    EXPECT_EQ(numbers(lights[0].at("strength")), (std::vector<double>(3, std::stod(lights[0].at("strength")))));
    EXPECT_NEAR(std::stod(lights[0].at("strength")), kPi, 1e-5);
    EXPECT_EQ(lights[0].at("use_mis"), "true");
    EXPECT_EQ(lights[0].at("use_camera"), "false");
    /* The table says the same. */
    const RigLight l = find_light_rig(e.rig).lights.at(0);
    EXPECT_NEAR(l.x, d.x, 1e-6);
    EXPECT_NEAR(l.y, d.y, 1e-6);
    EXPECT_NEAR(l.z, d.z, 1e-6);
    EXPECT_EQ(elements(xml, "background").at(0).at("strength"), "0");
  }
}

TEST(CyclesScene, IntegratorHasNoClampNoAdaptiveSamplingAndTheBounceLimitAndSeed)
{
  PlySceneOptions o;
  const Attributes d = elements(scene_text(o), "integrator").at(0);
  for (const char *k : {"max_bounce", "max_diffuse_bounce", "max_glossy_bounce", "max_transmission_bounce",
                        "transparent_max_bounce"}) {
    EXPECT_EQ(d.at(k), "1024") << k;
  }
  EXPECT_EQ(d.at("min_bounce"), "0");
  EXPECT_EQ(d.at("sample_clamp_direct"), "0");
  EXPECT_EQ(d.at("sample_clamp_indirect"), "0");
  EXPECT_EQ(d.at("use_adaptive_sampling"), "false");
  EXPECT_EQ(d.at("seed"), "0");

  o.max_bounce = 4096;
  o.seed = 7;
  o.lights = "grazing";
  const Attributes a = elements(scene_text(o), "integrator").at(0);
  EXPECT_EQ(a.at("max_bounce"), "4096");
  EXPECT_EQ(a.at("transparent_max_bounce"), "4096");
  EXPECT_EQ(a.at("seed"), "7");

  /* The white furnace: the environment rig, no roulette (min_bounce = max_bounce). */
  PlySceneOptions f;
  f.white_furnace = true;
  const std::string furnace = scene_text(f);
  EXPECT_TRUE(elements(furnace, "light").empty());
  EXPECT_EQ(elements(furnace, "background").at(0).at("strength"), "1");
  EXPECT_EQ(elements(furnace, "integrator").at(0).at("min_bounce"), "1024");
  f.lights = "front";
  EXPECT_THROW(scene_text(f), std::runtime_error);
  o.max_bounce = 0;
  EXPECT_THROW(scene_text(o), std::runtime_error);
}

}  // namespace

namespace {

/* The keys of the scene's <hair> element (std::regex recurses per character: too deep for its long lists). */
std::vector<double> hair_keys(const std::string &xml)
{
  const size_t hair = xml.find("<hair "), p = xml.find(" P=\"", hair);
  if (hair == std::string::npos || p == std::string::npos) {
    return {};
  }
  return numbers(xml.substr(p + 4, xml.find('"', p + 4) - (p + 4)));
}

TEST(CyclesScene, PlyRotationTurnsTheFibersAboutTheAxis)
{
  PlySceneOptions o;
  const std::vector<double> p0 = hair_keys(scene_text(o));
  o.ply_rotation_deg = 90.0;
  const std::vector<double> p90 = hair_keys(scene_text(o));
  ASSERT_EQ(p0.size(), p90.size());
  ASSERT_GT(p0.size(), 30u);
  /* Right-handed about +x: (x, y, z) -> (x, -z, y), every key (the writer's 7 significant digits). */
  for (size_t i = 0; i < p0.size(); i += 3) {
    EXPECT_NEAR(p90[i], p0[i], 1e-6);
    EXPECT_NEAR(p90[i + 1], -p0[i + 2], 1e-6);
    EXPECT_NEAR(p90[i + 2], p0[i + 1], 1e-6);
  }
}

}  // namespace

namespace {

/* The numbers of attribute `key` of the scene's first <hair> element (searched, not regex-matched: long). */
std::vector<double> hair_attribute(const std::string &xml, const std::string &key)
{
  const size_t hair = xml.find("<hair "), p = xml.find(" " + key + "=\"", hair);
  if (hair == std::string::npos || p == std::string::npos) {
    return {};
  }
  const size_t b = p + key.size() + 3;
  return numbers(xml.substr(b, xml.find('"', b) - b));
}

TEST(CyclesScene, ParametricSunsAreTheNamedRigsAtOtherAngles)
{
  /* sun-80-normal is the grazing rig's light, sun-80-axis the axis rig's, sun-170-normal the back rig's. */
  for (const auto &[sun, rig] : std::vector<std::pair<std::string, std::string>>{
           {"sun-80-normal", "grazing"}, {"sun-80-axis", "axis"}, {"sun-170-normal", "back"}}) {
    const RigLight a = find_light_rig(sun).lights.at(0), b = find_light_rig(rig).lights.at(0);
    EXPECT_NEAR(a.x, b.x, 1e-12) << sun;
    EXPECT_NEAR(a.y, b.y, 1e-12) << sun;
    EXPECT_NEAR(a.z, b.z, 1e-12) << sun;
    EXPECT_EQ(a.strength, b.strength);
    EXPECT_EQ(a.size, b.size);
  }
  /* Written as the named rigs are: 89.9 degrees from the view, along the axis. */
  const std::vector<Attributes> lights = elements(scene_text("sun-89.9-axis"), "light");
  ASSERT_EQ(lights.size(), 1u);
  const Dir d = distant_direction(lights[0]);
  EXPECT_NEAR(degrees_from_view(d), 89.9, 1e-4);
  EXPECT_NEAR(d.y, 0.0, 1e-7);
  /* Camera and light coincident (0) and straight behind (180) are allowed; nothing else is. */
  EXPECT_NEAR(find_light_rig("sun-0-normal").lights.at(0).z, -1.0, 1e-12);
  EXPECT_NEAR(find_light_rig("sun-180-axis").lights.at(0).z, 1.0, 1e-12);
  for (const char *bad : {"sun-180.5-normal", "sun--5-normal", "sun-abc-axis", "sun-45-up", "sun-45", "sun-45x-axis",
                          "sun--axis"}) {
    EXPECT_THROW(find_light_rig(bad), std::runtime_error) << bad;
  }
}

TEST(CyclesScene, UnitScaleScalesEveryLengthAndPointLightPower)
{
  PlySceneOptions o;
  const std::string one = scene_text(o);
  o.unit_scale = 1e-3;
  const std::string milli = scene_text(o);
  const std::vector<double> p1 = hair_keys(one), pm = hair_keys(milli);
  ASSERT_EQ(p1.size(), pm.size());
  for (size_t i = 0; i < p1.size(); i += 97) {
    EXPECT_NEAR(pm[i], 1e-3 * p1[i], 1e-9 + 1e-6 * std::abs(p1[i]));
  }
  EXPECT_NEAR(hair_attribute(milli, "radius").at(0), 1e-3 * hair_attribute(one, "radius").at(0), 1e-9);
  EXPECT_NEAR(numbers(elements(milli, "transform").at(0).at("translate")).at(2), -12e-3, 1e-12);
  /* key-rim's sphere lights: positions and radii scaled, power with the area (same irradiance at the ply). */
  const Attributes l1 = elements(one, "light").at(0), lm = elements(milli, "light").at(0);
  EXPECT_NEAR(numbers(lm.at("tfm")).at(3), 1e-3 * numbers(l1.at("tfm")).at(3), 1e-12);
  EXPECT_NEAR(std::stod(lm.at("size")), 1e-3 * std::stod(l1.at("size")), 1e-12);
  EXPECT_NEAR(numbers(lm.at("strength")).at(0), 1e-6 * numbers(l1.at("strength")).at(0), 1e-9);
  o.unit_scale = 0.0;
  EXPECT_THROW(scene_text(o), std::runtime_error);
}

TEST(CyclesScene, LayersAreSheetsOfPliesStackedAwayFromTheCamera)
{
  PlySceneOptions o;
  o.model = std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json";
  o.layers = 3;
  const std::string xml = scene_text(o);
  const std::vector<double> nkeys = hair_attribute(xml, "nkeys"), p = hair_keys(xml);
  /* The sheet fills the frame's height at the camera (12 tan 0.45 = 5.8 radii each side): 2 * 4 + 1 plies. */
  ASSERT_EQ(nkeys.size(), 3u * 9u);
  ASSERT_EQ(p.size(), 3u * nkeys.size() * size_t(nkeys[0]));
  double z_max = 0.0, y_max = 0.0;
  for (size_t i = 0; i < p.size(); i += 3) {
    y_max = std::max(y_max, std::abs(p[i + 1]));
    z_max = std::max(z_max, p[i + 2]);
    EXPECT_GE(p[i + 2], 0.0);
  }
  EXPECT_NEAR(y_max, 4 * 2.05, 1e-5);
  EXPECT_NEAR(z_max, 2 * 2.05, 1e-5); /* behind the first layer, away from the camera */
  /* Explicit: the same plies of fibers, each turned differently. */
  o.model.clear();
  o.layers = 2;
  const std::vector<double> fibers = hair_attribute(scene_text(o), "nkeys");
  o.layers = 1;
  EXPECT_EQ(fibers.size(), 2u * 9u * hair_attribute(scene_text(o), "nkeys").size());
  o.layers = 0;
  EXPECT_THROW(scene_text(o), std::runtime_error);
}

TEST(CyclesScene, LayerPitchesSpaceThePliesWithinAndBetweenSheets)
{
  PlySceneOptions o;
  o.model = std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json";
  o.layers = 2;
  o.layer_pitch_y = 3.0;
  o.layer_pitch_z = 4.0;
  const std::vector<double> nkeys = hair_attribute(scene_text(o), "nkeys"), p = hair_keys(scene_text(o));
  /* ceil(12 tan 0.45 / 3) + 1 = 3 plies each side of the axis: 7 per sheet, two sheets. */
  ASSERT_EQ(nkeys.size(), 2u * 7u);
  double z_max = 0.0, y_max = 0.0;
  for (size_t i = 0; i < p.size(); i += 3) {
    y_max = std::max(y_max, std::abs(p[i + 1]));
    z_max = std::max(z_max, p[i + 2]);
  }
  EXPECT_NEAR(y_max, 3 * 3.0, 1e-5);
  EXPECT_NEAR(z_max, 4.0, 1e-5);
  /* Plies that would overlap, a pitch that is not a number, and a pitch without layers are refused. */
  for (const double bad : {1.99, 100.5, std::nan("")}) {
    o.layer_pitch_y = bad;
    EXPECT_THROW(scene_text(o), std::runtime_error) << bad;
    o.layer_pitch_y = 3.0;
    o.layer_pitch_z = bad;
    EXPECT_THROW(scene_text(o), std::runtime_error) << bad;
    o.layer_pitch_z = 4.0;
  }
  o.layers = 1;
  EXPECT_THROW(scene_text(o), std::runtime_error);
}

TEST(CyclesScene, ArtistBounceLimitsAreBlendersDefaultsWithTheAddonsTransparency)
{
  PlySceneOptions o;
  o.artist_bounces = true;
  const Attributes a = elements(scene_text(o), "integrator").at(0);
  EXPECT_EQ(a.at("max_bounce"), "12");
  EXPECT_EQ(a.at("max_diffuse_bounce"), "4");
  EXPECT_EQ(a.at("max_glossy_bounce"), "4");
  EXPECT_EQ(a.at("max_transmission_bounce"), "12");
  EXPECT_EQ(a.at("transparent_max_bounce"), "64");
  o.white_furnace = true;
  EXPECT_THROW(scene_text(o), std::runtime_error);
}

TEST(CyclesScene, PointLightsAreSampledOnlyAndNeverSeen)
{
  /* The standalone's light default (no MIS: no ray hits the sphere), stated, so that Blender (whose lights
   * default to MIS and a visible sphere) renders the same light (tests/eval/test_scene_builder.py). */
  for (const Attributes &l : elements(scene_text("key-rim"), "light")) {
    EXPECT_EQ(l.at("use_mis"), "false");
    EXPECT_EQ(l.at("use_camera"), "false");
  }
}

TEST(SceneDescription, OneSceneTwoFormatsByExtension)
{
  using namespace neuralyarn::scenes;
  PlySceneOptions o;
  o.ply_length = 1.0;
  o.diffuse = true;
  const Scene scene = ply_scene(neuralyarn::find_preset("fleece"), o);
  ASSERT_EQ(scene.objects.size(), 1u);
  EXPECT_EQ(scene.objects[0].material.kind, Material::Kind::diffuse);
  EXPECT_EQ(scene.num_curves(), 1u);
  EXPECT_EQ(scene.num_curve_keys(), 17u);
  const fs::path dir = fs::temp_directory_path() / ("ny_scene_formats_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  write_scene(scene, (dir / "s.xml").string());
  write_scene(scene, (dir / "s.json").string());
  std::ifstream xml(dir / "s.xml"), json(dir / "s.json");
  std::stringstream x, j;
  x << xml.rdbuf();
  j << json.rdbuf();
  EXPECT_NE(x.str().find("<diffuse_bsdf name=\"y\" color=\"0.5 0.5 0.5\" />"), std::string::npos);
  EXPECT_NE(j.str().find("\"format\":\"neuralyarn-scene 1\""), std::string::npos);
  EXPECT_NE(j.str().find("\"type\":\"diffuse\""), std::string::npos);
  /* Another extension is refused, naming both formats, and nothing is written. */
  try {
    write_scene(scene, (dir / "s.txt").string());
    FAIL() << "no exception";
  }
  catch (const std::runtime_error &e) {
    EXPECT_NE(std::string(e.what()).find("must be .xml (Cycles XML) or .json"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "s.txt"));
  fs::remove_all(dir);
}

TEST(SceneDescription, EmptySceneHasTheCameraAndNothingElse)
{
  using namespace neuralyarn::scenes;
  PlySceneOptions o;
  o.empty = true;
  o.width = 64, o.height = 32;
  const Scene scene = ply_scene(neuralyarn::find_preset("fleece"), o);
  EXPECT_TRUE(scene.objects.empty());
  EXPECT_TRUE(scene.lights.empty());
  EXPECT_EQ(scene.background.strength, 0.0);
  EXPECT_EQ(scene.camera.width, 64);
  EXPECT_EQ(scene.camera.position.z(), -kCloseupCameraDistance);
  /* The diffuse check replaces the model: both is refused. */
  o.empty = false;
  o.diffuse = true;
  o.baseline = "sheen";
  EXPECT_THROW(ply_scene(neuralyarn::find_preset("fleece"), o), std::runtime_error);
}

}  // namespace

TEST(CyclesSceneBaselines, StockClosuresOnTheAggregatedGeometryWithTheirColour)
{
  PlySceneOptions o;
  o.model = std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json";
  const std::string native = scene_text(o);
  o.model.clear();
  o.baseline_colour[0] = 0.25, o.baseline_colour[1] = 0.5, o.baseline_colour[2] = 0.75;
  for (const auto &b : neuralyarn::scenes::baselines()) {
    SCOPED_TRACE(b.name);
    o.baseline = b.name;
    const std::string xml = scene_text(o);
    /* The same one thick curve as the neural model's, and no neural closure. */
    EXPECT_EQ(hair_keys(xml), hair_keys(native));
    EXPECT_EQ(hair_attribute(xml, "radius"), hair_attribute(native, "radius"));
    EXPECT_EQ(xml.find("neural_yarn_bsdf"), std::string::npos);
    const bool hair = b.name != "sheen";
    const std::vector<Attributes> nodes = elements(xml, hair ? "principled_hair_bsdf" : "principled_bsdf");
    ASSERT_EQ(nodes.size(), 1u);
    EXPECT_EQ(numbers(nodes[0].at(hair ? "color" : "base_color")), (std::vector<double>{0.25, 0.5, 0.75}));
    if (hair) {
      EXPECT_EQ(nodes[0].at("model"), b.name == "chiang" ? "Chiang" : "Huang");
      EXPECT_EQ(nodes[0].at("parametrization"), "Direct coloring");
    }
    else {
      EXPECT_EQ(nodes[0].at("sheen_weight"), "1");
    }
  }
  o.baseline = "lambert";
  EXPECT_THROW(scene_text(o), std::runtime_error);
  o.baseline = "chiang";
  o.baseline_colour[1] = std::nan("");
  EXPECT_THROW(scene_text(o), std::runtime_error);
  o.baseline_colour[1] = 1.5;
  EXPECT_THROW(scene_text(o), std::runtime_error);
  o.baseline_colour[1] = 0.5;
  o.model = std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json";
  EXPECT_THROW(scene_text(o), std::runtime_error);
}

namespace {

/* A file name of this process in the temporary directory: <stem><pid>.json. */
std::string temp_json(const std::string &stem)
{
  return (fs::temp_directory_path() / (stem + std::to_string(::getpid()) + ".json")).string();
}

/* The options of an aggregated scene of a plies file at a level (its model or surface still to give). */
PlySceneOptions at_level(const std::string &plies, const std::string &level)
{
  PlySceneOptions o;
  o.plies = plies;
  o.level = level;
  return o;
}

std::string write_plies(const std::string &body)
{
  const std::string path = temp_json("ny_plies_test_");
  std::ofstream(path) << body;
  return path;
}

}  // namespace

TEST(CyclesScenePlies, CurvesFromAFileForBothVersionsAndLightsMovedOut)
{
  /* Two plies in units where the ply radius is 0.5: a straight one and a bent one. */
  const std::string plies = write_plies(
      R"({"format": "neuralyarn-plies 1", "ply_radius": 0.5,
          "plies": [[0, 0, 0, 2, 0, 0, 4, 0, 0], [0, 2, 0, 1, 2, 1, 2, 2, 1.5, 3, 2, 1.7]]})");
  PlySceneOptions o;
  o.plies = plies;
  o.model = std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json";
  const std::string agg = scene_text(o);
  /* One thick curve per ply through its points, scaled to ply radius 1. */
  EXPECT_EQ(hair_attribute(agg, "nkeys"), (std::vector<double>{3, 4}));
  const std::vector<double> p = hair_keys(agg);
  ASSERT_EQ(p.size(), 21u);
  EXPECT_DOUBLE_EQ(p[6], 8.0);
  EXPECT_DOUBLE_EQ(p[20], 3.4);
  /* Explicit: every ply's fibers (fleece's N per ply), each fiber at most a ply radius from its ply. */
  o.model.clear();
  const std::string fibers = scene_text(o);
  const int N = neuralyarn::find_preset("fleece").N;
  EXPECT_EQ(hair_attribute(fibers, "nkeys").size(), size_t(2 * N));
  const std::vector<double> f = hair_keys(fibers);
  for (size_t i = 0; i < size_t(N) * 3; i += 3) { /* the first ply's fibers: around the x axis */
    EXPECT_LE(std::hypot(f[i + 1], f[i + 2]), 1.0 + 1e-5);
  }
  /* The key-rim's point lights moved out and brightened with light_scale; the default leaves them. */
  const Attributes l1 = elements(fibers, "light").at(0);
  o.light_scale = 10.0;
  const Attributes l10 = elements(scene_text(o), "light").at(0);
  EXPECT_NEAR(numbers(l10.at("tfm"))[3], 10.0 * numbers(l1.at("tfm"))[3], 1e-4);
  EXPECT_NEAR(numbers(l10.at("strength"))[0], 100.0 * numbers(l1.at("strength"))[0], 1e-2);
  EXPECT_NEAR(numbers(l10.at("size"))[0], 10.0 * numbers(l1.at("size"))[0], 1e-6);
  fs::remove(plies);
}

TEST(CyclesScenePlies, BadFilesAndTooManyKeysAreRefusedBeforeWriting)
{
  PlySceneOptions o;
  for (const char *body : {"not json", R"({"format": "other", "ply_radius": 1, "plies": [[0,0,0,1,0,0]]})",
                           R"({"format": "neuralyarn-plies 1", "ply_radius": 0, "plies": [[0,0,0,1,0,0]]})",
                           R"({"format": "neuralyarn-plies 1", "ply_radius": 1, "plies": []})",
                           R"({"format": "neuralyarn-plies 1", "ply_radius": 1, "plies": [[0,0,0,1,0]]})",
                           R"({"format": "neuralyarn-plies 1", "ply_radius": 1, "plies": [[0,0,0,"x",0,0]]})"})
  {
    o.plies = write_plies(body);
    EXPECT_THROW(scene_text(o), std::runtime_error) << body;
  }
  /* A ply a million radii long: hundreds of millions of fiber keys. */
  o.plies = write_plies(R"({"format": "neuralyarn-plies 1", "ply_radius": 1, "plies": [[0,0,0,1e6,0,0]]})");
  try {
    scene_text(o);
    FAIL() << "too many keys accepted";
  }
  catch (const std::runtime_error &e) {
    EXPECT_NE(std::string(e.what()).find("curve keys"), std::string::npos) << e.what();
  }
  o.layers = 2;
  EXPECT_THROW(scene_text(o), std::runtime_error);
  fs::remove(o.plies);
}

/* The yarn level (D27): each yarn of the file one curve of the yarn radius, with a yarn-level model of the
 * file's plying; a model of the other level, or of another plying, is refused before anything is written. */
TEST(CyclesScenePlies, YarnLevelDrawsTheYarnsWithAYarnModel)
{
  const std::string body = R"({"format": "neuralyarn-plies 1", "ply_radius": 0.5,
      "plies": [[0, 0.6, 0, 4, 0.6, 0], [0, -0.3, 0.5, 4, -0.3, 0.5], [0, -0.3, -0.5, 4, -0.3, -0.5]],
      "yarns": [[0, 0, 0, 2, 0, 0, 4, 0, 0]], "yarn_radius": 1.1, "plies_per_yarn": 3, "ply_twist": 0.5})";
  const std::string plies = write_plies(body);
  neuralyarn::model::YarnModel m =
      neuralyarn::model::load_model(std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json");
  const std::string ply_model = std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json";
  m.fallback.reset();
  m.structure.plies = 3;
  m.structure.ply_twist = 0.5;
  m.structure.surface_alpha = -0.08;
  const std::string yarn_model = temp_json("ny_yarn_model_");
  neuralyarn::model::save_model(m, yarn_model);
  PlySceneOptions o = at_level(plies, "yarns");
  o.model = yarn_model;
  const std::string agg = scene_text(o);
  EXPECT_EQ(hair_attribute(agg, "nkeys"), (std::vector<double>{3}));
  EXPECT_DOUBLE_EQ(hair_attribute(agg, "radius").at(0), 2.2); /* 1.1 in units of ply radius 0.5 */
  EXPECT_DOUBLE_EQ(hair_keys(agg).at(6), 8.0);
  /* The ply level draws the three plies with the ply model; each model on the other level is refused. */
  o.level = "plies";
  o.model = ply_model;
  EXPECT_EQ(hair_attribute(scene_text(o), "nkeys").size(), 3u);
  o.model = yarn_model;
  EXPECT_THROW(scene_text(o), std::runtime_error);
  o.level = "yarns";
  o.model = ply_model;
  EXPECT_THROW(scene_text(o), std::runtime_error);
  /* Another plying than the model's. */
  m.structure.ply_twist = 0.8;
  neuralyarn::model::save_model(m, yarn_model);
  o.model = yarn_model;
  EXPECT_THROW(scene_text(o), std::runtime_error);
  /* Fibers have no yarn level; a file without yarns, or with a bad yarn radius, cannot be drawn as yarns. */
  o.model.clear();
  EXPECT_THROW(scene_text(o), std::runtime_error);
  m.structure.ply_twist = 0.5;
  neuralyarn::model::save_model(m, yarn_model);
  o.model = yarn_model;
  o.plies = write_plies(R"({"format": "neuralyarn-plies 1", "ply_radius": 1, "plies": [[0,0,0,1,0,0]]})");
  EXPECT_THROW(scene_text(o), std::runtime_error);
  for (const char *bad : {"\"yarn_radius\": 0.4", "\"yarn_radius\": null", "\"plies_per_yarn\": 1", "\"ply_twist\": -1"}) {
    std::string b = body;
    const std::string key = std::string(bad).substr(0, std::string(bad).find(':'));
    const size_t at = b.find(key);
    b.replace(at, b.find_first_of(",}", at) - at, bad);
    o.plies = write_plies(b);
    EXPECT_THROW(scene_text(o), std::runtime_error) << bad;
  }
  fs::remove(plies);
  fs::remove(yarn_model);
}

TEST(CyclesScenePlies, SurfaceLevelDrawsTheClothSurfaceWithItsStockClosures)
{
  /* Units of ply radius 0.5: the quad's vertices come out doubled. */
  const std::string plies = write_plies(R"({"format": "neuralyarn-plies 1", "ply_radius": 0.5,
      "plies": [[0, 0, 0, 4, 0, 0]],
      "surface": {"vertices": [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0], "triangles": [0, 1, 2, 0, 2, 3]}})");
  neuralyarn::model::SurfaceBsdf s;
  s.view_bins = 2;
  s.lobes = {{"diffuse", 0.0}, {"ggx", 0.25}};
  s.transparent = {0.1f, 0.3f, 0.2f, 0.6f};
  s.W = std::vector<float>(24, 0.2f);
  s.W[0] = 0.5f; /* front, view bin 0, diffuse, red */
  s.albedo = std::vector<float>(12, 0.5f);
  s.fit_error = std::vector<float>(4, 0.1f);
  const std::string surface = temp_json("ny_surface_");
  neuralyarn::model::save_surface(s, surface);
  PlySceneOptions o = at_level(plies, "surface");
  o.surface = surface;
  const std::string xml = scene_text(o);
  /* No curves: the mesh of two triangles in ply radii. */
  EXPECT_TRUE(elements(xml, "hair").empty());
  const std::vector<Attributes> mesh = elements(xml, "mesh");
  ASSERT_EQ(mesh.size(), 1u);
  EXPECT_EQ(numbers(mesh[0].at("nverts")), (std::vector<double>{3, 3}));
  EXPECT_EQ(numbers(mesh[0].at("verts")), (std::vector<double>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(numbers(mesh[0].at("P")).at(3), 2.0);
  /* transparent, diffuse and the glossy lobe (roughness sqrt(alpha)), each weighted by its curve. */
  EXPECT_EQ(elements(xml, "transparent_bsdf").size(), 1u);
  EXPECT_EQ(elements(xml, "diffuse_bsdf").size(), 1u);
  const std::vector<Attributes> glossy = elements(xml, "glossy_bsdf");
  ASSERT_EQ(glossy.size(), 1u);
  EXPECT_EQ(glossy[0].at("distribution"), "ggx");
  EXPECT_NEAR(std::stod(glossy[0].at("roughness")), 0.5, 1e-6);
  const std::vector<Attributes> curves = elements(xml, "rgb_curves");
  ASSERT_EQ(curves.size(), 3u);
  const std::vector<double> t = numbers(curves[0].at("curves")), d = numbers(curves[1].at("curves"));
  ASSERT_EQ(t.size(), 3u * 256u);
  /* x = 0: the front face seen edge-on (the tables extrapolated to cos 0); the last sample: the back face at
   * the normal. */
  const neuralyarn::model::SurfaceAt front0 = neuralyarn::model::surface_at(s, 0, 0.0);
  const neuralyarn::model::SurfaceAt back1 = neuralyarn::model::surface_at(s, 1, 1.0);
  EXPECT_NEAR(t[0], front0.transparent, 1e-6);
  EXPECT_NEAR(t[t.size() - 1], back1.transparent, 1e-6);
  EXPECT_NEAR(d[0], front0.W[0][0], 1e-6);
  /* The curves' input: |N.I| and the face, through the nodes that compute x. */
  EXPECT_NE(xml.find("<connect from=\"g backfacing\" to=\"bf value1\" />"), std::string::npos);
  EXPECT_NE(xml.find("<connect from=\"g incoming\" to=\"nv vector2\" />"), std::string::npos);
  /* The description for Blender: version 2 (a version-1 reader would draw the scene without its cloth), the same
   * mesh and the same closures' curves as the XML. */
  const std::string json = temp_json("ny_surface_scene_");
  neuralyarn::scenes::write_ply_scene(neuralyarn::find_preset("fleece"), o, json);
  {
    const nlohmann::json d = nlohmann::json::parse(std::ifstream(json));
    EXPECT_EQ(d.at("format"), "neuralyarn-scene 2");
    const nlohmann::json &m = d.at("meshes").at(0);
    EXPECT_EQ(m.at("mesh").at("triangles"), nlohmann::json({0, 1, 2, 0, 2, 3}));
    const nlohmann::json &cl = m.at("material").at("closures");
    ASSERT_EQ(cl.size(), 3u);
    EXPECT_EQ(cl[0].at("closure"), "transparent");
    EXPECT_EQ(cl[2].at("closure"), "ggx");
    EXPECT_NEAR(cl[2].at("alpha").get<double>(), 0.25, 1e-12);
    ASSERT_EQ(cl[0].at("weight").size(), 256u);
    for (size_t i = 0; i < 256; i++) {
      EXPECT_NEAR(cl[0].at("weight")[i][0].get<double>(), t[3 * i], 1e-5) << i;
    }
    EXPECT_EQ(m.at("material").at("front"), neuralyarn::model::kSurfaceFront);
  }
  fs::remove(json);
  /* Refused: the level without its BSDF, the BSDF without the level, a file without a surface, a model beside
   * it. */
  o.surface.clear();
  EXPECT_THROW(scene_text(o), std::runtime_error);
  o.surface = surface;
  o.level = "plies";
  EXPECT_THROW(scene_text(o), std::runtime_error);
  o.level = "surface";
  o.model = std::string(NY_TEST_DATA_DIR) + "/../../models/fleece.json";
  EXPECT_THROW(scene_text(o), std::runtime_error);
  o.model.clear();
  o.plies = write_plies(R"({"format": "neuralyarn-plies 1", "ply_radius": 1, "plies": [[0,0,0,1,0,0]]})");
  EXPECT_THROW(scene_text(o), std::runtime_error);
  for (const char *bad : {R"("surface": {"vertices": [0, 0, 0], "triangles": [0, 0, 1]})",
                          R"("surface": {"vertices": [0, 0, "x"], "triangles": [0, 0, 0]})",
                          R"("surface": {"vertices": [0, 0, 0], "triangles": [0, 0]})", R"("period": [1, -1])"}) {
    o.plies = write_plies(std::string(R"({"format": "neuralyarn-plies 1", "ply_radius": 1, "plies": [[0,0,0,1,0,0]], )") +
                          bad + "}");
    EXPECT_THROW(scene_text(o), std::runtime_error) << bad;
  }
  fs::remove(plies);
  fs::remove(surface);
}
