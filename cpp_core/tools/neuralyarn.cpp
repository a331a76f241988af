// SPDX-License-Identifier: Apache-2.0
//
// The `neuralyarn` command line. Each verb is a thin layer over a library function that the tests call
// directly; the verbs only parse arguments, print, and turn exceptions into a message and exit code 1.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <optional>
#include <thread>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>

#include "cli_common.h"
#include "model_commands.h"
#include "neuralyarn/fiber_report.h"
#include "neuralyarn/io.h"
#include "neuralyarn/geometry/yarn.h"
#include "neuralyarn/plots.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/rdm/surface_gather.h"
#include "neuralyarn/model/surface_fit.h"
#include "neuralyarn/scenes/ply_curves.h"
#include "neuralyarn/scenes/closeup_prediction.h"
#include "neuralyarn/scenes/ply_scene.h"
#include "neuralyarn/scenes/scene_json.h"
#include "neuralyarn/version.h"

namespace fs = std::filesystem;
using namespace neuralyarn;
using namespace neuralyarn::cli;

namespace {

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


int run_gather(const std::string &preset_name, const std::string &params_file, const std::string &paths_text,
               uint64_t seed, uint64_t packing_seed, int layouts, int threads, const std::string &bins_text, bool no_symmetrize, bool variance,
               bool quiet, const LevelOptions &level, const std::string &out)
{
  const FiberPreset preset = resolve_preset(preset_name, params_file);
  rdm::GatherOptions opt;
  opt.paths = parse_count(paths_text);
  opt.seed = seed;
  opt.packing_seed = packing_seed;
  opt.layouts = layouts;
  opt.threads = threads;
  opt.bins = rdm::parse_resolution(bins_text);
  opt.symmetrize = !no_symmetrize;
  opt.variance = variance;
  rdm::validate(opt);
  check_writable(out);
  if (!quiet) {
    print_preset(preset);
    std::printf("gathering %llu paths, seed %llu, bins %dx%dx%dx%d%s, %d cross-section%s\n",
                (unsigned long long)opt.paths, (unsigned long long)seed, opt.bins.theta_i, opt.bins.phi_i,
                opt.bins.theta_o, opt.bins.phi_o, opt.symmetrize ? ", symmetrised" : "", opt.layouts,
                opt.layouts == 1 ? "" : "s");
    std::fflush(stdout);
  }
  ProgressBar bar(!quiet);
  opt.progress = [&bar](uint64_t done, uint64_t total) { bar.update(done, total); };
  const rdm::RdmMaps maps = gather_level(preset, level, opt);
  if (level.level == "yarn" && level.yarn_intersector == "grid" && maps.intersector != "slabs") {
    std::printf("note: this yarn's fibers turn back along its axis, which slabs cannot hold: walked through Embree's "
                "curves (the maps say so)\n");
  }
  rdm::save_maps(maps, out);
  const rdm::GatherStats &s = maps.stats;
  auto rgb = [](const double v[3]) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.4f %.4f %.4f", v[0], v[1], v[2]);
    return std::string(buf);
  };
  std::printf("paths            %llu in %.2f s: %.3f M paths/s (%d threads)\n", (unsigned long long)s.paths, s.seconds,
              s.paths_per_second() / 1e6, threads > 0 ? threads : int(std::thread::hardware_concurrency()));
  std::printf("energy T (rgb)   %s   (%llu paths)\n", rgb(s.energy_T).c_str(), (unsigned long long)s.paths_T);
  std::printf("energy R (rgb)   %s   (%llu paths)\n", rgb(s.energy_R).c_str(), (unsigned long long)s.paths_R);
  std::printf("energy M (rgb)   %s   (%llu paths)\n", rgb(s.energy_M).c_str(), (unsigned long long)s.paths_M);
  std::printf("absorbed (rgb)   %s\n", rgb(s.absorbed).c_str());
  std::printf("balance (rgb)    %s   (exit + absorbed + lost; 1 in expectation, standard error %.1e)\n",
              rgb(s.balance).c_str(), std::max({s.balance_se[0], s.balance_se[1], s.balance_se[2]}));
  std::printf("lost (rgb)       %s   (%llu paths cut at the event limit)\n", rgb(s.lost).c_str(),
              (unsigned long long)s.paths_truncated);
  if (maps.structure.is_yarn()) {
    std::printf("yarn             %d plies, ply twist %.3f, surface twist alpha %.4f; %llu paths left through an end\n",
                maps.structure.plies, maps.structure.ply_twist, maps.structure.surface_alpha,
                (unsigned long long)s.paths_past_ends);
  }
  std::printf("events per path  mean %.2f, 95th percentile %d, max %d\n", s.mean_events, s.p95_events,
              s.max_events_seen);
  std::printf("exit displacement (envelope radii, scattered paths)  mean %.2f, 95th percentile %.2f; M only: mean %.2f, "
              "95th %.2f\n",
              s.mean_displacement, s.p95_displacement, s.mean_displacement_M, s.p95_displacement_M);
  auto buf = [](double v) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.2f", v);
    return std::string(b);
  };
  /* Each band's mean and median (the middle quantile: the levels are symmetric about 50 %). */
  constexpr size_t median = ny::kExitQuantiles / 2;
  auto bands = [&](const std::vector<double> &q, const std::vector<double> &mean) {
    std::string t;
    for (size_t b = 0; b < mean.size() && (b + 1) * ny::kExitQuantiles <= q.size(); b++) {
      t += std::string(b ? ", " : "") + buf(mean[b]) + "/" + buf(q[b * ny::kExitQuantiles + median]);
    }
    return t;
  };
  std::printf("exit along the axis (envelope radii, energy-weighted, the way the light travelled; mean/median per band "
              "of |cos(w_i, axis)| 0-0.2 ... 0.8-1)  through the far side: %s; on the entry side: %s\n",
              bands(s.axial_exit_through, s.mean_axial_exit_through).c_str(),
              bands(s.axial_exit_reflected, s.mean_axial_exit_reflected).c_str());
  /* Where the light came in across the width for exits at its edge (h -1 ... -0.8) and its middle (-0.2 ... 0),
   * light across the axis (band 0): 10/50/90 %. */
  auto entry = [&](const std::vector<double> &q) {
    std::string t;
    for (const int row : {0, ny::kEntryRows / 2 - 1}) {
      const size_t at = size_t(row) * ny::kExitQuantiles;
      if (at + ny::kExitQuantiles <= q.size()) {
        t += std::string(row ? ", middle " : "edge ") + buf(q[at + 2]) + "/" + buf(q[at + median]) + "/" + buf(q[at + 6]);
      }
    }
    return t;
  };
  std::printf("entry across the width (h seen along w_i, 10/50/90 %%, light across the axis) for exits at the "
              "edge and in the middle  through the far side: %s; on the entry side: %s\n",
              entry(s.entry_h_through).c_str(), entry(s.entry_h_reflected).c_str());
  if (s.invalid_weights) {
    std::printf("WARNING: %llu paths had invalid weights and were dropped\n", (unsigned long long)s.invalid_weights);
  }
  std::printf("wrote %s\n", out.c_str());
  return s.invalid_weights ? 1 : 0;
}

