// SPDX-License-Identifier: Apache-2.0
//
// Helpers shared by the `neuralyarn` verbs: validators, preset resolution, counts, the progress bar.
#pragma once

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/yarn_tracer.h"

namespace neuralyarn::cli {

/* CLI::Range lets NaN through (every comparison with NaN is false): reject non-finite values first. */
inline CLI::Validator finite_range(double lo, double hi)
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

inline FiberPreset resolve_preset(const std::string &name, const std::string &params_file)
{
  if (!params_file.empty()) {
    return load_preset_file(params_file);
  }
  return find_preset(name);
}

inline void print_preset(const FiberPreset &p)
{
  std::printf("%-10s N=%-4d rho=%.3f alpha=%.3f C_R=(%.3f, %.3f, %.3f) C_TT=(%.3f, %.3f, %.3f) "
              "beta_R=%.3f beta_TT=%.3f gamma_TT=%.3f deg\n",
              p.name.c_str(), p.N, p.rho, p.alpha, p.C_R[0], p.C_R[1], p.C_R[2], p.C_TT[0], p.C_TT[1], p.C_TT[2],
              p.beta_R_deg, p.beta_TT_deg, p.gamma_TT_deg);
}

/* `--preset NAME` (built in) or `--params FILE` (a fiber parameter file), not both: what resolve_preset
 * takes. */
inline void add_preset_options(CLI::App *cmd, std::string *preset, std::string *params)
{
  auto *by_name = cmd->add_option("--preset", *preset, "Built-in preset name")->capture_default_str();
  cmd->add_option("--params", *params, "Fiber parameter file (JSON, docs/file_formats.md)")->excludes(by_name);
}

/* The level the random walks run through (docs/decisions.md D27): `--level ply` (the preset's ply) or
 * `--level yarn --plies K --ply-twist A` (a K-ply yarn of it, the add-on's default plying). */
struct LevelOptions {
  std::string level = "ply";
  int plies = 3;
  double ply_twist = 0.5;
  std::string yarn_intersector = "grid";
};

inline void add_level_options(CLI::App *cmd, LevelOptions *o)
{
  cmd->add_option("--level", o->level, "What the paths walk through: ply (one ply) or yarn (a K-ply yarn)")
      ->check(CLI::IsMember({"ply", "yarn"}))
      ->capture_default_str();
  cmd->add_option("--plies", o->plies, "--level yarn: plies per yarn")->check(CLI::Range(1, 16))->capture_default_str();
  cmd->add_option("--ply-twist", o->ply_twist, "--level yarn: ply twist alpha_yarn (2 R_yarn turns per length)")
      ->check(finite_range(0.0, 8.0))
      ->capture_default_str();
  cmd->add_option("--yarn-intersector", o->yarn_intersector,
                  "--level yarn: the yarn's fibers as slabs of chord tubes (grid) or Embree's round curves (embree, "
                  "the slower reference)")
      ->check(CLI::IsMember({"grid", "embree"}))
      ->capture_default_str();
}

inline rdm::RdmMaps gather_level(const FiberPreset &preset, const LevelOptions &level, const rdm::GatherOptions &options)
{
  if (level.level == "ply") {
    return rdm::gather(preset, options);
  }
  geometry::YarnStructure s;
  s.plies = level.plies;
  s.ply_twist = level.ply_twist;
  return rdm::gather_yarn(preset, s, options,
                          level.yarn_intersector == "embree" ? rdm::YarnIntersector::kEmbree : rdm::YarnIntersector::kGrid);
}

/* "10000000", "1e7", "10M", "2.5k": a positive integer path count. */
inline uint64_t parse_count(const std::string &text)
{
  std::string s = text;
  double mult = 1.0;
  if (!s.empty()) {
    const char suffix = s.back();
    if (suffix == 'k' || suffix == 'K') mult = 1e3;
    if (suffix == 'M' || suffix == 'm') mult = 1e6;
    if (suffix == 'G' || suffix == 'g') mult = 1e9;
    if (mult != 1.0) s.pop_back();
  }
  double v = 0.0;
  if (!CLI::detail::lexical_cast(s, v) || !std::isfinite(v) || v * mult < 1.0 || v * mult > 1e12 ||
      std::floor(v * mult) != v * mult) {
    throw ParameterError("paths", "--paths must be a whole number in [1, 1e12] (e.g. 1e7 or 10M), got '" + text + "'");
  }
  return uint64_t(v * mult);
}


/* A one-line progress bar on stderr, redrawn at most 4 times a second (every 10 % when stderr is not a
 * terminal, so logs stay short). A multi-stage job (bake) calls stage() before each stage; the bar then
 * shows the stage's name and its own progress and ETA, and stage_times() says where the time went. */
class ProgressBar {
 public:
  explicit ProgressBar(bool enabled, std::string unit = "paths")
      : enabled_(enabled), tty_(isatty(2)), unit_(std::move(unit)), start_(Clock::now())
  {
  }
  void stage(const std::string &name, const std::string &unit)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto now = Clock::now();
    end_stage(now);
    stage_ = name + " ";
    name_ = name;
    unit_ = unit;
    start_ = now;
    last_decile_ = -1;
    last_ = {};
  }
  void update(uint64_t done, uint64_t total)
  {
    if (!enabled_ || total == 0) return;
    std::lock_guard<std::mutex> lock(mutex_);
    const auto now = Clock::now();
    const double frac = double(done) / double(total);
    if (tty_) {
      if (done < total && now - last_ < std::chrono::milliseconds(250)) return;
    }
    else {
      if (done < total && int(frac * 10) == last_decile_) return;
      last_decile_ = int(frac * 10);
    }
    last_ = now;
    const double secs = std::chrono::duration<double>(now - start_).count();
    const double rate = secs > 0 ? double(done) / secs : 0.0;
    const double eta = rate > 0 ? double(total - done) / rate : 0.0;
    const int width = 30, filled = int(frac * width);
    std::string bar(size_t(filled), '#');
    bar.append(size_t(width - filled), '.');
    std::fprintf(stderr, "%s%s[%s] %5.1f%%  %s / %s %s  %s %s/s  ETA %.0fs%s", tty_ ? "\r" : "", stage_.c_str(),
                 bar.c_str(), 100.0 * frac, human(double(done)).c_str(), human(double(total)).c_str(), unit_.c_str(),
                 human(rate).c_str(), unit_.c_str(), eta, tty_ ? (done >= total ? "\n" : "") : "\n");
    std::fflush(stderr);
  }
  /* One line of the wall time of every stage so far: "stage times     gather 37.1 s, train T 0.4 s, ...". */
  std::string stage_times()
  {
    std::lock_guard<std::mutex> lock(mutex_);
    end_stage(Clock::now());
    std::string s = "stage times     ";
    for (size_t k = 0; k < times_.size(); k++) {
      char buf[128];
      std::snprintf(buf, sizeof(buf), "%s%s %.1f s", k ? ", " : "", times_[k].first.c_str(), times_[k].second);
      s += buf;
    }
    return s;
  }

