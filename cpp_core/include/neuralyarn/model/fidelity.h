// SPDX-License-Identifier: Apache-2.0
//
// How well a model reproduces the maps it was trained on (issue 4, item 7), and how well its sampler
// works. `neuralyarn check` prints these numbers; bake stores them in the model.
//
// Per incident bin (at its centre direction; the map holds the bin average):
//   albedo  = P_T + E_R + integral of S_M |cos| over the sphere     vs the map's exit energy
//   E_R     = rho_R F / 2 (exact for the analytic lobe)             vs the R map's energy
//   E_M     = sum over the map's outgoing bins of MLP_M * solid angle vs the M map's energy
// averaged over incident bins weighted by solid angle (w_i uniform on the hemisphere), channel by channel.
//
// Sampling efficiency: the relative variance Var[X] / E[X]^2 of one-sample estimates X of the non-delta
// albedo, X = eval / pdf with the model's sampler versus X = 4 pi eval with uniform sphere sampling,
// averaged over incident directions (the paper's "importance vs uniform" figure as a number), and the same
// with kappa_R chosen per w_i as E_R / (E_R + E_M) instead of the global constant.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::model {

/* Channel k (0 red, 1 green, 2 blue) of a kernel colour. */
inline double channel(const ny::Rgb &c, int k) { return k == 0 ? c.r : (k == 1 ? c.g : c.b); }

struct FidelityOptions {
  int variance_directions = 64;
  int variance_samples = 4096;
  uint64_t seed = 5;
};

struct FidelityReport {
  double albedo_mae = 0, albedo_mae_rel = 0, albedo_max_rel = 0; /* model vs map exit energy */
  double T_rmse = 0;                                               /* P_T model vs map        */
  double R_energy_mae_rel = 0, M_energy_mae_rel = 0;
  double rel_var_importance = 0, rel_var_uniform = 0, rel_var_per_wi_kappa_R = 0;
  /* Per theta_i bin of the maps (averaged over phi_i): relative albedo, M energy and R energy errors. */
  std::vector<double> albedo_rel_by_theta, M_rel_by_theta, R_rel_by_theta;
  /* The lobes' 4D shape against the maps (model/lobe_fidelity.h), with the noise removed when a second,
   * independent map was given. */
  LobeFidelity lobes;
  double seconds = 0;
  nlohmann::json to_json() const;
};

/* Energies and albedo against `maps`; the lobes against `maps` and, if given, `maps_b`, an independent
 * gather of the same ply (then the energies are checked against the mean of both). */
FidelityReport check_model(const YarnModel &model, const rdm::RdmMaps &maps, const FidelityOptions &options = {},
                           const rdm::RdmMaps *maps_b = nullptr);

}  // namespace neuralyarn::model