/* `neuralyarn fiber`: a fiber's albedo table and lobe plot. */
struct FiberCommand {
  CLI::App *cmd;
  std::string preset = "fleece", params, out;
  double theta_i = 30.0, phi_i = 0.0;
  int samples = 200000;
  uint64_t seed = 1;

  explicit FiberCommand(CLI::App &app) : cmd(app.add_subcommand("fiber", "Albedo table and scattering-lobe plot of a fiber preset"))
  {
    add_preset_options(cmd, &preset, &params);
    cmd->add_option("--theta-i", theta_i, "Incident longitudinal angle of the plot, degrees")
        ->check(finite_range(-90.0, 90.0))
        ->capture_default_str();
    cmd->add_option("--phi-i", phi_i, "Incident azimuth of the plot, degrees")
        ->check(finite_range(-180.0, 180.0))
        ->capture_default_str();
    cmd->add_option("--samples", samples, "Monte Carlo samples per albedo row")
        ->check(CLI::Range(1, 1000000000))
        ->capture_default_str();
    cmd->add_option("--seed", seed, "Random seed")->capture_default_str();
    cmd->add_option("--out", out, "Lobe plot to write (PNG)");
  }
  int run() const { return run_fiber(preset, params, theta_i, phi_i, samples, seed, out); }
};

/* `neuralyarn yarn-geometry`: where a K-ply yarn's plies sit, in ply radii (the add-on sizes yarn-level
 * curves with the same numbers). */
struct YarnGeometryCommand {
  CLI::App *cmd;
  int plies = 3;
  std::vector<double> ply_twists{0.5};
  int surface_frames = 0;
  double spread = 1.0;
  std::string preset = "fleece", params;

