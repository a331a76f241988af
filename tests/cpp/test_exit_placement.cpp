// SPDX-License-Identifier: Apache-2.0
//
// The near field of a model (decisions D68, D72): the kernel's offsets drawn from the gather's signed quantiles per
// band of the light's direction (kernel/exit_placement.h), and the model file's "near_field" (model/model.h).
#include <gtest/gtest.h>

#include <algorithm>
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
/* Cotton's far side as the gather measured it (ply radii, 1 ... 99 %), light across the axis and along it. */
const std::vector<float> kAcross = {-7.51f, -3.11f, -1.63f, -0.17f, 0.05f, 0.77f, 2.41f, 3.97f, 8.37f};
const std::vector<float> kAlong = {-2.53f, -0.09f, 0.11f, 0.63f, 2.35f, 5.53f, 10.33f, 14.39f, 25.57f};
/* Five bands from across to along the axis: each band's quantiles the two's mix. */
std::vector<float> side_quantiles()
{
  std::vector<float> q;
  for (int b = 0; b < ny::kExitBands; b++) {
    const float w = float(b) / float(ny::kExitBands - 1);
    for (int k = 0; k < ny::kExitQuantiles; k++) {
      q.push_back(kAcross[size_t(k)] + w * (kAlong[size_t(k)] - kAcross[size_t(k)]));
    }
  }
  return q;
}
/* A pre-D72 model's |offset| quantiles (25 ... 99 %). */
const std::vector<float> kLegacy = {0.18f, 0.94f, 2.8f, 5.85f, 8.6f, 17.1f};
}  // namespace

/* A band's drawn offsets follow its quantiles: stratified u (10^5 strata), the empirical CDF at each quantile is its
 * level up to one stratum per segment; the ends stay within the extrapolated knots. */
TEST(ExitPlacement, OffsetsFollowTheQuantiles)
{
  float knots[ny::kExitKnots];
  ny::exit_knots(kAlong.data(), knots);
  EXPECT_FLOAT_EQ(knots[0], -2.53f - (-0.09f + 2.53f));
  EXPECT_FLOAT_EQ(knots[ny::kExitKnots - 1], 25.57f + (25.57f - 14.39f));
  const int n = 100000;
  std::vector<int> below(ny::kExitQuantiles, 0);
  for (int i = 0; i < n; i++) {
    const float s = ny::exit_band_offset(knots, (float(i) + 0.5f) / float(n));
    EXPECT_GE(s, knots[0]);
    EXPECT_LE(s, knots[ny::kExitKnots - 1]);
    for (int k = 0; k < ny::kExitQuantiles; k++) {
      below[size_t(k)] += s <= kAlong[size_t(k)];
    }
  }
  for (int k = 0; k < ny::kExitQuantiles; k++) {
    EXPECT_NEAR(double(below[size_t(k)]) / n, double(ny::exit_knot_level(k + 1)), 3.0 / n) << "level " << k;
  }
  EXPECT_FLOAT_EQ(ny::exit_band_offset(knots, 0.5f), 2.35f);
  EXPECT_FLOAT_EQ(ny::exit_band_offset(knots, 0.0f), knots[0]);
  EXPECT_FLOAT_EQ(ny::exit_band_offset(knots, 1.0f), knots[ny::kExitKnots - 1]);
}

/* The offset follows the direction: a band's own quantiles at its centre, linear between two centres, the end bands
 * beyond theirs, and turned toward where the path goes along the axis (the sign of its cosine). */
TEST(ExitPlacement, OffsetsFollowTheDirection)
{
  const std::vector<float> q = side_quantiles();
  float knots[ny::kExitSideSize];
  ny::exit_side_knots(q.data(), knots);
  for (const float u : {0.003f, 0.2f, 0.5f, 0.77f, 0.999f}) {
    for (int b = 0; b < ny::kExitBands; b++) {
      const float centre = (float(b) + 0.5f) / float(ny::kExitBands);
      const float own = ny::exit_band_offset(knots + b * ny::kExitKnots, u);
      EXPECT_NEAR(ny::exit_sample_offset(knots, centre, u), own, 1e-4f) << "band " << b << " u " << u;
      EXPECT_NEAR(ny::exit_sample_offset(knots, -centre, u), -own, 1e-4f) << "band " << b << " u " << u;
      if (b + 1 < ny::kExitBands) {
        const float next = ny::exit_band_offset(knots + (b + 1) * ny::kExitKnots, u);
        EXPECT_NEAR(ny::exit_sample_offset(knots, centre + 0.5f / float(ny::kExitBands), u), 0.5f * (own + next),
                    1e-4f);
      }
    }
    EXPECT_NEAR(ny::exit_sample_offset(knots, 0.0f, u), ny::exit_band_offset(knots, u), 1e-4f);
    EXPECT_NEAR(ny::exit_sample_offset(knots, 1.0f, u),
                ny::exit_band_offset(knots + (ny::kExitBands - 1) * ny::kExitKnots, u), 1e-4f);
  }
  /* Light along the axis: most paths start toward the light (this band: ~93 % positive). */
  int toward = 0;
  const int n = 1000;
  for (int i = 0; i < n; i++) {
    toward += ny::exit_sample_offset(knots, -0.95f, (float(i) + 0.5f) / float(n)) < 0.0f;
  }
  EXPECT_GT(toward, 900);
}

