// SPDX-License-Identifier: Apache-2.0
//
// From maps to a model: train the T, R and M networks, fit the sampling proxy, record where it all came
// from. `neuralyarn train`, `fit` and `bake` are thin wrappers around these functions.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/model/proxy_fit.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/train/trainer.h"

namespace neuralyarn::model {

struct NetworkOptions {
  std::string widths;
  int samples = 0;     /* training samples drawn from the maps (validation: a tenth of that) */
  int steps = 0;
  int batch = 0;
  float learning_rate = 0.0f;
  float final_learning_rate_fraction = 0.1f;
  train::Loss loss = train::Loss::kMse;
  float log_eps = 1e-3f;
};

/* Defaults measured in docs/benchmarks.md ("Training"). */
struct TrainModelOptions {
  NetworkOptions T{"3-7-7-1", 200000, 10000, 2048, 2e-2f, 0.05f, train::Loss::kMse, 1e-3f};
  /* R: RGB, the energy's colour its own rather than the fiber's C_R (docs/decisions.md D65). */
  NetworkOptions R{"3-7-7-3", 200000, 10000, 2048, 2e-2f, 0.05f, train::Loss::kLogMse, 1e-2f};
  /* M: the relative loss (docs/decisions.md D19): with MSE the network ignored everything a decade below
   * the reflection peak, which is where the transmitted light is (0.03-0.5x of the maps through the ply).
   * 6-H-H-6 makes it two-sided, one RGB output per hemisphere of exits (kernel/yarn_bsdf.h, D45). */
  NetworkOptions M{"6-21-21-3", 2000000, 20000, 4096, 1e-2f, 0.05f, train::Loss::kRelativeMse, 1e-3f};
  uint64_t seed = 1;
  /* M networks trained from different seeds (weights, samples, mini-batches; candidate k from seed + 2 +
   * 100 (k - 1), so the first is the single-seed model); the model keeps the one whose lobe is closest to
   * the training maps (candidate_score). One by default: that choice does not pick the network that renders
   * closer to independent maps (docs/decisions.md D33). */
  int m_candidates = 1;
  /* The candidates' score, lower is better, and what it is (the model's provenance names it); unset: the 4D M
   * lobe's L1 (candidate_score). The tools set the close-up's image fit against the maps (`--m-choice image`,
   * docs/decisions.md D53), which lives in scenes/, above this library's layer. */
  std::function<double(const YarnModel &)> m_candidate_score;
  std::string m_candidate_score_name;
  /* The R lobe's free path (ply radii); negative: 0 or r_free_path() of the model (model/r_shape.h),
   * whichever fits the R map better (docs/decisions.md D38). */
  double r_free_path = -1.0;
  /* A yarn-level model's R nodes: the fibers of this share of its visible ply surface (0: the surface fiber
   * alone); negative: 0 or kRSurfaceSpread, whichever fits the R map better (docs/decisions.md D51). */
  double r_surface_spread = -1.0;
  int threads = 0;
  ProxyFitOptions fit;
  bool fit_proxy = true;
  /* Progress: stage name ("T", "R", "M", "M2" ..., "R shape", "calibration", "fit", "fallback tables") and the
   * fraction done within it. */
  std::function<void(const std::string &stage, double fraction)> progress;
};

/* Trains one network of the model ("T", "R" or "M") on its dataset; for M, `transmission` is the trained
 * T network whose escape factor 1 - P_T divides the targets. Throws ParameterError if it diverges (the
 * message says so and the model is not written). */
NetworkRecord train_one(const char *name, const rdm::RdmMaps &maps, const NetworkOptions &options, ny::MlpHead head,
                        uint64_t seed, int threads, const std::function<void(double)> &progress,
                        const train::Mlp<float> *transmission);

/* How close a calibrated model's M lobe is to the maps it was trained on: the mean over the theta_i bins of
 * the lobe's energy-weighted relative L1 (model/lobe_fidelity.h, raw: the maps' noise is the same for
 * every candidate, so it does not reorder them). Lower is better. */
double candidate_score(const LobeComparison &m_lobe);

/* A model's near field (YarnModel::near_field, decisions D68) from the maps' gather statistics; empty for maps
 * written before those were measured. */
NearField near_field_of(const rdm::RdmMaps &maps);

/* The whole model from maps. */
YarnModel train_model(const rdm::RdmMaps &maps, const TrainModelOptions &options);

/* Re-fits the sampling proxy of `model` on `maps` (which must be of the same preset). */
ProxyFitResult fit_model_proxy(YarnModel *model, const rdm::RdmMaps &maps, const ProxyFitOptions &options);

/* Provenance of the maps, for the model file. */
nlohmann::json maps_provenance(const rdm::RdmMaps &maps);

}  // namespace neuralyarn::model
