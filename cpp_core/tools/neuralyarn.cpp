// SPDX-License-Identifier: Apache-2.0
//
// The `neuralyarn` command line. Each verb is a thin layer over a library function that the tests call
// directly; the verbs only parse arguments, print, and turn exceptions into a message and exit code 1.
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "neuralyarn/fiber_report.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/version.h"

namespace fs = std::filesystem;
using namespace neuralyarn;

namespace {

/* CLI::Range lets NaN through (every comparison with NaN is false): reject non-finite values first. */
CLI::Validator finite_range(double lo, double hi)
{
  return CLI::Validator(
      [lo, hi](std::string &s) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(s, v) || !std::isfinite(v)) {
          return "value '" + s + "' is not a finite number";
        }
        if (v < lo || v > hi) {
          return "value " + s + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
        }
        return std::string();
      },
      "finite in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
}

FiberPreset resolve_preset(const std::string &name, const std::string &params_file)
{
  if (!params_file.empty()) {
    return load_preset_file(params_file);
  }
  return find_preset(name);
}

void print_preset(const FiberPreset &p)
{
  std::printf("%-10s N=%-4d rho=%.3f alpha=%.3f C_R=(%.3f, %.3f, %.3f) C_TT=(%.3f, %.3f, %.3f) "
              "beta_R=%.3f beta_TT=%.3f gamma_TT=%.3f deg\n",
              p.name.c_str(), p.N, p.rho, p.alpha, p.C_R[0], p.C_R[1], p.C_R[2], p.C_TT[0], p.C_TT[1], p.C_TT[2],
              p.beta_R_deg, p.beta_TT_deg, p.gamma_TT_deg);
}

int run_fiber(const std::string &preset_name, const std::string &params_file, double theta_i, double phi_i,
              int samples, uint64_t seed, const std::string &out)
{
  const FiberPreset preset = resolve_preset(preset_name, params_file);
  print_preset(preset);

  const std::vector<double> thetas = {0, 15, 30, 45, 60, 75, 85, 89, 90};
  const auto rows = fiber_albedo_table(preset, thetas, samples, seed);
  std::printf("\nAlbedo (integral of f cos over the sphere), analytic F + (1 - F) C_TT vs. Monte Carlo through\n"
              "the sampler (%d samples per row, seed %llu, mean +- standard error):\n\n",
              samples, (unsigned long long)seed);
  std::printf("theta_i   F_R (r g b)              albedo (r g b)           MC (r g b)                          p_R\n");
  for (const auto &r : rows) {
    std::printf("%6.1f   %.4f %.4f %.4f    %.4f %.4f %.4f    %.4f %.4f %.4f (+-%.4f)    %.3f\n", r.theta_i_deg,
                r.fresnel.r, r.fresnel.g, r.fresnel.b, r.analytic.r, r.analytic.g, r.analytic.b, r.mc_mean.r,
                r.mc_mean.g, r.mc_mean.b, std::max({r.mc_stderr.r, r.mc_stderr.g, r.mc_stderr.b}), r.p_R);
  }
  const AzimuthComparison az = compare_tt_azimuth(preset.fiber_params().gamma_TT);
  std::printf("\nTT azimuth: von Mises kappa = 1/gamma^2 = %.3f (gamma = %.3f deg); peak %.4f /rad vs. the\n"
              "authors' Gaussian %.4f /rad; L1 distance between the two densities %.5f\n",
              az.kappa, preset.gamma_TT_deg, az.peak_von_mises, az.peak_gaussian, az.l1_distance);

  if (!out.empty()) {
    const fs::path parent = fs::path(out).parent_path();
    if (!parent.empty()) {
      fs::create_directories(parent);
    }
    write_fiber_lobe_plot(preset, theta_i, phi_i, out);
    std::printf("\nwrote %s (lobe at theta_i = %.1f deg, phi_i = %.1f deg)\n", out.c_str(), theta_i, phi_i);
  }
  return 0;
}

}  // namespace

int main(int argc, char **argv)
{
  CLI::App app{"neuralyarn: neural yarn appearance model (Soh & Montazeri, EGSR 2024) tools"};
  app.set_version_flag("--version", std::string(kVersion));
  app.require_subcommand(1);

  auto *presets = app.add_subcommand("presets", "List the built-in fiber presets");

  auto *fiber = app.add_subcommand("fiber", "Albedo table and scattering-lobe plot of a fiber preset");
  std::string preset_name = "fleece", params_file, out;
  double theta_i = 30.0, phi_i = 0.0;
  int samples = 200000;
  uint64_t seed = 1;
  auto *opt_preset = fiber->add_option("--preset", preset_name, "Built-in preset name")->capture_default_str();
  fiber->add_option("--params", params_file, "Fiber parameter file (JSON, docs/file_formats.md)")
      ->excludes(opt_preset);
  fiber->add_option("--theta-i", theta_i, "Incident longitudinal angle of the plot, degrees")
      ->check(finite_range(-90.0, 90.0))
      ->capture_default_str();
  fiber->add_option("--phi-i", phi_i, "Incident azimuth of the plot, degrees")
      ->check(finite_range(-180.0, 180.0))
      ->capture_default_str();
  fiber->add_option("--samples", samples, "Monte Carlo samples per albedo row")
      ->check(CLI::Range(1, 1000000000))
      ->capture_default_str();
  fiber->add_option("--seed", seed, "Random seed")->capture_default_str();
  fiber->add_option("--out", out, "Lobe plot to write (PNG)");

  CLI11_PARSE(app, argc, argv);

  try {
    if (presets->parsed()) {
      for (const auto &p : builtin_presets()) {
        print_preset(p);
      }
      return 0;
    }
    if (fiber->parsed()) {
      return run_fiber(preset_name, params_file, theta_i, phi_i, samples, seed, out);
    }
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "neuralyarn: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