  explicit YarnGeometryCommand(CLI::App &app)
      : cmd(app.add_subcommand("yarn-geometry",
                               "The ply centre distance and yarn radius of a K-ply yarn in ply radii: a JSON line per ply twist"))
  {
    cmd->add_option("--plies", plies, "Plies per yarn")->check(CLI::Range(1, 16))->capture_default_str();
    cmd->add_option("--ply-twist", ply_twists, "Ply twist alpha_yarn (2 R_yarn turns per length); several give a line each")
        ->check(finite_range(0.0, 8.0))
        ->capture_default_str();
    cmd->add_option("--surface-frames", surface_frames,
                    "Also the fiber frames of the visible ply surface at this many quantiles (docs/decisions.md D51; "
                    "the fibers' twist from --preset or --params)")
        ->check(CLI::Range(1, 64));
    cmd->add_option("--spread", spread, "--surface-frames: the central share of the visible surface they stand for")
        ->check(finite_range(1e-6, 1.0))
        ->capture_default_str();
    add_preset_options(cmd, &preset, &params);
  }
  int run() const
  {
    for (const double alpha : ply_twists) {
      const double d = geometry::ply_center_distance(plies, 1.0, alpha);
      nlohmann::json line = {{"plies", plies}, {"ply_twist", alpha}, {"ply_distance", d}, {"yarn_radius", d + 1.0}};
      if (surface_frames > 0) {
        geometry::YarnStructure structure;
        structure.plies = plies;
        structure.ply_twist = alpha;
        const geometry::Yarn yarn(geometry::yarn_params(resolve_preset(preset, params), structure), 1);
        nlohmann::json frames = nlohmann::json::array();
        for (const geometry::SurfaceFrame &f : geometry::visible_surface_frames(yarn, surface_frames, spread)) {
          frames.push_back({{"T", {f.T.x(), f.T.y(), f.T.z()}}, {"N", {f.N.x(), f.N.y(), f.N.z()}},
                            {"turn_deg", f.turn * 180.0 / kPi}});
        }
        line["spread"] = spread;
        line["surface_frames"] = frames;
      }
      std::printf("%s\n", line.dump().c_str());
    }
    return 0;
  }
};

/* `neuralyarn gather`: radiance distribution maps of a ply or yarn. */
struct GatherCommand {
  CLI::App *cmd;
  std::string preset = "fleece", params, paths = "1e6", bins = "22x90x45x90", out;
  uint64_t seed = 1, packing_seed = 1;
  int layouts = 1, threads = 0;
  bool no_sym = false, variance = false, quiet = false;
  LevelOptions level;

  explicit GatherCommand(CLI::App &app)
      : cmd(app.add_subcommand("gather", "Trace paths through an explicit ply and write its radiance distribution maps"))
  {
    add_preset_options(cmd, &preset, &params);
    cmd->add_option("--paths", paths, "Number of paths (1e7, 10M, ...)")->capture_default_str();
    cmd->add_option("--seed", seed, "Seed of the paths")->capture_default_str();
    cmd->add_option("--packing-seed", packing_seed, "Seed of the fiber cross-section")->capture_default_str();
    cmd->add_option("--layouts", layouts,
                    "Spread the paths over this many fiber cross-sections (packing seeds --packing-seed, +1, ...): "
                    "the maps hold their mean (ply level)")
        ->capture_default_str();
    cmd->add_option("--threads", threads, "Worker threads (0: all cores); the result does not depend on it")
        ->capture_default_str();
    cmd->add_option("--bins", bins, "Map resolution theta_i x phi_i x theta_o x phi_o")->capture_default_str();
    cmd->add_flag("--no-symmetrize", no_sym, "Keep the raw maps (no 180-degree averaging)");
    cmd->add_flag("--variance", variance, "Also store per-bin standard errors");
    cmd->add_flag("--quiet", quiet, "No progress bar");
    cmd->add_option("--out", out, "Map file to write (.nyrdm)")->required();
    add_level_options(cmd, &level);
  }
  int run() const
  {
    return run_gather(preset, params, paths, seed, packing_seed, layouts, threads, bins, no_sym, variance, quiet, level, out);
  }
};

/* `neuralyarn surface`: the surface level's BSDF (D44) from walks through a flat patch of a pattern's curves. */
struct SurfaceCommand {
  CLI::App *cmd;
  std::string plies, model_path, paths = "4e6", out, maps_out, material_out, pattern;
  uint64_t seed = 1;
  int threads = 0, view_bins = 8;
  bool quiet = false;

  explicit SurfaceCommand(CLI::App &app)
      : cmd(app.add_subcommand("surface", "Measure a cloth pattern's far field through a flat patch of its curves and fit "
                                          "the surface level's stock-closure BSDF to it"))
  {
    cmd->add_option("--plies", plies, "Plies file of a flat patch with its 'period' (scripts/garment.py --flat)")
        ->required();
    cmd->add_option("--model", model_path, "The curves' model: a ply-level model walks the plies, a yarn-level one "
                                           "the yarns")
        ->required();
    cmd->add_option("--paths", paths, "Number of paths (over both faces and every view bin)")->capture_default_str();
    cmd->add_option("--seed", seed, "Seed of the paths")->capture_default_str();
    cmd->add_option("--threads", threads, "Worker threads (0: all cores); the result does not depend on it")
        ->capture_default_str();
    cmd->add_option("--view-bins", view_bins, "View cosine bins per face")->capture_default_str();
    cmd->add_flag("--quiet", quiet, "No progress bar");
    cmd->add_option("--out", out, "Surface BSDF file to write (.json)")->required();
    cmd->add_option("--maps-out", maps_out, "Also write the measured maps (JSON: D, tau, scattered and their layout)");
    cmd->add_option("--material-out", material_out,
                    "Also write the surface level's material as renderers draw it (\"neuralyarn-cloth-surface 1\": the "
                    "closures' sampled weights; what the add-on draws a cloth surface with)");
    cmd->add_option("--pattern", pattern,
                    "With --material-out: a JSON object naming the pattern the patch is of, kept in the file (the add-on "
                    "draws the material only on cloth of that pattern)");
  }