TEST(ExitPlacement, QuantileCheckNamesWhatIsWrong)
{
  EXPECT_EQ(ny::exit_quantiles_check(kAlong.data(), 9), nullptr);
  EXPECT_EQ(ny::exit_quantiles_check(kAcross.data(), 9), nullptr); /* negative offsets are offsets */
  std::vector<float> q = kAlong;
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 8), nullptr);
  q[2] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 9), nullptr);
  q = kAlong;
  q[3] = 0.0f; /* below the 10 % one */
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 9), nullptr);
  q = kAlong;
  q[8] = 2000.0f;
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 9), nullptr);
  q = kAlong;
  q[0] = -2000.0f;
  EXPECT_NE(ny::exit_quantiles_check(q.data(), 9), nullptr);
}

/* A pre-D72 model's unsigned quantiles become a symmetric signed distribution with the same |offset| at the levels
 * both describe (50 % and 90 % of |offset|: the signed 75 % and 95 %). */
TEST(ExitPlacement, ModelsFromBeforeD72AreConverted)
{
  float q[ny::kExitQuantiles];
  ny::exit_quantiles_from_magnitudes(kLegacy.data(), q);
  EXPECT_EQ(ny::exit_quantiles_check(q, ny::kExitQuantiles), nullptr);
  for (int k = 0; k < ny::kExitQuantiles; k++) {
    EXPECT_FLOAT_EQ(q[k], -q[ny::kExitQuantiles - 1 - k]) << k;
  }
  EXPECT_EQ(q[4], 0.0f);
  EXPECT_FLOAT_EQ(q[5], 0.94f);
  EXPECT_FLOAT_EQ(q[7], 5.85f);
}

/* The model file carries them outside its kernel array (which the fallback tables name): written, read back
 * unchanged, the array the same with or without; bad values are refused with the key's name; the entry side's are
 * optional (files from before they were measured); a pre-D72 file is read converted. */
