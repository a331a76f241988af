// SPDX-License-Identifier: Apache-2.0
//
// Several M trainings, the best kept (model/bake.h TrainModelOptions::m_candidates): the kept model is the
// candidate with the lowest score, carries the calibration computed for its own network, and is never
// worse than the single-seed model it replaces (candidate 1 is that model).
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "neuralyarn/model/bake.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/train/mlp.h"

using namespace neuralyarn;

namespace {
/* Small maps and short trainings: the candidates differ from one another, which is all the test needs. */
model::TrainModelOptions small_training(int candidates)
{
  model::TrainModelOptions o;
  for (model::NetworkOptions *n : {&o.T, &o.R, &o.M}) {
    n->steps = 200;
    n->samples = 20000;
    n->batch = 1024;
  }
  o.fit_proxy = false; /* the proxy is fitted to the maps, not the networks */
  o.m_candidates = candidates;
  return o;
}

/* Silk's maps at a coarse resolution, seeded. */
rdm::RdmMaps small_silk_maps(uint64_t paths)
{
  rdm::GatherOptions g;
  g.paths = paths;
  g.seed = 7;
  g.bins = {6, 24, 12, 24};
  return rdm::gather(find_preset("silk"), g);
}

double score(const model::YarnModel &m, const rdm::RdmMaps &maps, const model::LobeGrid &map_M)
{
  return model::candidate_score(model::compare_lobes(model::model_lobe_grid(m, maps.bins, model::Lobe::kM), map_M));
}
}  // namespace

TEST(MCandidates, KeepsTheBestCalibratedForItself)
{
  const rdm::RdmMaps maps = small_silk_maps(300000);
  const model::LobeGrid map_M = model::pool_map_lobe(maps, model::Lobe::kM);

  const model::TrainModelOptions o1 = small_training(1), o4 = small_training(4);
  const model::YarnModel one = model::train_model(maps, o1);
  const model::YarnModel best = model::train_model(maps, o4);
  EXPECT_FALSE(one.provenance.contains("m_candidates"));
  ASSERT_TRUE(best.provenance.contains("m_candidates"));
  const auto &c = best.provenance["m_candidates"]["candidates"];
  ASSERT_EQ(c.size(), 4u);
  /* T and R are shared: only M (with its calibration and fallback tables) differs from the single seed. */
  EXPECT_EQ(best.T.flat, one.T.flat);
  EXPECT_EQ(best.R.flat, one.R.flat);

  /* Each candidate built here independently (seed + 2 + 100 k, calibrated for its own network): the
   * recorded scores are theirs, the kept one is the lowest, and the model is that candidate. */
  const train::Mlp<float> transmission = train::Mlp<float>::from_flat(one.T.flat);
  std::vector<model::YarnModel> candidates;
  std::vector<double> scores;
  for (size_t k = 0; k < 4; k++) {
    model::YarnModel m = one;
    const uint64_t seed = o4.seed + 2 + 100 * k;
    m.M = model::train_one("M", maps, o4.M, ny::kMlpHeadExp, seed, 0, {}, &transmission);
    m.calibration = model::calibrate_energy(m, maps, 0);
    const double s = score(m, maps, map_M);
    std::printf("candidate %zu, seed %llu: score %.4f (recorded %.4f)\n", k + 1, (unsigned long long)seed, s,
                c[k]["score"].get<double>());
    EXPECT_EQ(c[k]["seed"].get<uint64_t>(), seed);
    EXPECT_NEAR(c[k]["score"].get<double>(), s, 1e-9);
    candidates.push_back(std::move(m));
    scores.push_back(s);
  }
  const size_t lowest = size_t(std::min_element(scores.begin(), scores.end()) - scores.begin());
  EXPECT_EQ(candidates[0].M.flat, one.M.flat) << "candidate 1 is the single-seed model";
  EXPECT_EQ(best.provenance["m_candidates"]["kept"].get<size_t>(), lowest);
  EXPECT_EQ(best.M.flat, candidates[lowest].M.flat);
  EXPECT_EQ(best.calibration.values, candidates[lowest].calibration.values)
      << "the kept network carries another one's calibration";
  EXPECT_LE(score(best, maps, map_M), scores[0]);
}

TEST(MCandidates, AnotherScoreChoosesAndIsNamed)
{
  /* The tools' --m-choice image scores candidates by their close-up images (scenes/, D53) through
   * TrainModelOptions::m_candidate_score: whatever that score prefers is kept, and the provenance names it. Here
   * a score that prefers the last candidate (by its seed's network: each candidate is told apart by its M). */
  const rdm::RdmMaps maps = small_silk_maps(100000);
  model::TrainModelOptions o = small_training(3);
  std::vector<std::vector<float>> seen;
  o.m_candidate_score = [&seen](const model::YarnModel &m) {
    seen.push_back(m.M.flat);
    return -double(seen.size()); /* later candidates score lower */
  };
  o.m_candidate_score_name = "the test's";
  const model::YarnModel m = model::train_model(maps, o);
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(m.provenance["m_candidates"]["kept"].get<size_t>(), 2u);
  EXPECT_EQ(m.provenance["m_candidates"]["score"].get<std::string>(), "the test's");
  EXPECT_EQ(m.M.flat, seen[2]);
  EXPECT_NE(seen[0], seen[2]);
}