  int run() const
  {
    const scenes::PlyCurves pc = scenes::read_ply_curves(plies);
    const model::YarnModel m = model::load_model(model_path);
    const bool yarns = m.structure.is_yarn();
    if (yarns && (pc.yarns.empty() || m.structure.plies != pc.plies_per_yarn ||
                  std::abs(m.structure.ply_twist - pc.ply_twist) > 1e-6)) {
      throw std::runtime_error("model '" + model_path + "' is a yarn-level model of " + std::to_string(m.structure.plies) +
                               " plies; '" + plies + "' has no yarns of that plying");
    }
    if (!(pc.period[0] > 0.0)) {
      throw std::runtime_error("'" + plies + "' has no 'period': the surface level walks through a flat patch "
                               "(scripts/garment.py --flat)");
    }
    check_writable(out);
    nlohmann::json pattern_json = nlohmann::json::object();
    if (!material_out.empty()) {
      check_writable(material_out);
      try {
        pattern_json = nlohmann::json::parse(pattern.empty() ? "{}" : pattern);
      }
      catch (const nlohmann::json::exception &) {
        pattern_json = nullptr;
      }
      if (!pattern_json.is_object()) {
        throw std::runtime_error("--pattern must be a JSON object, got '" + pattern + "'");
      }
    }
    const geometry::CurveSet curves = scenes::curve_set(yarns ? pc.yarns : pc.plies, yarns ? pc.yarn_radius : 1.0);
    Eigen::AlignedBox3f box;
    for (const Eigen::Vector3f &q : curves.points) {
      box.extend(q);
    }
    rdm::SurfaceGatherOptions o;
    o.paths = parse_count(paths);
    o.seed = seed;
    o.threads = threads;
    o.view_bins = view_bins;
    o.centre_x = box.center().x(), o.centre_y = box.center().y();
    o.period_x = pc.period[0], o.period_y = pc.period[1];
    ProgressBar bar(!quiet);
    o.progress = [&bar](uint64_t done, uint64_t total) { bar.update(done, total); };
    const rdm::SurfaceMaps maps = rdm::gather_surface(curves, m, o);
    model::SurfaceBsdf s = model::fit_surface(maps);
    s.source = {{"model", model_path}, {"level", yarns ? "yarns" : "plies"}, {"plies", plies},
                {"paths", maps.paths}, {"seed", seed}, {"period", {pc.period[0], pc.period[1]}},
                {"paths_past_edges", maps.paths_past_edges}, {"paths_lost", maps.paths_lost},
                {"code", std::string(kVersion) + "+" + kGitRevision}};
    model::save_surface(s, out);
    if (!material_out.empty()) {
      const nlohmann::json j = {{"format", scenes::kClothSurfaceFormat}, {"pattern", pattern_json},
                                {"level", yarns ? "yarns" : "plies"},
                                {"material", scenes::material_json(scenes::cloth_surface_material(s), material_out)},
                                {"source", s.source}};
      write_file_atomically(material_out, j.dump() + "\n", "");
    }
    if (!maps_out.empty()) {
      const nlohmann::json j = {{"view_bins", maps.view_bins}, {"light_theta", maps.light_theta},
                                {"light_phi", maps.light_phi}, {"D", maps.D}, {"tau", maps.tau},
                                {"scattered", maps.scattered}, {"layout", "D[side][view][hemisphere][theta][phi][rgb]"}};
      write_file_atomically(maps_out, j.dump() + "\n", "");
    }
    std::printf("paths            %llu in %.2f s: %.3f M paths/s; %llu left near the patch's edge, %llu cut\n",
                (unsigned long long)maps.paths, maps.seconds, double(maps.paths) / maps.seconds / 1e6,
                (unsigned long long)maps.paths_past_edges, (unsigned long long)maps.paths_lost);
    std::printf("absorbed (rgb)   %.4f %.4f %.4f\n", maps.absorbed[0], maps.absorbed[1], maps.absorbed[2]);
    for (int side = 0; side < 2; side++) {
      std::printf("%s face: cos theta_v, straight through, scattered (rgb), fit error\n", side == 0 ? "front" : "back");
      for (int v = 0; v < view_bins; v++) {
        const size_t c = size_t(side) * size_t(view_bins) + size_t(v);
        std::printf("  %.3f   %.4f   %.4f %.4f %.4f   %.3f\n", s.view_cos(v), s.transparent[c], s.albedo[c * 3],
                    s.albedo[c * 3 + 1], s.albedo[c * 3 + 2], s.fit_error[c]);
      }
    }
    std::printf("wrote %s\n", out.c_str());
    return 0;
  }
};

