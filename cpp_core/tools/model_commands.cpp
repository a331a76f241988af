// SPDX-License-Identifier: Apache-2.0
#include "model_commands.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "cli_common.h"
#include "neuralyarn/io.h"
#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/bake.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/fidelity.h"
#include "neuralyarn/model/forward_peak.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/model/r_shape.h"
#include "neuralyarn/plots.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/scenes/closeup_prediction.h"
#include "neuralyarn/units.h"
#include "neuralyarn/version.h"

namespace neuralyarn::cli {

namespace {

using model::NetworkOptions;
using model::TrainModelOptions;

/* What maps from before decisions D72 lack, for a model's near field (train, fit and near-field say it). */
std::string no_signed_offsets(const std::string &maps)
{
  return "'" + maps + "' records no signed exit offsets per band (gathered before decisions D72)";
}

void add_network_options(CLI::App *cmd, const char *name, NetworkOptions *o)
{
  const std::string p = std::string("--") + name + "-";
  cmd->add_option(p + "widths", o->widths, std::string("Layer widths of the ") + name + " network")
      ->capture_default_str();
  cmd->add_option(p + "samples", o->samples, "Training samples drawn from the maps")
      ->check(CLI::Range(1, 100000000))
      ->capture_default_str();
  cmd->add_option(p + "steps", o->steps, "Adam steps")->check(CLI::Range(0, 10000000))->capture_default_str();
  cmd->add_option(p + "batch", o->batch, "Mini-batch size (0: full batch)")
      ->check(CLI::Range(0, 100000000))
      ->capture_default_str();
  cmd->add_option(p + "lr", o->learning_rate, "Initial learning rate")
      ->check(finite_range(1e-7, 1.0))
      ->capture_default_str();
  cmd->add_option(p + "lr-final", o->final_learning_rate_fraction, "Final learning rate as a fraction of the initial")
      ->check(finite_range(1e-6, 1.0))
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         p + "loss",
         [o](const std::string &s) {
           o->loss = s == "log"       ? train::Loss::kLogMse
                     : s == "rel"     ? train::Loss::kRelativeMse
                     : s == "poisson" ? train::Loss::kPoissonMse
                                      : train::Loss::kMse;
         },
         "Loss: mse (the paper's), log (MSE of log(y + eps)), rel (relative MSE (y - t)^2 / (y^2 + eps)) or "
         "poisson ((y - t)^2 / (y + eps)); targets scaled to mean 1")
      ->check(CLI::IsMember({"mse", "log", "rel", "poisson"}));
  cmd->add_option(p + "log-eps", o->log_eps, "Offset of the log and relative losses")->check(finite_range(1e-9, 1.0))->capture_default_str();
}

void add_train_options(CLI::App *cmd, TrainModelOptions *o)
{
  add_network_options(cmd, "t", &o->T);
  add_network_options(cmd, "r", &o->R);
  add_network_options(cmd, "m", &o->M);
  cmd->add_option("--train-seed", o->seed, "Seed of weights, training samples and mini-batches")->capture_default_str();
  /* One M network unless asked: keeping the best of several by their fit to the training maps does not pick
   * the one that renders closer to independent maps (docs/decisions.md D33); the option is the tool that
   * measured it. */
  cmd->add_option("--m-candidates", o->m_candidates,
                  "M networks to train from different seeds; the model keeps the one closest to the training maps "
                  "(--m-choice: in 4D or in the close-up's images)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  cmd->add_option("--r-free-path", o->r_free_path,
                  "The R lobe's mean free path to its fiber in ply radii (0: the surface fiber alone); default: "
                  "0 or 0.6 x pi / (2 sqrt(N rho)), whichever fits the R map better (0 for a yarn-level model)")
      ->check(finite_range(0.0, ny::kYarnMaxFreePath));
  cmd->add_option("--r-surface-spread", o->r_surface_spread,
                  "A yarn-level model's R nodes: the fibers of this central share of its visible ply surface (0: the "
                  "surface fiber alone); default: 0 or 0.6, whichever fits the R map better (docs/decisions.md D51)")
      ->check(finite_range(0.0, 1.0));
  cmd->add_option("--fit-samples", o->fit.samples, "M exits drawn for the proxy fit")
      ->check(CLI::Range(100, 100000000))
      ->capture_default_str();
}

void print_network(const char *name, const model::NetworkRecord &n)
{
  const auto &t = n.training;
  std::printf("network %s %-12s %s loss: train %.4g, validation %.4g (mse %.4g), %d steps in %.1f s\n", name,
              train::format_widths(n.shape.widths).c_str(), t.value("loss", "").c_str(),
              t.value("train_loss", 0.0), t.value("validation_loss", 0.0), t.value("validation_mse", 0.0),
              t.value("steps", 0), t.value("seconds", 0.0));
}

void print_proxy(const model::YarnModel &m)
{
  const double deg = 1.0 / kDeg;
  std::printf("sampling proxy   kappa_R %.4f, beta_M %.2f deg, gamma_M %.2f deg, kappa_M %.4f", m.proxy.kappa_R,
              m.proxy.beta_M * deg, m.proxy.gamma_M * deg, m.proxy.kappa_M);
  if (m.provenance.contains("proxy_fit")) {
    const auto &f = m.provenance["proxy_fit"];
    std::printf("  (M exits: -log L %.4f vs uniform %.4f)", f.value("nll", 0.0), f.value("nll_uniform", 0.0));
  }
  std::printf("\n");
}

/* The 4D lobe fidelity (model/lobe_fidelity.h), one row per theta_i bin. */
void print_lobes(const model::LobeFidelity &f)
{
  const model::LobeComparison &R = f.R, &M = f.M;
  const bool nr = M.noise_removed;
  std::printf("lobes (4D)       energy-weighted relative L1 per (w_i, w_o) cell, %s;\n"
              "                 energy ratios model / maps per exit band (theta_o from the ply normal; axial: within\n"
              "                 30 deg of the ply axis; forward: within 12 deg of -w_i, the maps' share of the energy\n"
              "                 in brackets; through: w_i and w_o within 15 deg of the plane normal to the ply axis,\n"
              "                 w_o on the far side: a light behind the ply, seen from the front)\n",
              nr ? "model error with the maps' noise removed (raw L1 and noise floor in brackets)"
                 : "against one map, its noise included (--maps-b gives the noise floor)");
  std::printf("  theta_i |   R L1%s |   M L1%s | R  0-30 30-60 60-90 | M  0-30 30-60 60-90 90-120 120-150 150-180 axial forward through\n",
              nr ? " (raw, floor)" : "", nr ? " (raw, floor)" : "");
  for (size_t t = 0; t < M.l1.size(); t++) {
    std::printf("  %5.1f   | %5.1f %%", M.theta_i_deg[t], 100 * R.l1[t]);
    if (nr) {
      std::printf(" (%4.1f, %4.1f)", 100 * R.l1_raw[t], 100 * R.noise_floor[t]);
    }
    std::printf(" | %5.1f %%", 100 * M.l1[t]);
    if (nr) {
      std::printf(" (%4.1f, %4.1f)", 100 * M.l1_raw[t], 100 * M.noise_floor[t]);
    }
    std::printf(" |   %4.2f  %4.2f  %4.2f |  ", R.band_ratio[t][0], R.band_ratio[t][1], R.band_ratio[t][2]);
    for (int k = 0; k <= model::kLobeForwardBand; k++) {
      std::printf(" %5.2f", M.band_ratio[t][size_t(k)]);
    }
    std::printf(" (%2.0f %%)  %5.2f\n", 100 * M.band_share[t][model::kLobeForwardBand],
                M.band_ratio[t][model::kLobeThroughBand]);
  }
  std::printf("  worst L1 but the grazing bin: R %.1f %%, M %.1f %%; grazing bin: R %.1f %%, M %.1f %% (%.1f s)\n",
              100 * R.l1_max_but_grazing, 100 * M.l1_max_but_grazing, 100 * R.l1_grazing, 100 * M.l1_grazing,
              f.seconds);
}

/* The maps' forward peak (model/forward_peak.h) per theta_i row: its share of the row's M energy (EM: per
 * incident bin, RGB, the fitted maps' mean), the median width (spot: 1 / sqrt(kappa); arc: beta and gamma) over
 * the row's bins with a peak, how much of the cone's excess it explains, and (two maps) the most a lobe could,
 * the rest being their noise. */
void print_forward_peaks(const model::ForwardPeakTable &t, const rdm::RdmMaps &maps, const std::vector<double> &EM,
                         model::ForwardShape shape)
{
  const bool arc = shape == model::ForwardShape::kArc;
  std::printf("forward peak     the maps' M lobe within 12 deg of -w_i as %s on the radiance around it\n"
              "  theta_i | share of M | width (deg)     | explained | ceiling\n",
              arc ? "the surface fibers' TT arc" : "a von Mises-Fisher lobe");
  auto median = [](std::vector<double> &v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  for (int ti = 0; ti < t.theta_bins; ti++) {
    double w = 0.0, e = 0.0, explained = 0.0, ceiling = 0.0;
    int n_ceiling = 0;
    std::vector<double> w1, w2;
    for (int pi = 0; pi < t.phi_bins; pi++) {
      const model::ForwardPeak &p = t.at(ti, pi);
      w += model::luminance(p.w.data());
      e += model::luminance(&EM[maps.incident_index(ti, pi) * 3]);
      if (p.kappa > 0.0 || p.beta > 0.0) {
        w1.push_back((arc ? p.beta : 1.0 / std::sqrt(p.kappa)) / kDeg);
        w2.push_back(p.gamma / kDeg);
        explained += p.explained;
        if (p.ceiling > -1.0) {
          ceiling += p.ceiling;
          n_ceiling++;
        }
      }
    }
    std::printf("  %5.1f   |   %5.1f %%  |", rdm::bin_center(ti, 0.0, 90.0, t.theta_bins), e > 0.0 ? 100 * w / e : 0.0);
    if (w1.empty()) {
      std::printf("       -         |     -     |    -\n");
      continue;
    }
    const double n = double(w1.size());
    if (arc) {
      const double b = median(w1), g = median(w2);
      std::printf(" %5.2f x %6.2f  |", b, g);
    }
    else {
      std::printf("     %5.2f       |", median(w1));
    }
    std::printf("   %5.2f   |", explained / n);
    if (n_ceiling > 0) {
      std::printf("  %5.2f\n", ceiling / n_ceiling);
    }
    else {
      std::printf("    -\n");
    }
  }
}

void print_fidelity(const model::FidelityReport &r)
{
  std::printf("albedo vs map    mean abs error %.4f, mean relative error %.2f %%, max relative %.1f %%\n", r.albedo_mae,
              100 * r.albedo_mae_rel, 100 * r.albedo_max_rel);
  auto by_theta = [](const char *label, const std::vector<double> &v) {
    std::printf("%-16s", label);
    for (double x : v) {
      std::printf(" %.0f", 100 * x);
    }
    std::printf("  (%% per theta_i bin, normal to grazing)\n");
  };
  by_theta("  albedo", r.albedo_rel_by_theta);
  by_theta("  M energy", r.M_rel_by_theta);
  by_theta("  R energy", r.R_rel_by_theta);
  std::printf("P_T              rms error %.4f\n", r.T_rmse);
  std::printf("energy vs map    R: mean relative error %.2f %%   M: %.2f %%\n", 100 * r.R_energy_mae_rel,
              100 * r.M_energy_mae_rel);
  print_lobes(r.lobes);
  std::printf("sampling         relative variance of the albedo estimate: importance %.3f, uniform %.3f (%.1fx); "
              "kappa_R per w_i %.3f\n",
              r.rel_var_importance, r.rel_var_uniform,
              r.rel_var_importance > 0 ? r.rel_var_uniform / r.rel_var_importance : 0.0, r.rel_var_per_wi_kappa_R);
}

/* min/max P_T and the mean energies over the cells (channel means; the cells are not solid-angle
 * weighted), and the largest albedo P_T + E_R + E_M of a cell. */
void print_fallback(const model::FallbackTables &f)
{
  const size_t n = f.cells();
  double pmin = 1.0, pmax = 0.0, er = 0.0, eu = 0.0, ed = 0.0, amax = 0.0;
  for (size_t k = 0; k < n; k++) {
    pmin = std::min(pmin, double(f.P_T[k]));
    pmax = std::max(pmax, double(f.P_T[k]));
    double a = f.P_T[k];
    for (size_t c = 0; c < 3; c++) {
      er += f.E_R[k * 3 + c] / (3.0 * n);
      eu += f.E_M_up[k * 3 + c] / (3.0 * n);
      ed += f.E_M_down[k * 3 + c] / (3.0 * n);
      a = std::max(a, double(f.P_T[k]) + f.E_R[k * 3 + c] + f.E_M_up[k * 3 + c] + f.E_M_down[k * 3 + c]);
    }
    amax = std::max(amax, a);
  }
  std::printf("fallback tables  %d x %d views (theta, phi in (-90, 90) deg): P_T %.4f .. %.4f, mean E_R %.4f, "
              "E_M up %.4f, down %.4f; max albedo %.4f\n",
              f.theta_bins, f.phi_bins, pmin, pmax, er, eu, ed, amax);
}

std::function<void(const std::string &, double)> bar_callback(ProgressBar *bar, const TrainModelOptions &o)
{
  auto current = std::make_shared<std::string>();
  return [bar, current, &o](const std::string &stage, double f) {
    /* The networks "T", "R", "M", then "M2", "M3", ... for the M candidates, in Adam steps; the other stages
     * ("R shape", "calibration", "fit", "fallback tables") in per cent. */
    const bool network = stage == "T" || stage == "R" || stage[0] == 'M';
    if (*current != stage) {
      *current = stage;
      bar->stage(network ? "train " + stage : stage, network ? "steps" : "%");
    }
    const int steps = stage == "T" ? o.T.steps : stage == "R" ? o.R.steps : network ? o.M.steps : 100;
    bar->update(uint64_t(f * steps + 0.5), uint64_t(std::max(1, steps)));
  };
}

class Commands : public ModelCommands {
 public:
  explicit Commands(CLI::App &app)
  {
    train_ = app.add_subcommand("train", "Train the T, R and M networks on maps and fit the sampling proxy");
    train_->add_option("--maps", maps_, "Map file (.nyrdm) to train on")->required();
    train_->add_option("--out", out_, "Model file to write (.json)")->required();
    add_train_options(train_, &topt_);
    add_m_choice(train_);
    train_->add_flag("--no-fit", no_fit_, "Skip the proxy fit (kappa_R only)");
    train_->add_flag("--quiet", quiet_, "No progress bar");

    fit_ = app.add_subcommand("fit", "Re-fit the importance-sampling proxy and energy calibration of a model on maps");
    fit_->add_option("model", model_, "Model file (.json)")->required();
    fit_->add_option("--maps", maps_, "Map file (.nyrdm)")->required();
    fit_->add_option("--out", out_, "Model file to write (default: replace the input)");
    fit_->add_option("--samples", topt_.fit.samples, "M exits drawn for the fit")
        ->check(CLI::Range(100, 100000000))
        ->capture_default_str();
    fit_->add_option("--seed", topt_.fit.seed, "Seed of the drawn exits")->capture_default_str();
    fit_->add_option("--r-free-path", topt_.r_free_path,
                     "Set the R lobe's mean free path to its fiber (ply radii) before the R shape is re-fitted "
                     "(default: keep the model's)")
        ->check(finite_range(0.0, ny::kYarnMaxFreePath));
    fit_->add_option("--check-maps", check_maps_,
                     "Independent maps of the same ply or yarn (two: the lobes' noise removed): the model's fidelity "
                     "numbers are measured again against them; without, the file drops the old ones (they were of "
                     "the lobes before this fit)")
        ->expected(1, 2);
    fit_->add_option("--r-surface-spread", topt_.r_surface_spread,
                     "A yarn-level model: set its R nodes to the fibers of this central share of its visible ply "
                     "surface (0: the surface fiber alone) before the R shape is re-fitted (default: keep the model's)")
        ->check(finite_range(0.0, 1.0));
    fit_->add_flag("--retrain-r", retrain_r_,
                   "Train the R-energy network again on the maps (seeded as the bake seeded it), before the rest is "
                   "re-fitted: with --r-widths 3-7-7-3 (the default) it carries the R energy's colour "
                   "(docs/decisions.md D65)");
    add_network_options(fit_, "r", &topt_.R);

    bake_ = app.add_subcommand("bake", "Gather maps, train, fit and check: a model from fiber parameters");
    add_preset_options(bake_, &preset_, &params_);
    bake_->add_option("--out", out_, "Model file to write (.json)")->required();
    bake_->add_option("--paths", paths_, "Paths to gather (1e7, 40M, ...)")->capture_default_str();
    bake_->add_option("--seed", gopt_.seed, "Seed of the paths")->capture_default_str();
    bake_->add_option("--packing-seed", gopt_.packing_seed, "Seed of the fiber cross-section")->capture_default_str();
    bake_->add_option("--layouts", gopt_.layouts,
                      "Spread the paths over this many fiber cross-sections (packing seeds --packing-seed, +1, "
                      "...): the model of their mean (ply level)")
        ->capture_default_str();
    bake_->add_option("--bins", bins_, "Map resolution")->capture_default_str();
    bake_->add_option("--maps-out", maps_out_, "Also keep the gathered maps (.nyrdm)");
    bake_->add_option("--image", image_, "Comparison image (PNG): maps next to the model");
    bake_->add_option("--check-paths", check_paths_,
                      "Check the model against independent maps of this many paths (seed + 1000; 0: against the "
                      "training maps, which the energy calibration matches by construction)")
        ->capture_default_str();
    bake_->add_option("--threads", threads_, "Worker threads (0: all cores); results do not depend on it")
        ->capture_default_str();
    add_train_options(bake_, &topt_);
    add_m_choice(bake_);
    add_level_options(bake_, &level_);
    bake_->add_flag("--quiet", quiet_, "No progress bar");

    fallback_ = app.add_subcommand(
        "fallback", "(Re)compute the view-dependent tables of the stock-Blender fallbacks (OSL, node group) in a model");
    fallback_->add_option("model", model_, "Model file (.json)")->required();
    fallback_->add_option("--out", out_, "Model file to write (default: replace the input)");
    fallback_->add_option("--theta-bins", fbopt_.theta_bins, "Cells over the view's theta in (-90, 90) degrees")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    fallback_->add_option("--phi-bins", fbopt_.phi_bins, "Cells over the view's phi in (-90, 90) degrees")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    fallback_->add_option("--threads", threads_, "Worker threads (0: all cores); results do not depend on it")
        ->capture_default_str();

    near_field_ = app.add_subcommand(
        "near-field", "Set a model's near field (how far along the ply the light it sends through the ply travels before "
                      "it leaves; docs/decisions.md D68) from maps of the same ply or yarn; nothing else changes");
    near_field_->add_option("model", model_, "Model file (.json)")->required();
    near_field_->add_option("--maps", maps_, "Map file (.nyrdm) gathered since D72 (it records the exits' signed offsets per band)")
        ->required();
    near_field_->add_option("--out", out_, "Model file to write (default: replace the input)");

    furnace_ = app.add_subcommand("furnace",
                                  "White furnace of a model: the largest energy it scatters from any incident "
                                  "direction under uniform white light (must not exceed 1)");
    furnace_->add_option("model", model_, "Model file (.json)")->required();
    furnace_->add_flag("--inside", furnace_inside_,
                       "Also between the bin centres (3 x 3 directions per bin) and at theta_i 89.975 deg");
    furnace_->add_option("--max", max_furnace_, "Exit 1 if the largest value exceeds this")
        ->check(finite_range(0.0, 100.0));
    furnace_->add_flag("--bound", furnace_bound_,
                       "First bound the calibration table between its centres (as every bake does), recompute "
                       "the fallback tables and write the model (--out, default: replace the input)");
    furnace_->add_option("--out", out_, "Model file to write with --bound")->needs("--bound");
    furnace_->add_option("--threads", threads_, "Worker threads (0: all cores); results do not depend on it")
        ->capture_default_str();

    check_ = app.add_subcommand("check", "Fidelity of a model against maps (albedo, energies, sampling variance)");
    check_->add_option("model", model_, "Model file (.json)")->required();
    check_->add_option("--maps", maps_, "Map file (.nyrdm)")->required();
    check_->add_option("--maps-b", maps_b_,
                       "An independent map of the same ply (another path seed): separates the lobes' model error "
                       "from the maps' noise");
    check_->add_flag("--forward-peaks", forward_peaks_,
                     "Fit the maps' forward peak of M per incident bin and report it per theta_i (docs/decisions.md D41)");
    check_->add_option("--forward-shape", forward_shape_, "The forward peak's lobe: spot (von Mises-Fisher about -w_i) "
                       "or arc (the surface fibers' TT form)")
        ->check(CLI::IsMember({"spot", "arc"}))
        ->needs("--forward-peaks")
        ->capture_default_str();
    check_->add_option("--threads", threads_, "Worker threads (0: all cores); results do not depend on it")
        ->capture_default_str();
    check_->add_option("--image", image_, "Comparison image (PNG)");
    check_->add_option("--json", json_out_, "Also write the numbers as JSON (the object a bake stores as \"fidelity\")");
    check_->add_option("--theta-i", theta_i_, "Incident polar angle of the image, degrees")
        ->check(finite_range(0.0, 90.0))
        ->capture_default_str();
    check_->add_option("--phi-i", phi_i_, "Incident azimuth of the image, degrees")
        ->check(finite_range(-180.0, 180.0))
        ->capture_default_str();
    check_->add_option("--max-albedo-error", max_err_, "Exit 1 if the mean relative albedo error exceeds this")
        ->check(finite_range(0.0, 10.0));
    check_->add_option("--max-lobe-error", max_lobe_,
                       "R,M: exit 1 if the worst lobe L1 of the theta_i bins but the grazing one exceeds these "
                       "(fractions; the noise removed with --maps-b)")
        ->expected(2)
        ->delimiter(',')
        ->check(finite_range(0.0, 100.0));
  }

  int run() override
  {
    if (train_->parsed()) {
      return run_train();
    }
    if (fit_->parsed()) {
      return run_fit();
    }
    if (bake_->parsed()) {
      return run_bake();
    }
    if (check_->parsed()) {
      return run_check();
    }
    if (fallback_->parsed()) {
      return run_fallback();
    }
    if (furnace_->parsed()) {
      return run_furnace();
    }
    if (near_field_->parsed()) {
      return run_near_field();
    }
    return -1;
  }

 private:
  /* Fail on a bad option before spending minutes on loading or gathering. */
  void validate_train_options()
  {
    /* Before any gathering: what the model file and the kernel take (model/model.h). */
    const std::vector<int> wT = train::parse_widths(topt_.T.widths);
    if (wT.front() != 3 || wT.back() != 1) {
      throw ParameterError("widths", "'" + topt_.T.widths + "': the T network maps 3 inputs to 1 output");
    }
    validate_r_widths();
    const std::vector<int> w = train::parse_widths(topt_.M.widths);
    if (w.front() != 6 || !model::is_m_output_width(w.back())) {
      throw ParameterError("widths", "'" + topt_.M.widths + "': the M network maps 6 inputs to 3 outputs, or to 6 "
                                     "when it is two-sided (docs/decisions.md D45)");
    }
  }

  void validate_r_widths()
  {
    const std::vector<int> w = train::parse_widths(topt_.R.widths);
    if (w.front() != 3 || !model::is_r_output_width(w.back())) {
      throw ParameterError("widths", "'" + topt_.R.widths + "': the R network maps 3 inputs to 3 outputs (RGB) or to 1 "
                                     "(its colour the fiber's C_R; docs/decisions.md D65)");
    }
  }

  int run_train()
  {
    validate_train_options();
    check_writable(out_);
    const rdm::RdmMaps maps = rdm::load_maps(maps_);
    topt_.fit_proxy = !no_fit_;
    topt_.threads = threads_;
    ProgressBar bar(!quiet_, "steps");
    topt_.progress = bar_callback(&bar, topt_);
    set_m_choice(maps);
    model::YarnModel m = model::train_model(maps, topt_);
    m.provenance["maps"]["file"] = maps_;
    model::save_model(m, out_);
    print_networks(m);
    if (m.near_field.empty()) {
      std::printf("note: %s: the model has no near field; `neuralyarn near-field` sets one from newer maps\n",
                  no_signed_offsets(maps_).c_str());
    }
    std::printf("%s\n", bar.stage_times().c_str());
    std::printf("wrote %s\n", out_.c_str());
    return 0;
  }

  int run_fit()
  {
    model::YarnModel m = model::load_model(model_);
    const rdm::RdmMaps maps = rdm::load_maps(maps_);
    require_same_preset(m, maps);
    const std::string out = out_.empty() ? model_ : out_;
    check_writable(out);
    if (retrain_r_) {
      /* Seeded as a bake seeds it (model/bake.cpp train_model: the training seed + 1). */
      validate_r_widths();
      const uint64_t seed = m.provenance.value("training_seed", uint64_t(1)) + 1;
      m.R = model::train_one("R", maps, topt_.R, ny::kMlpHeadExp, seed, threads_, {}, nullptr);
      print_network("R", m.R);
    }
    model::fit_model_proxy(&m, maps, topt_.fit);
    if (const model::NearField nf = model::near_field_of(maps); !nf.empty()) {
      m.near_field = nf;
    }
    else { /* maps from before D72 leave the model's near field as it was */
      std::printf("note: %s: the model's near field is left as it was\n", no_signed_offsets(maps_).c_str());
    }
    if (topt_.r_free_path >= 0.0) {
      m.r_free_path = topt_.r_free_path;
    }
    if (topt_.r_surface_spread >= 0.0) {
      model::set_r_surface_spread(&m, topt_.r_surface_spread);
    }
    model::require_one_r_node_kind(m.r_free_path, m.r_frames.empty() ? 0.0 : m.r_surface_spread);
    m.r_shape = model::fit_r_shape(m, maps);
    m.calibration = model::calibrate_energy(m, maps, threads_);
    refresh_fallback(&m);
    m.provenance["refit"] = {{"maps", model::maps_provenance(maps)},
                             {"created", utc_now()},
                             {"code_version", std::string(kVersion) + "+" + kGitRevision}};
    if (retrain_r_) {
      m.provenance["refit"]["retrained"] = "R " + topt_.R.widths;
    }
    m.fidelity = nlohmann::json::object();
    if (!check_maps_.empty()) {
      const rdm::RdmMaps a = rdm::load_maps(check_maps_[0]);
      require_same_preset(m, a);
      std::optional<rdm::RdmMaps> b;
      if (check_maps_.size() > 1) {
        b = rdm::load_maps(check_maps_[1]);
        require_same_preset(m, *b);
      }
      const model::FidelityReport r = model::check_model(m, a, {}, b ? &*b : nullptr);
      m.fidelity = r.to_json();
      m.fidelity["maps"] = "independent maps: " + check_maps_[0] + (b ? " and " + check_maps_[1] : std::string()) +
                           " (" + std::to_string(a.paths) + " paths each, at the re-fit)";
      print_fidelity(r);
    }
    model::save_model(m, out);
    print_proxy(m);
    print_fallback(*m.fallback);
    std::printf("wrote %s\n", out.c_str());
    return 0;
  }

  int run_bake()
  {
    validate_train_options();
    check_writable(out_);
    if (!maps_out_.empty()) {
      check_writable(maps_out_);
    }
    const FiberPreset preset = resolve_preset(preset_, params_);
    gopt_.paths = parse_count(paths_);
    const uint64_t check_paths = check_paths_ == "0" ? 0 : parse_count(check_paths_);
    gopt_.bins = rdm::parse_resolution(bins_);
    gopt_.threads = threads_;
    rdm::validate(gopt_);
    if (!quiet_) {
      print_preset(preset);
    }
    ProgressBar bar(!quiet_, "paths");
    bar.stage("gather", "paths");
    gopt_.progress = [&bar](uint64_t done, uint64_t total) { bar.update(done, total); };
    const rdm::RdmMaps maps = gather_level(preset, level_, gopt_);
    if (!maps_out_.empty()) {
      rdm::save_maps(maps, maps_out_);
    }
    topt_.threads = threads_;
    topt_.progress = bar_callback(&bar, topt_);
    set_m_choice(maps);
    model::YarnModel m = model::train_model(maps, topt_);
    m.provenance["gather_seconds"] = maps.stats.seconds;
    /* Two independent check gathers of half the check paths each: their mean checks the energies, the
     * pair the lobes with the maps' noise removed (model/lobe_fidelity.h). */
    rdm::RdmMaps check_a, check_b;
    if (check_paths > 0) {
      rdm::GatherOptions c = gopt_;
      c.progress = [&bar](uint64_t done, uint64_t total) { bar.update(done, total); };
      c.paths = std::max<uint64_t>(check_paths / 2, gopt_.bins.incident());
      c.seed = gopt_.seed + 1000;
      bar.stage("check gather", "paths");
      check_a = gather_level(preset, level_, c);
      c.seed = gopt_.seed + 2000;
      check_b = gather_level(preset, level_, c);
    }
    bar.stage("fidelity", "");
    const model::FidelityReport r = check_paths > 0 ? model::check_model(m, check_a, {}, &check_b)
                                                    : model::check_model(m, maps);
    m.fidelity = r.to_json();
    m.fidelity["maps"] = check_paths > 0 ? "independent maps: two gathers of " + std::to_string(check_a.paths) +
                                               " paths, seeds " + std::to_string(gopt_.seed + 1000) + " and " +
                                               std::to_string(gopt_.seed + 2000) + ", same geometry"
                                         : std::string("the maps the model was trained on");
    model::save_model(m, out_);
    std::printf("gathered         %llu paths in %.1f s\n", (unsigned long long)maps.paths, maps.stats.seconds);
    print_networks(m);
    print_fidelity(r);
    std::printf("%s\n", bar.stage_times().c_str());
    if (!image_.empty()) {
      model::write_comparison_image(m, check_paths > 0 ? check_a : maps, theta_i_, phi_i_, image_);
      std::printf("wrote %s\n", image_.c_str());
    }
    std::printf("wrote %s\n", out_.c_str());
    return 0;
  }

  int run_check()
  {
    const model::YarnModel m = model::load_model(model_);
    const rdm::RdmMaps maps = rdm::load_maps(maps_);
    require_same_preset(m, maps);
    rdm::RdmMaps maps_b;
    if (!maps_b_.empty()) {
      maps_b = rdm::load_maps(maps_b_);
      require_same_preset(m, maps_b);
    }
    print_proxy(m);
    if (!json_out_.empty()) {
      check_writable(json_out_);
    }
    const model::FidelityReport r = model::check_model(m, maps, {}, maps_b_.empty() ? nullptr : &maps_b);
    print_fidelity(r);
    if (!json_out_.empty()) {
      try {
        write_file_atomically(json_out_, r.to_json().dump(1), "\n");
      }
      catch (const std::exception &e) {
        throw std::runtime_error(json_out_ + ": " + e.what());
      }
      std::printf("wrote %s\n", json_out_.c_str());
    }
    if (forward_peaks_) {
      /* Both maps together where there are two (twice the paths per bin): the fit takes their mean, and the M
       * energy, linear in the map, is the mean of theirs. */
      std::vector<double> EM = maps.energy(maps.m);
      if (!maps_b_.empty()) {
        const std::vector<double> EM_b = maps_b.energy(maps_b.m);
        for (size_t k = 0; k < EM.size(); k++) {
          EM[k] = 0.5 * (EM[k] + EM_b[k]);
        }
      }
      model::ForwardPeakOptions fo;
      fo.threads = threads_;
      fo.shape = forward_shape_ == "arc" ? model::ForwardShape::kArc : model::ForwardShape::kSpot;
      print_forward_peaks(model::fit_forward_peaks(maps, fo, maps_b_.empty() ? nullptr : &maps_b), maps, EM, fo.shape);
    }
    if (!image_.empty()) {
      model::write_comparison_image(m, maps, theta_i_, phi_i_, image_);
      std::printf("wrote %s\n", image_.c_str());
    }
    if (max_err_ >= 0.0 && r.albedo_mae_rel > max_err_) {
      std::fprintf(stderr, "neuralyarn: albedo error %.4f exceeds --max-albedo-error %.4f\n", r.albedo_mae_rel, max_err_);
      return 1;
    }
    if (max_lobe_.size() == 2 &&
        (r.lobes.R.l1_max_but_grazing > max_lobe_[0] || r.lobes.M.l1_max_but_grazing > max_lobe_[1])) {
      std::fprintf(stderr, "neuralyarn: worst lobe L1 but the grazing bin R %.3f, M %.3f exceeds --max-lobe-error %.3f,%.3f\n",
                   r.lobes.R.l1_max_but_grazing, r.lobes.M.l1_max_but_grazing, max_lobe_[0], max_lobe_[1]);
      return 1;
    }
    return 0;
  }

  void add_m_choice(CLI::App *cmd)
  {
    cmd->add_option("--m-choice", m_choice_,
                    "With --m-candidates: keep the M network whose lobe is closest to the maps in 4D (lobes), or "
                    "whose close-up image under the front, grazing, back and axis lights is, over the whole frame "
                    "(image: ranks trainings as independent maps do, docs/decisions.md D53) or over the frame and "
                    "its central region (image-centre: what the ply level's goals measure, D54)")
        ->check(CLI::IsMember({"lobes", "image", "image-centre"}))
        ->capture_default_str();
  }

  /* --m-choice image, image-centre: the candidates scored by their close-up images against the maps' (scenes/, so
   * set here). */
  void set_m_choice(const rdm::RdmMaps &maps)
  {
    if (m_choice_ == "lobes" || topt_.m_candidates < 2) {
      return;
    }
    const bool centre = m_choice_ == "image-centre";
    const scenes::ImageFitRegions regions = centre ? scenes::ImageFitRegions::kFrameAndCentre
                                                   : scenes::ImageFitRegions::kFrame;
    auto target = std::make_shared<std::vector<scenes::Rgb3>>(
        scenes::predict_distant_rigs(scenes::maps_far_field(maps), regions));
    topt_.m_candidate_score = [target, regions](const model::YarnModel &m) {
      return scenes::image_fit_error(scenes::predict_distant_rigs(scenes::model_far_field(m), regions), *target);
    };
    topt_.m_candidate_score_name = std::string("mean over the front, grazing, back and axis lights and the channels "
                                               "of |model / maps - 1| of the close-up's ") +
                                   (centre ? "whole frame and central region" : "whole frame") +
                                   " predicted with the model and with the training maps "
                                   "(scenes/closeup_prediction.h image_fit_error, " + (centre ? "D54)" : "D53)");
  }

  /* The fallback tables sample the kernel: every change to a model's networks or tables redoes them. */
  void refresh_fallback(model::YarnModel *m) const
  {
    model::FallbackOptions fo;
    fo.threads = threads_;
    m->fallback = model::compute_fallback(*m, fo);
  }

  int run_furnace()
  {
    model::YarnModel m = model::load_model(model_);
    if (furnace_bound_) {
      const std::string out = out_.empty() ? model_ : out_;
      check_writable(out);
      const model::CentreBound b = model::bound_between_centres(&m, model::kBoundSub, threads_);
      if (b.nodes > 0) {
        refresh_fallback(&m);
        model::save_model(m, out);
      }
      else if (out != model_) {
        /* Nothing lowered: the model is the one read, so the file is too (an older layout stays as written). */
        write_file_atomically(out, read_file(model_), "");
      }
      std::printf("bound between the calibration centres: %d of %d nodes lowered, smallest factor %.4f; %s %s\n",
                  b.nodes, m.calibration.theta_bins * m.calibration.phi_bins, b.smallest,
                  b.nodes == 0 && out == model_ ? "left unchanged" : "wrote", out.c_str());
    }
    const std::vector<float> flat = m.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    /* The bin centres of the paper's incident bins (where the calibration bounds the sum), or with --inside
     * 3 x 3 directions inside each bin and theta_i 89.975 deg. */
    const rdm::MapResolution bins{22, 90, 45, 90};
    const model::FurnaceMax f =
        model::white_furnace_max(p, model::furnace_directions(bins, furnace_inside_ ? 3 : 1, furnace_inside_));
    std::printf("white furnace max %.5f at theta_i %.2f deg, phi_i %.1f deg (%s)\n", f.value,
                std::acos(std::clamp(double(f.wi.z), -1.0, 1.0)) / kDeg,
                std::atan2(double(f.wi.y), double(f.wi.x)) / kDeg,
                furnace_inside_ ? "3 x 3 directions inside each of 22 x 90 incident bins, and theta_i 89.975 deg"
                                : "22 x 90 incident bin centres");
    if (!std::isfinite(f.value)) {
      std::fprintf(stderr, "neuralyarn: error: the model scatters a non-finite energy\n");
      return 1;
    }
    if (max_furnace_ && f.value > *max_furnace_) {
      std::fprintf(stderr, "neuralyarn: error: white furnace %.5f exceeds --max %g\n", f.value, *max_furnace_);
      return 1;
    }
    return 0;
  }

  int run_near_field()
  {
    /* Only "near_field" changes: the rest of the file stays as written (its kernel array, which the fallback
     * tables name, included). */
    const std::string source = model::model_source(model_);
    nlohmann::json j = model::read_model_json(model_);
    const model::YarnModel m = model::model_from_json(j, source);
    const rdm::RdmMaps maps = rdm::load_maps(maps_);
    require_same_preset(m, maps);
    const model::NearField nf = model::near_field_of(maps);
    if (nf.empty()) {
      throw std::runtime_error(no_signed_offsets(maps_) + ": gather it again");
    }
    const std::string out = out_.empty() ? model_ : out_;
    check_writable(out);
    j["near_field"] = model::near_field_to_json(nf);
    j["near_field"]["maps"] = model::maps_provenance(maps);
    j["code_version"] = std::string(kVersion) + "+" + kGitRevision;
    model::model_from_json(j, source); /* loads as it will be read before it replaces anything */
    write_file_atomically(out, j.dump(1) + "\n", "");
    std::printf("near field: exits' axial offset quantiles (1 5 10 25 50 75 90 95 99 %%, ply radii, positive the "
                "way the light travelled), per band of |cos(light, axis)|:\n");
    for (const auto &[side, q] : {std::pair{"far side", &nf.through}, std::pair{"entry side", &nf.reflected}}) {
      for (size_t b = 0; b * ny::kExitQuantiles < q->size(); b++) {
        std::printf("  %-10s %.1f-%.1f:", side, double(b) / ny::kExitBands, double(b + 1) / ny::kExitBands);
        for (int k = 0; k < ny::kExitQuantiles; k++) {
          std::printf(" %+.3g", double((*q)[b * ny::kExitQuantiles + size_t(k)]));
        }
        std::printf("\n");
      }
    }
    if (nf.through_entry.empty()) {
      std::printf("note: %s holds no entry h (maps from before D73): paths start on the hit point's line\n",
                  maps_.c_str());
    }
    else {
      std::printf("near field: where across the width the light came in (median h of the entry for exits at h "
                  "-0.9 ... 0.9), light across the axis:\n");
      for (const auto &[side, q] : {std::pair{"far side", &nf.through_entry}, std::pair{"entry side", &nf.reflected_entry}}) {
        if (q->empty()) {
          continue;
        }
        std::printf("  %-10s", side);
        for (int r = 0; r < ny::kEntryRows; r++) {
          std::printf(" %+.2f", double((*q)[size_t(r) * ny::kExitQuantiles + ny::kExitQuantiles / 2]));
        }
        std::printf("\n");
      }
    }
    std::printf("wrote %s\n", out.c_str());
    return 0;
  }

  int run_fallback()
  {
    /* The model without its current tables: they are what this verb replaces, and stale or corrupt ones
     * (which load_model rejects) must not stop it. */
    const std::string source = model::model_source(model_);
    nlohmann::json j = model::read_model_json(model_);
    if (j.is_object()) {
      j.erase("fallback");
    }
    model::YarnModel m = model::model_from_json(j, source);
    const std::string out = out_.empty() ? model_ : out_;
    check_writable(out);
    fbopt_.threads = threads_;
    m.fallback = model::compute_fallback(m, fbopt_);
    /* Only the fallback object changes (and code_version, the writer's): a layout 4 or 5 kernel array stays as
     * the file holds it (the loader reads it as layout 6), and the tables name that array. Files whose older
     * arrays cannot carry tables (versions 1-3) are written in the current format. */
    const auto written = j.contains("kernel_flat") ? j["kernel_flat"] : nlohmann::json();
    const bool keep = written.is_array() && !written.empty() && written[0].is_number() &&
                      written[0].get<double>() >= 4.0; /* the loader took it, so it is layout 4, 5 or 6 */
    if (keep) {
      m.fallback->kernel_flat_hash = model::fnv1a64_hex(written.get<std::vector<float>>());
      j["fallback"] = model::fallback_to_json(*m.fallback);
      j["code_version"] = std::string(kVersion) + "+" + kGitRevision;
      model::model_from_json(j, source); /* loads as written (the tables name the array) before it replaces anything */
      write_file_atomically(out, j.dump(1) + "\n", "");
    }
    else {
      model::save_model(m, out);
    }
    print_fallback(*m.fallback);
    std::printf("wrote %s\n", out.c_str());
    return 0;
  }

  void print_networks(const model::YarnModel &m)
  {
    print_network("T", m.T);
    print_network("R", m.R);
    print_network("M", m.M);
    if (m.provenance.contains("m_candidates")) {
      const auto &c = m.provenance["m_candidates"];
      // Each score as the file names it (the M lobe's 4D L1, or the close-up images' fit: D53).
      std::printf("M candidates    ");
      for (const auto &k : c["candidates"]) {
        std::printf(" %.2f %% (seed %llu)", 100 * k.value("score", 0.0),
                    (unsigned long long)k.value("seed", uint64_t(0)));
      }
      std::printf("; kept #%zu\n                 score: %s\n", c.value("kept", size_t(0)) + 1,
                  c.value("score", std::string("?")).c_str());
    }
    print_proxy(m);
    if (m.fallback) {
      print_fallback(*m.fallback);
    }
  }

  static void require_same_preset(const model::YarnModel &m, const rdm::RdmMaps &maps)
  {
    if (preset_to_json(m.preset) != preset_to_json(maps.preset)) {
      throw std::runtime_error("the maps were gathered for preset '" + maps.preset.name +
                               "' with other parameters than the model's ('" + m.preset.name + "')");
    }
    if (m.structure.plies != maps.structure.plies || m.structure.ply_twist != maps.structure.ply_twist) {
      auto level = [](const geometry::YarnStructure &s) {
        return s.is_yarn() ? "a " + std::to_string(s.plies) + "-ply yarn at ply twist " + std::to_string(s.ply_twist)
                           : std::string("one ply");
      };
      throw std::runtime_error("the maps were gathered through " + level(maps.structure) + ", the model describes " +
                               level(m.structure));
    }
  }

  CLI::App *train_, *fit_, *bake_, *check_, *fallback_, *furnace_, *near_field_;
  LevelOptions level_;
  std::optional<double> max_furnace_;
  bool furnace_inside_ = false;
  bool furnace_bound_ = false;
  bool forward_peaks_ = false;
  std::string forward_shape_ = "spot";
  std::string m_choice_ = "lobes";
  TrainModelOptions topt_;
  model::FallbackOptions fbopt_;
  rdm::GatherOptions gopt_;
  std::vector<std::string> check_maps_;
  std::string maps_, maps_b_, out_, model_, preset_ = "fleece", params_, paths_ = "4e7", check_paths_ = "0", bins_ = "22x90x45x90", maps_out_,
                                   image_, json_out_;
  int threads_ = 0;
  bool no_fit_ = false, quiet_ = false, retrain_r_ = false;
  double theta_i_ = 45.0, phi_i_ = 0.0, max_err_ = -1.0;
  std::vector<double> max_lobe_;
};

}  // namespace

std::unique_ptr<ModelCommands> add_model_commands(CLI::App &app) { return std::make_unique<Commands>(app); }

}  // namespace neuralyarn::cli
