// SPDX-License-Identifier: Apache-2.0
//
// The shipped models (models/<preset>.json) against fresh, independent maps of their preset: gathered here
// with another path seed, the paper's incident resolution (22 x 90, so that comparing at bin centres adds
// no discretisation error: 6 x 24 bins gave P_T rms 0.05 from the bin width alone) and coarse outgoing bins,
// so the check measures the model, not the noise it was trained on.
//
// Noise floor: 3e6 paths over 1980 incident bins is ~1500 paths per bin, a per-bin albedo standard error of
// 1-3 % (dark channels more), which the solid-angle mean of |error| keeps. Measured with the calibrated
// models (docs/benchmarks.md, "Model fidelity"): fleece 2.2 %, silk 3.2 %, polyester 1.4 %, cotton 0.8 %,
// gabardine 2.7 % (abs. <= 0.0083), P_T rms <= 0.0091. The limits (5 %, 0.015, 0.02) sit above that
// floor; the uncalibrated networks gave 8.7-23.9 % (all but polyester) and a wrong convention, swapped
// channels or a broken network 30-100 %.
#include <gtest/gtest.h>

#include <ostream>

#include "neuralyarn/model/fidelity.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"

using namespace neuralyarn;

struct Limits {
  const char *preset;
  double albedo_rel, albedo_abs;
};
std::ostream &operator<<(std::ostream &os, const Limits &l) { return os << l.preset; }

class ShippedModel : public ::testing::TestWithParam<Limits> {};

TEST_P(ShippedModel, MatchesFreshMapsOfItsPreset)
{
  const Limits lim = GetParam();
  const model::YarnModel m = model::load_model(model::builtin_model_path(lim.preset));
  EXPECT_EQ(preset_to_json(m.preset), preset_to_json(find_preset(lim.preset)))
      << "the shipped model was trained for other parameters than the built-in preset";
  rdm::GatherOptions o;
  o.paths = 3000000;
  o.seed = 77; /* the bake used seed 1, its check seed 1001 */
  /* The model's own fiber cross-sections (D42: 32 since the re-bake), so that the maps differ by path noise. */
  ASSERT_TRUE(m.provenance.contains("maps"));
  o.packing_seed = m.provenance["maps"].value("packing_seed", uint64_t(1));
  o.layouts = m.provenance["maps"].value("layouts", 1);
  o.bins = {22, 90, 12, 24};
  const rdm::RdmMaps maps = rdm::gather(m.preset, o);
  model::FidelityOptions fo;
  fo.variance_directions = 24;
  fo.variance_samples = 2048;
  const model::FidelityReport r = model::check_model(m, maps, fo);
  RecordProperty("albedo_mae_rel", std::to_string(r.albedo_mae_rel));
  std::printf("%-10s albedo mean rel. error %.4f (abs %.4f), P_T rms %.4f, R energy %.4f, M energy %.4f, "
              "variance importance %.3f vs uniform %.3f\n",
              lim.preset, r.albedo_mae_rel, r.albedo_mae, r.T_rmse, r.R_energy_mae_rel, r.M_energy_mae_rel,
              r.rel_var_importance, r.rel_var_uniform);
  EXPECT_LT(r.albedo_mae_rel, lim.albedo_rel);
  EXPECT_LT(r.albedo_mae, lim.albedo_abs);
  EXPECT_LT(r.R_energy_mae_rel, 0.15);
  EXPECT_LT(r.T_rmse, 0.02);
  /* The fitted sampler must beat uniform sphere sampling, and the fit must beat the uniform density. */
  EXPECT_LT(r.rel_var_importance, r.rel_var_uniform);
  ASSERT_TRUE(m.provenance.contains("proxy_fit"));
  EXPECT_LT(m.provenance["proxy_fit"]["nll"].get<double>(), m.provenance["proxy_fit"]["nll_uniform"].get<double>());
}

INSTANTIATE_TEST_SUITE_P(Presets, ShippedModel,
                         ::testing::Values(Limits{"fleece", 0.05, 0.015}, Limits{"silk", 0.05, 0.015},
                                           Limits{"polyester", 0.05, 0.015}, Limits{"cotton", 0.05, 0.015},
                                           Limits{"gabardine", 0.05, 0.015}),
                         [](const ::testing::TestParamInfo<Limits> &i) { return std::string(i.param.preset); });