/* `neuralyarn cycles-scene`: the close-up (or plies, layers, a baseline) for the patched Cycles, and what the
 * core library predicts of it. */
struct SceneCommand {
  CLI::App *cmd;
  std::string preset = "fleece", params;
  std::vector<std::string> outs;
  scenes::PlySceneOptions opt;
  std::vector<double> baseline_colour;
  std::vector<int> region;
  std::vector<std::string> predict_maps, predict_lights;
  std::string predict_lobes = "RM", predict_image;
  bool predict_fallback = false, predict_interpolate = false;

  explicit SceneCommand(CLI::App &app)
      : cmd(app.add_subcommand("cycles-scene", "Write the single-ply close-up (explicit fibers, or aggregated with --model) "
                                               "for the patched Cycles (.xml) and for the add-on's Blender builder (.json)"))
  {
    add_preset_options(cmd, &preset, &params);
    cmd->add_option("--width", opt.width, "Image width")->check(CLI::Range(1, 16384))->capture_default_str();
    cmd->add_option("--height", opt.height, "Image height")->check(CLI::Range(1, 16384))->capture_default_str();
    cmd->add_option("--packing-seed", opt.packing_seed, "Seed of the fiber cross-section")->capture_default_str();
    cmd->add_option("--ply-length", opt.ply_length, "Length of the ply along x, centred on the origin (ply radii)")
        ->check(finite_range(1.0, 1000.0))
        ->capture_default_str();
    auto *opt_lights = cmd->add_option("--lights", opt.lights,
                                       "Light rig: " + scenes::light_rig_names() +
                                           " (--list-lights), or sun-DEG-normal / sun-DEG-axis: a distant light DEG "
                                           "degrees from the view")
                             ->capture_default_str();
    cmd->add_flag("--white-furnace", opt.white_furnace,
                  "Uniform white background, no lights (the environment rig) and no Russian roulette")
        ->excludes(opt_lights);
    /* A flag that prints a table (name, description; one a line) and exits. It runs while parsing, before the
     * check for the required --out: `cycles-scene --list-lights` alone works. */
    const auto list_flag = [this](const std::string &flag, const auto &table, const std::string &what) {
      cmd->add_flag_callback(
          flag,
          [&table] {
            for (const auto &row : table) {
              std::printf("%-12s %s\n", row.name.c_str(), row.description.c_str());
            }
            throw CLI::Success();
          },
          "Print the " + what + " (name, description; one a line) and exit");
    };
    list_flag("--list-lights", scenes::light_rigs(), "light rigs");
    cmd->add_option_function<std::string>(
        "--describe-light",
        [](const std::string &name) {
          scenes::LightRig rig;
          try {
            rig = scenes::find_light_rig(name);
          }
          catch (const std::runtime_error &e) {
            throw CLI::ValidationError("--describe-light", e.what());
          }
          std::printf("%-12s %s\n", rig.name.c_str(), rig.description.c_str());
          throw CLI::Success();
        },
        "Print one light rig (name, description), a listed one or sun-DEG-normal / sun-DEG-axis, and exit");
    cmd->add_option("--ply-rotation", opt.ply_rotation_deg,
                    "Explicit version: turn the fibers by this many degrees about the ply axis (another "
                    "orientation of the same cross-section; references average over several)")
        ->check(CLI::Range(-360.0, 360.0))
        ->capture_default_str();
    cmd->add_option("--max-bounce", opt.max_bounce, "Cycles' bounce limit (Russian roulette ends paths before it)")
        ->check(CLI::Range(1, 65535))
        ->capture_default_str();
    cmd->add_flag("--artist-bounces", opt.artist_bounces,
                  "Blender's default bounce limits (12, diffuse 4, glossy 4, transmission 12) with the add-on's 64 "
                  "transparent bounces, instead of --max-bounce for every kind");
    cmd->add_option("--camera-distance", opt.camera_distance,
                    "Camera distance from the ply axis (ply radii): the ply's width in pixels is about "
                    "height / (0.483 distance)")
        ->check(finite_range(1.0001, 1e4))
        ->capture_default_str();
    cmd->add_option("--unit-scale", opt.unit_scale,
                    "Every length times this (ply radius 1 becomes this; a 0.5 mm ply in metres is 2.5e-4)")
        ->check(finite_range(1e-6, 1e6))
        ->capture_default_str();
    cmd->add_option("--layers", opt.layers,
                    "Cloth layers: sheets of plies side by side, stacked away from the camera (1: the single ply)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    cmd->add_option_function<std::vector<double>>(
           "--layer-pitch",
           [this](const std::vector<double> &v) {
             opt.layer_pitch_y = v[0];
             opt.layer_pitch_z = v.size() > 1 ? v[1] : v[0];
           },
           "With --layers: ply axes this far apart within a sheet, and (second value, default the first) between "
           "sheets, in ply radii (at least 2)")
        ->default_str(CLI::detail::to_string(scenes::kLayerPitch))
        ->expected(1, 2)
        ->check(finite_range(2.0, 100.0));
    cmd->add_option("--level", opt.level,
                    "With --plies and --model (or --baseline): draw the plies (a ply-level model) or the file's yarns "
                    "(a yarn-level model); with --surface: the file's cloth surface (the surface level)")
        ->check(CLI::IsMember({"plies", "yarns", "surface"}))
        ->capture_default_str();
    cmd->add_option("--plies", opt.plies,
                    "Instead of the straight ply: these ply centrelines (a \"neuralyarn-plies 1\" JSON file, e.g. "
                    "from scripts/garment.py); the explicit version sweeps each ply's fibers along its curve")
        ->check(CLI::ExistingFile);
    cmd->add_option("--light-scale", opt.light_scale,
                    "Point lights' positions and sizes times this, their power times its square (a larger scene)")
        ->check(finite_range(1e-6, 1e6))
        ->capture_default_str();
    cmd->add_option("--segments-per-turn", opt.segments_per_turn,
                    "Explicit version: curve keys per helix turn of a fiber (Cycles interpolates between them)")
        ->check(CLI::Range(3, 256))
        ->capture_default_str();
    cmd->add_option("--seed", opt.seed, "Cycles' integrator seed: renders with other seeds have independent noise")
        ->check(CLI::Range(0, 2147483647))
        ->capture_default_str();
    auto *opt_model =
        cmd->add_option("--model", opt.model, "Aggregated version: one thick curve with this neural yarn model");
    cmd->add_option("--surface", opt.surface,
                    "With --level surface: the surface level's BSDF (`neuralyarn surface`) on the plies file's "
                    "\"surface\" mesh")
        ->check(CLI::ExistingFile)
        ->excludes(opt_model);
    auto *opt_baseline = cmd->add_option("--baseline", opt.baseline,
                                         "Aggregated geometry with a stock closure instead of a model (--list-baselines)")
                               ->excludes(opt_model);
    cmd->add_option("--baseline-colour", baseline_colour, "With --baseline: its colour R G B, each in [0, 1]")
        ->expected(3)
        ->needs(opt_baseline);
    list_flag("--list-baselines", scenes::baselines(), "baselines");
    cmd->add_flag("--diffuse", opt.diffuse,
                  "Aggregated geometry in a grey Lambertian instead of a model: the check that two renderers "
                  "build the same scene")
        ->excludes(opt_model)
        ->excludes(opt_baseline);
    cmd->add_flag("--empty", opt.empty,
                  "Camera, film, integrator and a black background only (the renderer's own memory)");
    cmd->add_flag("--embed-model", opt.embed_model,
                  "With --model: write the model's JSON into the scene (a self-contained file; cycles_patch 0003)");
    cmd->add_option("--predict-region", region,
                    "Print the mean colour the core library predicts over the pixel rectangle X Y W H of a WIDTH x "
                    "HEIGHT render (see --width/--height) under the environment or a distant-light rig: of the "
                    "--model, and of each --predict-maps file. The scene must be one straight curve along x seen "
                    "from -z: the close-up, or the yarn level's straight yarn (--level yarns with such a plies file)")
        ->expected(4);
    cmd->add_option("--predict-image", predict_image,
                    "Write the whole WIDTH x HEIGHT image the core library predicts, as OpenEXR, for each far field "
                    "and rig: PREFIX_model_RIG.exr, PREFIX_fallback_RIG.exr, PREFIX_maps1_RIG.exr (the --predict-maps "
                    "files in order); with the same options and scene conditions as --predict-region, with or "
                    "without it")
        ->type_name("PREFIX");
    cmd->add_option("--predict-lights", predict_lights,
                    "With --predict-region or --predict-image: predict under these rigs (default: the scene's), "
                    "each map file loaded once for all of them")
        ->delimiter(',');
    cmd->add_flag("--predict-fallback", predict_fallback,
                  "With --predict-region or --predict-image, and --model: also predict the model's stock-Blender "
                  "fallback (its fallback tables, as Blender renders them)");
    cmd->add_option("--predict-lobes", predict_lobes,
                    "With --predict-region or --predict-image: the lobes of the model and the maps to predict: RM "
                    "(what renders), or R or M alone (which lobe a difference is in; distant lights only)")
        ->check(CLI::IsMember({"RM", "R", "M"}))
        ->capture_default_str();
    cmd->add_option("--predict-maps", predict_maps,
                    "With --predict-region or --predict-image: also predict with these radiance distribution maps "
                    "(.nyrdm) as the ply's scattering (the tabulated far field)")
        ->check(CLI::ExistingFile);
    cmd->add_flag("--predict-interpolate", predict_interpolate,
                  "With --predict-maps: the maps interpolated linearly between their bins' centres in each angle "
                  "instead of the bin a direction pair falls in (a predicted image without the bins' steps)");
    cmd->add_option("--out", outs,
                    "Scene file to write: .xml (Cycles XML) or .json (the scene description that the add-on's "
                    "Blender builder reads, docs/file_formats.md); give it more than once for one scene in both")
        ->required();
  }

