// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/bake.h"

#include <cmath>

#include "neuralyarn/io.h"
#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/r_shape.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/version.h"

namespace neuralyarn::model {

using nlohmann::json;

namespace {
const char *loss_name(train::Loss l)
{
  switch (l) {
    case train::Loss::kMse: return "mse";
    case train::Loss::kLogMse: return "log_mse";
    case train::Loss::kRelativeMse: return "relative_mse";
    case train::Loss::kPoissonMse: return "poisson_mse";
  }
  return "?";
}

train::Dataset dataset_for(const char *name, const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation,
                           int outputs)
{
  const std::string s(name);
  if (s == "T") {
    return train::sample_transmission(maps, n, seed, validation);
  }
  if (s == "R") {
    return train::sample_reflection_scale(maps, n, seed, validation, outputs);
  }
  /* An M network of six outputs is two-sided (kernel/yarn_bsdf.h, D45). */
  return train::sample_multiple_scattering(maps, n, seed, validation, outputs == 6);
}
}  // namespace

void divide_by_escape(train::Dataset *d, const train::Mlp<float> &transmission)
{
  const train::Mlp<float>::Mat P_T = transmission.forward(d->X.topRows(3));
  for (long j = 0; j < d->X.cols(); j++) {
    d->Y.col(j) /= ny::yarn_escape(P_T(0, j));
  }
}

NetworkRecord train_one(const char *name, const rdm::RdmMaps &maps, const NetworkOptions &o, ny::MlpHead head,
                        uint64_t seed, int threads, const std::function<void(double)> &progress,
                        const train::Mlp<float> *transmission)
{
  train::MlpShape shape;
  shape.widths = train::parse_widths(o.widths);
  shape.head = head;
  const int outputs = shape.widths.back();
  train::Dataset tr = dataset_for(name, maps, o.samples, seed * 1000003u + 1u, false, outputs);
  train::Dataset va = dataset_for(name, maps, std::max(1, o.samples / 10), seed * 1000003u + 2u, true, outputs);
  if (transmission) {
    /* The M network learns S_M |cos| / (1 - P_T) (kernel/yarn_bsdf.h, docs/decisions.md D15). */
    divide_by_escape(&tr, *transmission);
    divide_by_escape(&va, *transmission);
  }
  /* With an exp head, each output channel is trained on its targets divided by their mean s_c and
   * log s_c is added to the output bias afterwards (exp(z + log s) = s exp(z): exactly the same network).
   * Without it the MSE of a dim channel (fleece's red M energy is 1/10 of its blue) is ignored and that
   * channel comes out 3x too dark (docs/decisions.md D14). */
  Eigen::VectorXf scale = Eigen::VectorXf::Ones(tr.Y.rows());
  if (head == ny::kMlpHeadExp) {
    for (int c = 0; c < tr.Y.rows(); c++) {
      /* Over the targets there are (a two-sided M's rows hold NaN where the other side has them). */
      const auto has = tr.Y.row(c).array().isFinite();
      const float mean = has.count() > 0 ? has.select(tr.Y.row(c).array(), 0.0f).sum() / float(has.count()) : 0.0f;
      scale(c) = mean > 0.0f ? mean : 1.0f;
      tr.Y.row(c) /= scale(c);
      va.Y.row(c) /= scale(c);
    }
  }
  train::TrainOptions to;
  to.steps = o.steps;
  to.batch = o.batch;
  to.learning_rate = o.learning_rate;
  to.final_learning_rate_fraction = o.final_learning_rate_fraction;
  to.loss = o.loss;
  to.log_eps = o.log_eps;
  to.seed = seed;
  to.threads = threads;
  to.record_every = std::max(1, o.steps / 100);
  if (progress) {
    to.progress = [&](int step, int steps, float) { progress(double(step) / std::max(1, steps)); };
  }
  const train::TrainResult r = train::train_network(shape, tr, va, to);
  if (r.diverged) {
    throw ParameterError(std::string("network ") + name, r.message);
  }
  train::Mlp<float> net = r.net;
  if (head == ny::kMlpHeadExp) {
    train::Mlp<float>::Vec params = net.params();
    const long out0 = params.size() - scale.size(); /* the last layer's bias ends the parameter vector */
    for (int c = 0; c < scale.size(); c++) {
      params(out0 + c) += std::log(scale(c));
    }
    net.set_params(params);
  }
  NetworkRecord rec;
  rec.shape = shape;
  rec.flat = net.to_flat();
  rec.training = {{"loss", loss_name(o.loss)},
                  {"log_eps", o.log_eps},
                  {"samples", o.samples},
                  {"steps", r.steps_done},
                  {"batch", o.batch},
                  {"learning_rate", o.learning_rate},
                  {"final_learning_rate_fraction", o.final_learning_rate_fraction},
                  {"seed", seed},
                  {"target_scale", std::vector<float>(scale.data(), scale.data() + scale.size())},
                  {"initial_loss", r.initial_loss},
                  {"train_loss", r.train_loss},
                  {"validation_loss", r.validation_loss},
                  {"train_mse", r.train_mse},
                  {"validation_mse", r.validation_mse},
                  {"seconds", r.seconds}};
  return rec;
}

json maps_provenance(const rdm::RdmMaps &maps)
{
  const rdm::MapResolution &b = maps.bins;
  json j = {{"paths", maps.paths},
            {"seed", maps.seed},
            {"packing_seed", maps.packing_seed},
            {"layouts", maps.layouts},
            {"symmetrized", maps.symmetrized},
            {"bins", std::to_string(b.theta_i) + "x" + std::to_string(b.phi_i) + "x" + std::to_string(b.theta_o) + "x" +
                         std::to_string(b.phi_o)}};
  if (!maps.intersector.empty()) {
    j["intersector"] = maps.intersector; /* the yarn level's: what the same seed reproduces */
  }
  return j;
}

ProxyFitResult fit_model_proxy(YarnModel *model, const rdm::RdmMaps &maps, const ProxyFitOptions &options)
{
  const ProxyFitResult r = fit_sampling_proxy(maps, options);
  model->proxy = r.proxy;
  model->provenance["proxy_fit"] = {{"samples", options.samples},         {"seed", options.seed},
                                    {"nll", r.nll},                       {"nll_uniform", r.nll_uniform},
                                    {"evaluations", r.evaluations},       {"seconds", r.seconds}};
  return r;
}

double candidate_score(const LobeComparison &m_lobe)
{
  double sum = 0.0;
  for (double l1 : m_lobe.l1_raw) {
    sum += l1;
  }
  return m_lobe.l1_raw.empty() ? 0.0 : sum / double(m_lobe.l1_raw.size());
}

namespace {
/* The R lobe's nodes and shape table. A ply's: the free path asked for (>= 0), or 0 (the surface fiber) or
 * r_free_path(), whichever puts the fitted lobe closer to the maps in its worst theta_i bin but the grazing one
 * (raw L1): the nodes move the cone where twisted plies put it and cost untwisted ones at grazing light, which a
 * mean over the bins hides (D38). A yarn's, the same way: the surface spread asked for (> 0: the frames of
 * that share of its visible ply surface; 0: the surface fiber), or the better of the surface fiber and
 * kRSurfaceSpread (D51). Returns the candidates' scores (empty when there was no choice). */
nlohmann::json fit_r_lobe(YarnModel *m, const rdm::RdmMaps &maps, double requested_path, double requested_spread,
                          const std::function<void(double)> &progress)
{
  auto done = [&](double f) {
    if (progress) {
      progress(f);
    }
  };
  done(0.0);
  /* A candidate: its free path and surface spread (at most one of them non-zero). */
  using Candidate = std::pair<double, double>;
  auto apply = [&](const Candidate &c) {
    m->r_free_path = c.first;
    set_r_surface_spread(m, c.second);
  };
  std::vector<Candidate> candidates;
  if (m->structure.is_yarn()) {
    require_one_r_node_kind(requested_path, requested_spread);
    candidates = requested_path > 0.0      ? std::vector<Candidate>{{requested_path, 0.0}}
                 : requested_spread >= 0.0 ? std::vector<Candidate>{{0.0, requested_spread}}
                                           : std::vector<Candidate>{{0.0, 0.0}, {0.0, kRSurfaceSpread}};
  }
  else if (requested_spread > 0.0) {
    candidates = {{0.0, requested_spread}}; /* refused by r_surface_frames: a ply has no plies */
  }
  else {
    const double lambda = r_free_path(*m);
    candidates = requested_path >= 0.0 || lambda == 0.0 ? std::vector<Candidate>{{std::max(requested_path, 0.0), 0.0}}
                                                        : std::vector<Candidate>{{0.0, 0.0}, {lambda, 0.0}};
  }
  if (candidates.size() == 1) {
    apply(candidates[0]);
    m->r_shape = fit_r_shape(*m, maps);
    done(1.0);
    return nlohmann::json();
  }
  const LobeGrid map_R = pool_map_lobe(maps, Lobe::kR);
  nlohmann::json scores = nlohmann::json::array();
  double best_score = 0.0;
  Candidate best;
  RShapeTable best_shape;
  std::vector<float> best_frames;
  for (size_t k = 0; k < candidates.size(); k++) {
    apply(candidates[k]);
    /* Four quadratures of the R lobe over every incident bin, the nodes' four times the surface fiber's
     * (four nodes against one): 1, 2, 6, 10 of 10. */
    m->r_shape = fit_r_shape(*m, maps);
    done(k == 0 ? 0.1 : 0.6);
    const LobeComparison cmp = compare_lobes(model_lobe_grid(*m, maps.bins, Lobe::kR), map_R);
    done(k == 0 ? 0.2 : 1.0);
    const double score = cmp.l1_max_but_grazing; /* the goal's measure (issue 17); raw L1 without maps B */
    nlohmann::json row = {{"r_free_path", candidates[k].first}, {"r_lobe_l1_worst", score},
                          {"r_lobe_l1_mean", candidate_score(cmp)}};
    if (m->structure.is_yarn()) {
      row["r_surface_spread"] = candidates[k].second;
    }
    scores.push_back(row);
    if (k == 0 || score < best_score) {
      best_score = score;
      best = candidates[k];
      best_shape = m->r_shape;
      best_frames = m->r_frames;
    }
  }
  m->r_free_path = best.first;
  m->r_surface_spread = best.second;
  m->r_frames = std::move(best_frames); /* the geometry's, kept rather than found again */
  m->r_shape = std::move(best_shape);
  return scores;
}

/* Seed of M candidate k (0-based): candidate 0 is the single-seed model's network. */
uint64_t m_candidate_seed(uint64_t seed, int k)
{
  return seed + 2 + 100 * uint64_t(k);
}

/* Trains candidates 2..K of the M network (candidate 1 is model->M), each calibrated for its own network,
 * and keeps the one with the lowest candidate_score; every candidate's seed and score go into the
 * provenance. */
void select_m_candidate(YarnModel *model, const rdm::RdmMaps &maps, const TrainModelOptions &o,
                        const train::Mlp<float> &transmission,
                        const std::function<std::function<void(double)>(const char *)> &stage)
{
  const LobeGrid map_M = pool_map_lobe(maps, Lobe::kM);
  auto score = [&](const YarnModel &m) {
    if (o.m_candidate_score) {
      return o.m_candidate_score(m);
    }
    return candidate_score(compare_lobes(model_lobe_grid(m, maps.bins, Lobe::kM), map_M));
  };
  YarnModel best = *model;
  double best_score = score(best);
  size_t best_k = 0;
  json candidates = json::array();
  candidates.push_back({{"seed", m_candidate_seed(o.seed, 0)}, {"score", best_score}});
  for (int k = 1; k < o.m_candidates; k++) {
    const uint64_t seed = m_candidate_seed(o.seed, k);
    const std::string name = "M" + std::to_string(k + 1);
    YarnModel m = *model;
    m.M = train_one("M", maps, o.M, ny::kMlpHeadExp, seed, o.threads, stage(name.c_str()), &transmission);
    m.calibration = calibrate_energy(m, maps, o.threads);
    const double s = score(m);
    candidates.push_back({{"seed", seed}, {"score", s}});
    if (s < best_score) {
      best = std::move(m);
      best_score = s;
      best_k = size_t(k);
    }
  }
  *model = std::move(best);
  model->provenance["m_candidates"] = {{"score", o.m_candidate_score ? o.m_candidate_score_name
                                                                    : "mean over theta_i of the M lobe's relative L1 "
                                                                      "against the training maps (model/bake.h "
                                                                      "candidate_score)"},
                                       {"candidates", candidates},
                                       {"kept", best_k}};
}
}  // namespace

NearField near_field_of(const rdm::RdmMaps &maps)
{
  /* The gather's quantiles as floats, if there are `n` of them (maps before D72 / D73 have none). */
  auto quantiles = [](const std::vector<double> &q, size_t n) {
    return q.size() == n ? std::vector<float>(q.begin(), q.end()) : std::vector<float>();
  };
  const size_t offsets = size_t(ny::kExitBands) * ny::kExitQuantiles, entry = offsets * ny::kEntryRows;
  NearField nf{quantiles(maps.stats.axial_exit_through, offsets), quantiles(maps.stats.axial_exit_reflected, offsets),
               quantiles(maps.stats.entry_h_through, entry), quantiles(maps.stats.entry_h_reflected, entry)};
  if (nf.through.empty()) {
    return NearField();
  }
  if (nf.reflected.empty()) {
    nf.reflected_entry.clear(); /* an entry h needs its side's offsets */
  }
  return nf;
}

YarnModel train_model(const rdm::RdmMaps &maps, const TrainModelOptions &o)
{
  YarnModel m;
  m.preset = maps.preset;
  m.structure = maps.structure;
  auto stage = [&](const char *name) -> std::function<void(double)> {
    if (!o.progress) {
      return {};
    }
    return [&o, name](double f) { o.progress(name, f); };
  };
  /* A stage without steps of its own: its start and its end. */
  auto report = [&](const char *name, double f) {
    if (o.progress) {
      o.progress(name, f);
    }
  };
  m.T = train_one("T", maps, o.T, ny::kMlpHeadSigmoid, o.seed, o.threads, stage("T"), nullptr);
  m.R = train_one("R", maps, o.R, ny::kMlpHeadExp, o.seed + 1, o.threads, stage("R"), nullptr);
  const train::Mlp<float> transmission = train::Mlp<float>::from_flat(m.T.flat);
  m.M = train_one("M", maps, o.M, ny::kMlpHeadExp, m_candidate_seed(o.seed, 0), o.threads, stage("M"), &transmission);
  /* Mean M albedo over w_i uniform on the hemisphere (the renderer's closure-weight estimate). */
  const std::vector<double> EM = maps.energy(maps.m);
  double wsum = 0.0;
  const rdm::MapResolution &b = maps.bins;
  for (int ti = 0; ti < b.theta_i; ti++) {
    const double w = maps.incident_solid_angle(ti);
    for (int pi = 0; pi < b.phi_i; pi++) {
      for (int c = 0; c < 3; c++) {
        m.albedo_M[size_t(c)] += w * EM[maps.incident_index(ti, pi) * 3 + size_t(c)];
      }
      wsum += w;
    }
  }
  for (double &a : m.albedo_M) {
    a /= wsum;
  }
  m.near_field = near_field_of(maps);
  /* The R lobe's shape (its energy is unchanged by it; it depends on R alone), then the energies. */
  const nlohmann::json r_scores = fit_r_lobe(&m, maps, o.r_free_path, o.r_surface_spread, stage("R shape"));
  report("calibration", 0.0);
  m.calibration = calibrate_energy(m, maps, o.threads);
  report("calibration", 1.0);
  m.provenance = {{"maps", maps_provenance(maps)},
                  {"training_seed", o.seed},
                  {"created", utc_now()},
                  {"code_version", std::string(kVersion) + "+" + kGitRevision}};
  if (!r_scores.empty()) {
    m.provenance["r_free_path_scores"] = r_scores;
  }
  if (o.m_candidates > 1) {
    select_m_candidate(&m, maps, o, transmission, stage);
  }
  if (o.fit_proxy) {
    report("fit", 0.0);
    fit_model_proxy(&m, maps, o.fit);
    report("fit", 1.0);
  }
  else {
    m.proxy.kappa_R = global_kappa_R(maps);
  }
  /* Last: the fallback tables describe the finished model (networks, calibration and proxy). */
  FallbackOptions fo;
  fo.threads = o.threads;
  report("fallback tables", 0.0);
  m.fallback = compute_fallback(m, fo);
  report("fallback tables", 1.0);
  return m;
}

}  // namespace neuralyarn::model