TEST(ExitPlacement, ModelFileRoundTripAndRejection)
{
  model::YarnModel m = synthetic_model("cotton", 7);
  const std::vector<float> flat = m.kernel_flat();
  std::vector<float> reflected = side_quantiles();
  for (float &v : reflected) {
    v *= 0.25f;
  }
  m.near_field = {side_quantiles(), reflected};
  EXPECT_EQ(m.kernel_flat(), flat);
  const nlohmann::json j = model::model_to_json(m);
  ASSERT_TRUE(j.contains("near_field"));
  EXPECT_TRUE(model::model_from_json(j, "t").near_field == m.near_field);
  nlohmann::json without = j;
  without.erase("near_field");
  EXPECT_TRUE(model::model_from_json(without, "t").near_field.empty());
  nlohmann::json through_only = j;
  through_only["near_field"].erase("reflected_bands");
  EXPECT_TRUE((model::model_from_json(through_only, "t").near_field == model::NearField{side_quantiles(), {}}));
  nlohmann::json legacy = j;
  legacy["near_field"] = {{"axial_exit_through", kLegacy}};
  const model::NearField converted = model::model_from_json(legacy, "t").near_field;
  ASSERT_EQ(converted.through.size(), size_t(ny::kExitBands * ny::kExitQuantiles));
  float q[ny::kExitQuantiles];
  ny::exit_quantiles_from_magnitudes(kLegacy.data(), q);
  for (int b = 0; b < ny::kExitBands; b++) {
    EXPECT_EQ(std::vector<float>(converted.through.begin() + b * 9, converted.through.begin() + b * 9 + 9),
              std::vector<float>(q, q + 9));
  }
  EXPECT_TRUE(converted.reflected.empty());
  const nlohmann::json band = std::vector<float>(kAlong);
  for (const char *key : {"through_bands", "reflected_bands"}) {
    nlohmann::json decreasing = band;
    decreasing[3] = -1.0;
    nlohmann::json text = band;
    text[2] = "x";
    for (const auto &bad : {nlohmann::json::array({band, band}), nlohmann::json::array({band, band, band, band, decreasing}),
                            nlohmann::json::array({band, text, band, band, band}),
                            nlohmann::json::array({band, band, band, band, {0.1, 0.2}}), nlohmann::json("cotton")}) {
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
  nlohmann::json none = j;
  none["near_field"] = nlohmann::json::object({{"reflected_bands", j["near_field"]["reflected_bands"]}});
  EXPECT_THROW(model::model_from_json(none, "t"), model::ModelError);
}

/* A bake takes them from its maps' gather statistics; maps from before D72 give none. */
TEST(ExitPlacement, TakenFromTheMapsStatistics)
{
  rdm::RdmMaps maps;
  EXPECT_TRUE(model::near_field_of(maps).empty());
  const std::vector<float> q = side_quantiles();
  maps.stats.axial_exit_through.assign(q.begin(), q.end());
  maps.stats.axial_exit_reflected.assign(q.begin(), q.end());
  maps.stats.axial_exit_reflected[0] = -9.0;
  const model::NearField nf = model::near_field_of(maps);
  EXPECT_EQ(nf.through, q);
  EXPECT_EQ(nf.reflected[0], -9.0f);
  maps.stats.axial_exit_through = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6}; /* D68's pooled form */
  EXPECT_TRUE(model::near_field_of(maps).empty());
}

namespace {
/* An entry h table (D73): per band and row, nine quantiles about the row's centre c, spread s (clamped to the width):
 * the far side's light across the axis spreads wide, the entry side's stays near where it leaves. */
std::vector<float> entry_quantiles(float spread)
{
  const float z[ny::kExitQuantiles] = {-2.33f, -1.64f, -1.28f, -0.67f, 0.0f, 0.67f, 1.28f, 1.64f, 2.33f};
  std::vector<float> q;
  for (int b = 0; b < ny::kExitBands; b++) {
    for (int r = 0; r < ny::kEntryRows; r++) {
      const float c = -0.9f + 0.2f * float(r) * (1.0f - 0.1f * float(b));
      for (int k = 0; k < ny::kExitQuantiles; k++) {
        q.push_back(std::clamp(c + spread * z[k], -1.0f, 1.0f));
      }
    }
  }
  return q;
}
}  // namespace

/* The entry's h drawn in the kernel (D73) follows a row's quantiles, moves with the hit point's h and the direction's
 * band linearly between their centres, stays on the width, and survives a NaN. */
TEST(ExitPlacement, EntryFollowsTheRowsAndBands)
{
  const std::vector<float> q = entry_quantiles(0.1f);
  std::vector<float> knots(ny::kEntrySideSize);
  ny::entry_side_knots(q.data(), knots.data());
  /* Band 0's centre (|cos| 0.1) and row 3's centre (h -0.3): that row's quantile function, level by level. */
  for (int k = 1; k <= ny::kExitQuantiles; k++) {
    EXPECT_NEAR(ny::entry_sample_h(knots.data(), 0.1f, -0.3f, ny::exit_knot_level(k)), q[size_t(3 * 9 + k - 1)], 1e-5f);
  }
  /* Half-way between rows 3 and 4 (h -0.2), and between bands 0 and 1 (|cos| 0.2), at the median: the mean of the
   * two rows' (bands') medians; the cosine's sign does not matter. */
  EXPECT_NEAR(ny::entry_sample_h(knots.data(), 0.1f, -0.2f, 0.5f), 0.5f * (q[3 * 9 + 4] + q[4 * 9 + 4]), 1e-5f);
  const size_t band1 = size_t(ny::kEntryRows * 9);
  EXPECT_NEAR(ny::entry_sample_h(knots.data(), -0.2f, -0.3f, 0.5f), 0.5f * (q[3 * 9 + 4] + q[band1 + 3 * 9 + 4]), 1e-5f);
  /* Beyond the outer rows' and bands' centres: theirs. */
  EXPECT_FLOAT_EQ(ny::entry_sample_h(knots.data(), 1.0f, 1.0f, 0.5f), q[q.size() - 5]);
  EXPECT_FLOAT_EQ(ny::entry_sample_h(knots.data(), 0.0f, -1.0f, 0.5f), q[4]);
  /* On the width for every level, the extrapolated ends included; NaN lands in the first band and row. */
  const std::vector<float> wide = entry_quantiles(0.6f);
  ny::entry_side_knots(wide.data(), knots.data());
  for (int i = 0; i <= 1000; i++) {
    const float h = ny::entry_sample_h(knots.data(), 0.5f, 0.95f, float(i) / 1000.0f);
    ASSERT_GE(h, -1.0f);
    ASSERT_LE(h, 1.0f);
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FLOAT_EQ(ny::entry_sample_h(knots.data(), nan, nan, 0.5f), wide[4]);
}

/* A model file's entry h: read and written with its side, refused by key when malformed or without its side's
 * offsets; the kernel's block of a side holds it after the offsets' knots, its size telling whether it is there. */
TEST(ExitPlacement, EntryInTheModelFileAndTheKernelBlock)
{
  model::YarnModel m = synthetic_model("cotton", 7);
  const std::vector<float> e = entry_quantiles(0.2f);
  m.near_field = model::NearField{side_quantiles(), side_quantiles(), e, e};
  nlohmann::json j = model::model_to_json(m);
  EXPECT_TRUE(model::model_from_json(j, "t").near_field == m.near_field);
  float block[1 + ny::kExitSideSizeWithEntry];
  const char *key = nullptr, *problem = nullptr;
  ASSERT_EQ(ny::exit_side_block_from_json(j["near_field"], true, block, &key, &problem), 1 + ny::kExitSideSizeWithEntry);
  EXPECT_EQ(block[0], float(ny::kExitSideSizeWithEntry));
  std::vector<float> knots(ny::kEntrySideSize);
  ny::entry_side_knots(e.data(), knots.data());
  EXPECT_EQ(std::vector<float>(block + 1 + ny::kExitSideSize, block + 1 + ny::kExitSideSizeWithEntry), knots);
  nlohmann::json before = j; /* a model from before D73: the offsets alone */
  before["near_field"].erase("through_entry");
  ASSERT_EQ(ny::exit_side_block_from_json(before["near_field"], true, block, &key, &problem), 1 + ny::kExitSideSize);
  EXPECT_EQ(block[0], float(ny::kExitSideSize));
  EXPECT_TRUE(model::model_from_json(before, "t").near_field.through_entry.empty());
  nlohmann::json no_side = j; /* an entry side without its offsets: refused (its h would move nothing along) */
  no_side["near_field"].erase("reflected_bands");
  EXPECT_EQ(ny::exit_side_block_from_json(no_side["near_field"], false, block, &key, &problem), -1);
  EXPECT_STREQ(key, "reflected_entry");
  EXPECT_THROW(model::model_from_json(no_side, "t"), model::ModelError);
  const nlohmann::json row = std::vector<float>(e.begin(), e.begin() + 9);
  nlohmann::json wide = row, decreasing = row, text = row;
  wide[8] = 1.5;
  decreasing[8] = -1.0;
  text[0] = "x";
  const nlohmann::json rows = nlohmann::json::array({row, row, row, row, row, row, row, row, row, row});
  auto band_with = [&](const nlohmann::json &bad_row) {
    nlohmann::json r = rows;
    r[9] = bad_row;
    return nlohmann::json::array({rows, rows, rows, rows, r});
  };
  for (const char *k : {"through_entry", "reflected_entry"}) {
    for (const auto &bad : {band_with(wide), band_with(decreasing), band_with(text), band_with({0.1, 0.2}),
                            nlohmann::json::array({rows, rows}), nlohmann::json::array({rows, rows, rows, rows, row}),
                            nlohmann::json("cotton")}) {
      nlohmann::json b = j;
      b["near_field"][k] = bad;
      try {
        model::model_from_json(b, "t");
        ADD_FAILURE() << "accepted " << k << " " << bad.dump();
      }
      catch (const model::ModelError &err) {
        EXPECT_NE(std::string(err.what()).find(std::string("near_field: '") + k), std::string::npos) << err.what();
      }
      EXPECT_EQ(ny::exit_side_block_from_json(b["near_field"], k[0] == 't', block, &key, &problem), -1) << bad.dump();
    }
  }
}

/* A bake takes the entry h from its maps with the offsets; maps from before D73 give the offsets alone. */
TEST(ExitPlacement, EntryTakenFromTheMapsStatistics)
{
  rdm::RdmMaps maps;
  const std::vector<float> q = side_quantiles(), e = entry_quantiles(0.2f);
  maps.stats.axial_exit_through.assign(q.begin(), q.end());
  maps.stats.axial_exit_reflected.assign(q.begin(), q.end());
  EXPECT_TRUE(model::near_field_of(maps).through_entry.empty());
  maps.stats.entry_h_through.assign(e.begin(), e.end());
  maps.stats.entry_h_reflected.assign(e.begin(), e.end());
  const model::NearField nf = model::near_field_of(maps);
  EXPECT_EQ(nf.through_entry, e);
  EXPECT_EQ(nf.reflected_entry, e);
}