  int run()
  {
    scenes::find_light_rig(opt.lights); /* an unknown rig is named before anything else */
    for (const std::string &name : predict_lights) {
      scenes::find_light_rig(name);
    }
    for (size_t c = 0; c < baseline_colour.size(); c++) {
      opt.baseline_colour[c] = baseline_colour[c];
    }
    for (const std::string &out : outs) {
      scenes::check_scene_extension(out);
      check_writable(out);
    }
    if (!predict_image.empty()) {
      check_writable(predict_image + "_model.exr"); /* before the scene and the predictions */
    }
    const scenes::Scene scene = scenes::ply_scene(resolve_preset(preset, params), opt);
    for (const std::string &out : outs) {
      scenes::write_scene(scene, out);
      /* What the harness records of the scene (scripts/evaluate.py reads this line, never the scene). */
      const Eigen::Vector3d &cam = scene.camera.position;
      std::printf("wrote %s (%zu curves, %zu curve keys; camera at %.9g %.9g %.9g, fov %.9g)\n", out.c_str(),
                  scene.num_curves(), scene.num_curve_keys(), cam.x(), cam.y(), cam.z(), scene.camera.fov);
    }
    if (!region.empty() || !predict_image.empty()) {
      predict(scene);
    }
    else if (!predict_maps.empty() || !predict_lights.empty() || predict_fallback || predict_lobes != "RM" ||
             predict_interpolate)
    {
      throw std::runtime_error("--predict-maps, --predict-lights, --predict-lobes, --predict-fallback and "
                               "--predict-interpolate need --predict-region or --predict-image");
    }
    return 0;
  }

