// SPDX-License-Identifier: Apache-2.0
//
// The near field of a model (decisions D68): the kernel's offsets drawn from the gather's quantiles
// (kernel/exit_placement.h), and the model file's "near_field" (model/model.h).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "neuralyarn/kernel/exit_placement.h"
#include "neuralyarn/model/bake.h"
#include "neuralyarn/model/model.h"
#include "synthetic_model.h"

using namespace neuralyarn;
using neuralyarn::testing::synthetic_model;

namespace {
/* Cotton's quantiles as the gather measured them (ply radii, 25 ... 99 %). */
const std::vector<float> kCotton = {0.18f, 0.94f, 2.8f, 5.85f, 8.6f, 17.1f};
}  // namespace

/* The drawn offsets' distribution is the quantiles': at each level its share of |offset| below the quantile,
 * signs even. Stratified u (10^5 strata): the empirical CDF at a knot is exact up to one stratum per segment. */
TEST(ExitPlacement, OffsetsFollowTheQuantiles)
{
  float knots[ny::kExitKnots];
  ny::exit_knots(kCotton.data(), knots);
  EXPECT_EQ(knots[0], 0.0f);
  EXPECT_FLOAT_EQ(knots[ny::kExitKnots - 1], 17.1f + (17.1f - 8.6f));
  const int n = 100000;
  std::vector<int> below(ny::kExitQuantiles, 0);
  int negative = 0;
  float largest = 0.0f;
  for (int i = 0; i < n; i++) {
    const float s = ny::exit_sample_offset(knots, (float(i) + 0.5f) / float(n));
    negative += s < 0.0f;
    largest = std::max(largest, std::abs(s));
    for (int k = 0; k < ny::kExitQuantiles; k++) {
      below[size_t(k)] += std::abs(s) <= kCotton[size_t(k)];
    }
  }
  EXPECT_EQ(negative, n / 2);
  EXPECT_LE(largest, knots[ny::kExitKnots - 1]);
  for (int k = 0; k < ny::kExitQuantiles; k++) {
    EXPECT_NEAR(double(below[size_t(k)]) / n, double(ny::exit_knot_level(k + 1)), 3.0 / n) << "level " << k;
  }
  /* The median of |offset| sits at the 50 % quantile, between the knots' linear pieces. */
  EXPECT_NEAR(std::abs(ny::exit_sample_offset(knots, 0.75f)), 0.94f, 1e-6f);
  EXPECT_NEAR(std::abs(ny::exit_sample_offset(knots, 0.25f)), 0.94f, 1e-6f);
  /* u at the ends of [0, 1) stays finite and bounded. */
  EXPECT_EQ(ny::exit_sample_offset(knots, 0.5f), 0.0f);
  EXPECT_LE(std::abs(ny::exit_sample_offset(knots, std::nextafter(1.0f, 0.0f))), knots[ny::kExitKnots - 1]);
}

TEST(ExitPlacement, QuantileCheckNamesWhatIsWrong)
{
  EXPECT_EQ(ny::exit_quantiles_check(kCotton.data(), 6), nullptr);
  std::vector<float> q = kCotton;
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 5), nullptr);
  q[2] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 6), nullptr);
  q = kCotton;
  q[3] = 0.5f; /* below the 75 % one */
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 6), nullptr);
  q = kCotton;
  q[0] = -0.1f;
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 6), nullptr);
  q = kCotton;
  q[5] = 2000.0f;
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 6), nullptr);
}

/* The model file carries them outside its kernel array (which the fallback tables name): written, read back
 * unchanged, the array the same with or without; bad values are refused with the key's name; the entry side's are
 * optional (files from before they were measured). */
TEST(ExitPlacement, ModelFileRoundTripAndRejection)
{
  model::YarnModel m = synthetic_model("cotton", 7);
  const std::vector<float> flat = m.kernel_flat();
  m.near_field = {kCotton, {0.01f, 0.05f, 0.2f, 0.9f, 2.0f, 8.0f}};
  EXPECT_EQ(m.kernel_flat(), flat);
  const nlohmann::json j = model::model_to_json(m);
  ASSERT_TRUE(j.contains("near_field"));
  EXPECT_TRUE(model::model_from_json(j, "t").near_field == m.near_field);
  nlohmann::json without = j;
  without.erase("near_field");
  EXPECT_TRUE(model::model_from_json(without, "t").near_field.empty());
  nlohmann::json through_only = j;
  through_only["near_field"].erase("axial_exit_reflected");
  EXPECT_TRUE((model::model_from_json(through_only, "t").near_field == model::NearField{kCotton, {}}));
  for (const char *key : {"axial_exit_through", "axial_exit_reflected"}) {
    for (const auto &bad : {nlohmann::json({0.1, 0.2}), nlohmann::json({0.1, 0.2, 0.3, 0.2, 0.5, 0.6}),
                            nlohmann::json({0.1, 0.2, 0.3, "x", 0.5, 0.6}), nlohmann::json("cotton")}) {
      nlohmann::json k = j;
      k["near_field"][key] = bad;
      try {
        model::model_from_json(k, "t");
        ADD_FAILURE() << "accepted " << key << " " << bad.dump();
      }
      catch (const model::ModelError &e) {
        EXPECT_NE(std::string(e.what()).find(std::string("near_field: '") + key), std::string::npos) << e.what();
      }
    }
  }
}

/* A bake takes them from its maps' gather statistics; maps from before D68 give none. */
TEST(ExitPlacement, TakenFromTheMapsStatistics)
{
  rdm::RdmMaps maps;
  EXPECT_TRUE(model::near_field_of(maps).empty());
  maps.stats.axial_exit_through = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
  maps.stats.axial_exit_reflected = {0.01, 0.02, 0.03, 0.04, 0.05, 0.06};
  const model::NearField nf = model::near_field_of(maps);
  EXPECT_EQ(nf.through, std::vector<float>({0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f}));
  EXPECT_EQ(nf.reflected, std::vector<float>({0.01f, 0.02f, 0.03f, 0.04f, 0.05f, 0.06f}));
}
