// SPDX-License-Identifier: Apache-2.0
//
// The five presets are the paper's table, they validate, and bad parameters are rejected with a message
// that names the parameter.
#include <cmath>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "neuralyarn/presets.h"
#include "neuralyarn/units.h"

using neuralyarn::kPi;

namespace {

using neuralyarn::FiberPreset;
using neuralyarn::ParameterError;

TEST(Presets, FiveFromThePaperTable)
{
  const auto &all = neuralyarn::builtin_presets();
  ASSERT_EQ(all.size(), 5u);
  const char *order[] = {"fleece", "silk", "polyester", "cotton", "gabardine"};
  for (size_t i = 0; i < 5; i++) {
    EXPECT_EQ(all[i].name, order[i]);
  }
  const FiberPreset &f = neuralyarn::find_preset("fleece");
  EXPECT_EQ(f.N, 300);
  EXPECT_DOUBLE_EQ(f.rho, 0.30);
  EXPECT_DOUBLE_EQ(f.alpha, 0.24);
  EXPECT_DOUBLE_EQ(f.C_R[1], 0.087);
  EXPECT_DOUBLE_EQ(f.C_TT[2], 0.948);
  EXPECT_DOUBLE_EQ(f.beta_R_deg, 7.238);
  EXPECT_DOUBLE_EQ(f.gamma_TT_deg, 25.989);
  const FiberPreset &c = neuralyarn::find_preset("cotton");
  EXPECT_EQ(c.N, 600);
  EXPECT_DOUBLE_EQ(c.beta_TT_deg, 27.197);
  EXPECT_DOUBLE_EQ(c.gamma_TT_deg, 38.269);
  const FiberPreset &g = neuralyarn::find_preset("gabardine");
  EXPECT_DOUBLE_EQ(g.C_R[0], 0.185);
  EXPECT_DOUBLE_EQ(g.C_TT[0], 0.999);
  const FiberPreset &s = neuralyarn::find_preset("silk");
  EXPECT_DOUBLE_EQ(s.alpha, 0.0);
  EXPECT_DOUBLE_EQ(s.C_R[0], 0.745);
}

TEST(Presets, PolyesterTransmissionWidthFollowsThePaperNotTheCode)
{
  /* docs/decisions.md D2: the paper's table says beta_TT = 20 degrees, the authors' code 10. */
  EXPECT_DOUBLE_EQ(neuralyarn::find_preset("polyester").beta_TT_deg, 20.0);
}

TEST(Presets, FiberParamsAreInRadians)
{
  const ny::FiberBsdfParams p = neuralyarn::find_preset("fleece").fiber_params();
  EXPECT_NEAR(p.beta_R, 7.238 * kPi / 180, 1e-7);
  EXPECT_NEAR(p.beta_TT, 10.0 * kPi / 180, 1e-7);
  EXPECT_NEAR(p.gamma_TT, 25.989 * kPi / 180, 1e-7);
}

TEST(Presets, UnknownNameListsTheKnownOnes)
{
  try {
    neuralyarn::find_preset("wool");
    FAIL() << "no exception";
  }
  catch (const ParameterError &e) {
    EXPECT_NE(std::string(e.what()).find("known: fleece, silk, polyester, cotton, gabardine"), std::string::npos);
  }
}

/* Runs validate() on a copy of fleece with one field changed, expects a ParameterError naming `param`. */
template<class F> void expect_rejected(const std::string &param, F mutate)
{
  FiberPreset p = neuralyarn::find_preset("fleece");
  mutate(p);
  try {
    neuralyarn::validate(p);
    ADD_FAILURE() << "accepted a bad " << param;
  }
  catch (const ParameterError &e) {
    EXPECT_EQ(e.parameter(), param);
    EXPECT_NE(std::string(e.what()).find("'" + param + "'"), std::string::npos) << e.what();
  }
}

TEST(Presets, ValidationRejectsUnphysicalValuesNamingTheParameter)
{
  expect_rejected("N", [](FiberPreset &p) { p.N = 0; });
  expect_rejected("rho", [](FiberPreset &p) { p.rho = 1.0; });
  expect_rejected("rho", [](FiberPreset &p) { p.rho = 0.0; });
  expect_rejected("rho", [](FiberPreset &p) { p.rho = NAN; });
  expect_rejected("alpha", [](FiberPreset &p) { p.alpha = -0.01; });
  expect_rejected("alpha", [](FiberPreset &p) { p.alpha = INFINITY; });
  expect_rejected("C_R[1]", [](FiberPreset &p) { p.C_R[1] = 1.5; });
  expect_rejected("C_TT[2]", [](FiberPreset &p) { p.C_TT[2] = -0.1; });
  expect_rejected("C_TT[0]", [](FiberPreset &p) { p.C_TT[0] = NAN; });
  expect_rejected("beta_R_deg", [](FiberPreset &p) { p.beta_R_deg = -1.0; });
  expect_rejected("beta_R_deg", [](FiberPreset &p) { p.beta_R_deg = 0.0; });
  expect_rejected("beta_TT_deg", [](FiberPreset &p) { p.beta_TT_deg = NAN; });
  expect_rejected("gamma_TT_deg", [](FiberPreset &p) { p.gamma_TT_deg = 1000.0; });
}

TEST(Presets, BoundaryValuesAreAccepted)
{
  FiberPreset p = neuralyarn::find_preset("fleece");
  p.C_R = {0.0, 0.0, 1.0};
  p.C_TT = {1.0, 0.0, 0.5};
  p.alpha = 0.0;
  p.beta_R_deg = neuralyarn::kMinWidthDeg;
  p.gamma_TT_deg = neuralyarn::kMaxWidthDeg;
  EXPECT_NO_THROW(neuralyarn::validate(p));
}

TEST(Presets, JsonErrorsNameTheParameter)
{
  nlohmann::json o = {{"N", 300},          {"rho", 0.3},          {"alpha", 0.24},
                      {"C_R", {0.1, 0.1, 0.1}}, {"C_TT", {0.5, 0.5, 0.5}}, {"beta_R_deg", 5},
                      {"beta_TT_deg", 10}, {"gamma_TT_deg", 20}};
  EXPECT_EQ(neuralyarn::preset_from_json(o, "ok").name, "ok");

  auto expect_param = [](nlohmann::json bad, const std::string &param) {
    try {
      neuralyarn::preset_from_json(bad, "custom");
      ADD_FAILURE() << "accepted " << bad.dump();
    }
    catch (const ParameterError &e) {
      EXPECT_EQ(e.parameter(), param) << e.what();
    }
  };
  nlohmann::json b = o;
  b["N"] = 12.5;
  expect_param(b, "N");
  b = o;
  b["C_R"] = {0.1, 0.1};
  expect_param(b, "C_R");
  b = o;
  b["C_TT"] = {0.1, "red", 0.1};
  expect_param(b, "C_TT[1]");
  b = o;
  b.erase("gamma_TT_deg");
  expect_param(b, "gamma_TT_deg");
  b = o;
  b["beta_r_deg"] = 5;
  expect_param(b, "beta_r_deg");
  b = o;
  b["rho"] = "dense";
  expect_param(b, "rho");
}

TEST(Presets, FileErrorsNameTheFile)
{
  try {
    neuralyarn::load_preset_file("/nonexistent/fiber.json");
    FAIL();
  }
  catch (const ParameterError &e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/fiber.json"), std::string::npos);
  }
  const std::string path = std::string(NY_TEST_DATA_DIR) + "/bad_not_json.json";
  try {
    neuralyarn::load_preset_file(path);
    FAIL();
  }
  catch (const ParameterError &e) {
    EXPECT_NE(std::string(e.what()).find("not valid JSON"), std::string::npos) << e.what();
  }
  const FiberPreset good = neuralyarn::load_preset_file(std::string(NY_TEST_DATA_DIR) + "/good_custom.json");
  EXPECT_EQ(good.name, "my_wool");
  EXPECT_EQ(good.N, 120);
}

}  // namespace