  /* The prediction's camera: the scene must be one straight curve along the x axis (the close-up's ply, or the
   * yarn level's straight yarn) and the camera on the -z side of it at x = y = 0, looking along +z; its distance
   * in the curve's radii. Throws std::runtime_error naming what differs. */
  static scenes::CloseupCamera straight_curve_camera(const scenes::Scene &scene)
  {
    const auto refuse = [](const char *what) {
      throw std::runtime_error(std::string("--predict-region and --predict-image predict one straight curve along x "
                                           "seen from -z (give --model): ") + what);
    };
    if (scene.objects.size() != 1 || scene.objects[0].curves.num_curves() != 1 || !scene.meshes.empty()) {
      refuse("the scene has other curves or meshes");
    }
    const geometry::CurveSet &c = scene.objects[0].curves;
    const double r = c.radii[0];
    for (const Eigen::Vector3f &p : c.points) {
      if (std::abs(p.y()) > 1e-5 * r || std::abs(p.z()) > 1e-5 * r) {
        refuse("its curve leaves the x axis");
      }
    }
    const Eigen::Vector3d &cam = scene.camera.position;
    if (std::abs(cam.x()) > 1e-9 * r || std::abs(cam.y()) > 1e-9 * r || !(cam.z() < -r)) {
      refuse("the camera is not on the -z side of the curve at x = y = 0");
    }
    return {-cam.z() / r, scene.camera.fov};
  }