 private:
  using Clock = std::chrono::steady_clock;
  void end_stage(Clock::time_point now)
  {
    if (!name_.empty()) {
      times_.emplace_back(name_, std::chrono::duration<double>(now - start_).count());
      name_.clear();
    }
  }
  /* 1234 -> "1234", 4.2e7 -> "42M". */
  static std::string human(double v)
  {
    char buf[32];
    if (v >= 1e6) {
      std::snprintf(buf, sizeof(buf), "%.3gM", v / 1e6);
    }
    else {
      std::snprintf(buf, sizeof(buf), "%.0f", v);
    }
    return buf;
  }
  bool enabled_, tty_;
  std::string unit_, stage_, name_;
  std::vector<std::pair<std::string, double>> times_;
  Clock::time_point start_, last_{};
  int last_decile_ = -1;
  std::mutex mutex_;
};

inline void check_writable(const std::string &out)
{
  const std::filesystem::path parent = std::filesystem::path(out).has_parent_path() ? std::filesystem::path(out).parent_path() : std::filesystem::path(".");
  if (!std::filesystem::is_directory(parent)) {
    throw std::runtime_error("output directory '" + parent.string() + "' does not exist");
  }
  if (::access(parent.c_str(), W_OK) != 0) {
    throw std::runtime_error("output directory '" + parent.string() + "' is not writable");
  }
  if (std::filesystem::is_directory(out)) {
    throw std::runtime_error("output path '" + out + "' is a directory");
  }
}

}  // namespace neuralyarn::cli