  /* One line per prediction and rig: "predicted model R G B RIG", "predicted fallback R G B RIG",
   * "predicted maps R G B RIG PATH"; with --predict-image, "predicted image WHAT RIG EXR" per image written. */
  void predict(const scenes::Scene &scene)
  {
    if (opt.unit_scale != 1.0 || opt.layers != 1) {
      throw std::runtime_error("--predict-region predicts the scene as the close-up is built: no --unit-scale or "
                               "--layers");
    }
    std::vector<scenes::LightRig> rigs;
    if (predict_lights.empty()) {
      predict_lights.push_back(opt.white_furnace ? "environment" : opt.lights);
    }
    for (const std::string &name : predict_lights) {
      rigs.push_back(scenes::find_light_rig(name));
    }
    if (predict_fallback && opt.model.empty()) {
      throw std::runtime_error("--predict-fallback needs --model");
    }
    /* A single lobe under the environment: its far field refuses the albedo (closeup_prediction.h). */
    const scenes::Lobes lobes = scenes::parse_lobes(predict_lobes);
    if (lobes != scenes::Lobes::kRM && predict_fallback) {
      throw std::runtime_error("--predict-fallback predicts the fallback whole: no --predict-lobes");
    }
    if (predict_interpolate && predict_maps.empty()) {
      throw std::runtime_error("--predict-interpolate reads the --predict-maps files: give some");
    }
    /* After the options' own errors: they name what the user asked for wrongly before the scene's shape. */
    const scenes::CloseupCamera camera = straight_curve_camera(scene);
    const auto print = [&](const scenes::FarField &f, const char *what, const std::string &suffix,
                           const std::string &image_name) {
      for (const scenes::LightRig &rig : rigs) {
        if (!region.empty()) {
          const scenes::PixelRegion pixels{opt.width, opt.height, region[0], region[1], region[2], region[3]};
          const scenes::Rgb3 a = scenes::predict_closeup(f, rig, pixels, camera);
          std::printf("predicted %s %.6g %.6g %.6g %s%s\n", what, a.r, a.g, a.b, rig.name.c_str(), suffix.c_str());
        }
        if (!predict_image.empty()) {
          const std::vector<scenes::Rgb3> img = scenes::predict_closeup_image(f, rig, opt.width, opt.height, camera);
          std::vector<float> rgb;
          rgb.reserve(3 * img.size());
          for (const scenes::Rgb3 &p : img) {
            rgb.insert(rgb.end(), {float(p.r), float(p.g), float(p.b)});
          }
          const std::string path = predict_image + "_" + image_name + "_" + rig.name + ".exr";
          write_rgb_exr(rgb, opt.width, opt.height, path);
          std::printf("predicted image %s %s %s\n", image_name.c_str(), rig.name.c_str(), path.c_str());
        }
      }
    };
    /* Every input read before anything is written: a bad map file leaves no partial set of images. */
    std::optional<model::YarnModel> m;
    if (!opt.model.empty()) {
      m = model::load_model(opt.model);
    }
    std::vector<rdm::RdmMaps> maps;
    for (const std::string &path : predict_maps) {
      maps.push_back(rdm::load_maps(path));
    }
    if (m) {
      print(scenes::model_far_field(*m, lobes), "model", "", "model");
      if (predict_fallback) {
        print(scenes::fallback_far_field(*m), "fallback", "", "fallback");
      }
    }
    const scenes::MapLookup lookup = predict_interpolate ? scenes::MapLookup::kInterpolated : scenes::MapLookup::kNearest;
    for (size_t k = 0; k < maps.size(); k++) {
      print(scenes::maps_far_field(maps[k], lobes, lookup), "maps", " " + predict_maps[k], "maps" + std::to_string(k + 1));
    }
  }
};

}  // namespace

int main(int argc, char **argv)
{
  CLI::App app{"neuralyarn: neural yarn appearance model (Soh & Montazeri, EGSR 2024) tools"};
  app.set_version_flag("--version", std::string(kVersion) + "+" + kGitRevision); /* as model files stamp it */
  app.require_subcommand(1);

  auto *presets = app.add_subcommand("presets", "List the built-in fiber presets");
  FiberCommand fiber(app);
  GatherCommand gather(app);
  SceneCommand scene(app);
  YarnGeometryCommand yarn_geometry(app);
  SurfaceCommand surface(app);
  auto model_commands = add_model_commands(app);

  try {
    app.parse(argc, argv);
  }
  catch (const CLI::ParseError &e) {
    /* CLI11 prints the message (naming the option) or the help; every usage error exits 1, as every other error
     * of this tool, instead of CLI11's own codes (105 for a value out of range, 109 for an extra argument ...). */
    return app.exit(e) == 0 ? 0 : 1;
  }

  try {
    const int rc = model_commands->run();
    if (rc >= 0) {
      return rc;
    }
    if (presets->parsed()) {
      for (const auto &p : builtin_presets()) {
        print_preset(p);
      }
      return 0;
    }
    if (scene.cmd->parsed()) {
      return scene.run();
    }
    if (gather.cmd->parsed()) {
      return gather.run();
    }
    if (fiber.cmd->parsed()) {
      return fiber.run();
    }
    if (yarn_geometry.cmd->parsed()) {
      return yarn_geometry.run();
    }
    if (surface.cmd->parsed()) {
      return surface.run();
    }
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "neuralyarn: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
