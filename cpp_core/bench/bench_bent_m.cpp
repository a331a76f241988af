// SPDX-License-Identifier: Apache-2.0
//
// Can the multiple-scattering network learn a ply's bend? (decisions D75, D76) Trains M on the maps of one preset's
// ply gathered straight and bent (bench_bent_gather, per radius and sector of psi) twice on the same samples: once
// conditioned on the bend, inputs (w_i, w_o, kappa R cos psi, kappa R sin psi) with kappa R = 1 / radius (0 when
// straight) and psi the sector's centre, and once pooled, inputs (w_i, w_o) alone — one far field for every bend, as
// the shipped model has. Both learn the maps' S_M |cos theta_o| itself (no escape division, no calibration), with the
// bake's M recipe (exp head, per-channel target scale, relative MSE, Adam). Prints, per map, how far each network's M
// energy per incident bin is from the map's (mean over bins of |E_net / E_map - 1|, by solid angle) and writes both
// networks (the kernel's flat arrays) for bench_bent_ply --bent-m, which renders them on a bent ply, with the
// conditioned network's M calibration per map (its M energy over the map's per incident bin, windowed in phi_i as the
// bake's: what a calibration conditioned on the bend would hold, decisions D77).
//
// Usage: bench_bent_m --maps FILE|RADIUS:SECTOR:SECTORS:FILE ... [--samples 4e6] [--steps 20000] [--hidden 21]
//                     [--seed 1] --out NETS.json
// (A bent gather's maps record their bend since D76; older ones are labelled. RADIUS 0: the ply straight.)
// A benchmark: prints, never a test.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "neuralyarn/model/calibration.h"
#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/train/trainer.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

namespace {

struct BentMaps {
  double radius = 0.0;
  int sector = 0, sectors = 1;
  std::string path;
  /* The bend's two inputs: kappa R (cos psi, sin psi) at the sector's centre. */
  double bend_cos() const { return radius > 0.0 ? std::cos(2.0 * kPi * sector / sectors) / radius : 0.0; }
  double bend_sin() const { return radius > 0.0 ? std::sin(2.0 * kPi * sector / sectors) / radius : 0.0; }
};

/* FILE (its maps record their bend) or RADIUS:SECTOR:SECTORS:FILE (maps gathered before they did). */
BentMaps parse_spec(const std::string &spec)
{
  BentMaps b;
  if (spec.find(':') == std::string::npos) {
    b.path = spec;
    b.sectors = 0; /* from the file */
    return b;
  }
  std::stringstream s(spec);
  char c1 = 0, c2 = 0, c3 = 0;
  if (!(s >> b.radius >> c1 >> b.sector >> c2 >> b.sectors >> c3) || c1 != ':' || c2 != ':' || c3 != ':' ||
      !std::getline(s, b.path) || b.path.empty() || b.sectors < 1 || b.sector < 0 || b.sector >= b.sectors ||
      !(b.radius >= 0.0)) {
    throw std::runtime_error("--maps wants FILE or RADIUS:SECTOR:SECTORS:FILE, got '" + spec + "'");
  }
  return b;
}

/* The bake's M samples (train::sample_multiple_scattering: w_i uniform in cos theta_i over the split's bins with paths,
 * target the map's S_M |cos theta_o| in the bin of w_o), but w_o drawn with probability `share` from the map's own M
 * energy at the sample's incident bin (an outgoing bin in proportion to its mean RGB times its solid angle, uniform in
 * cos theta_o and phi_o within it) and otherwise uniformly on the sphere: the relative MSE then weighs each exit by
 * (1 - share) / 4 pi + share * its energy density, so that the exits that carry the light (the back light's forward
 * peak) count for what they carry (decisions D77). share 0: the bake's samples. */
train::Dataset sample_m_by_energy(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation, double share,
                                  double forward_share = 0.0, double forward_cone = 0.0)
{
  if (!(share > 0.0) && !(forward_share > 0.0)) {
    return train::sample_multiple_scattering(maps, n, seed, validation);
  }
  const rdm::MapResolution &b = maps.bins;
  const int n_out = b.theta_o * b.phi_o;
  /* Per incident bin, the cumulative energy over its outgoing bins (built when first drawn). */
  std::vector<std::vector<float>> cdf(size_t(b.theta_i) * b.phi_i);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  train::Dataset d;
  d.X.resize(6, n);
  d.Y.resize(3, n);
  for (int k = 0; k < n; k++) {
    double theta_i, phi_i;
    int ti, pi;
    for (long tries = 0;; tries++) {
      if (tries > 100000000L) {
        throw std::runtime_error("no incident bin with paths for this split");
      }
      theta_i = std::acos(1.0 - U(rng));
      phi_i = -kPi + 2.0 * kPi * U(rng);
      ti = rdm::bin_of(theta_i, 0.0, 0.5 * kPi, b.theta_i);
      pi = rdm::bin_of(phi_i, -kPi, kPi, b.phi_i);
      if (train::is_validation_bin(b, ti, pi) == validation && maps.count[maps.incident_index(ti, pi)] > 0) {
        break;
      }
    }
    std::vector<float> &c = cdf[maps.incident_index(ti, pi)];
    if (c.empty() && share > 0.0) {
      c.resize(size_t(n_out));
      double sum = 0.0;
      for (int j = 0; j < n_out; j++) {
        const float *v = &maps.m[maps.map_index(ti, pi, j / b.phi_o, j % b.phi_o)];
        sum += (double(v[0]) + v[1] + v[2]) * maps.outgoing_solid_angle(j / b.phi_o);
        c[size_t(j)] = float(sum);
      }
    }
    double theta_o, phi_o;
    const double pick = U(rng);
    if (pick < forward_share) {
      /* Uniform in the cone of half-angle forward_cone about -w_i. */
      const Eigen::Vector3d f = -train::entry_direction(theta_i, phi_i).cast<double>();
      const Eigen::Vector3d a = std::abs(f.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
      const Eigen::Vector3d e1 = f.cross(a).normalized(), e2 = f.cross(e1);
      const double z = 1.0 - U(rng) * (1.0 - std::cos(forward_cone)), r = std::sqrt(std::max(0.0, 1.0 - z * z));
      const double ph = 2.0 * kPi * U(rng);
      const Eigen::Vector3d w = z * f + r * (std::cos(ph) * e1 + std::sin(ph) * e2);
      theta_o = std::acos(std::clamp(w.z(), -1.0, 1.0));
      phi_o = std::atan2(w.y(), w.x());
    }
    else if (pick < forward_share + share && !c.empty() && c.back() > 0.0f) {
      const int j = int(std::upper_bound(c.begin(), c.end(), float(U(rng) * c.back())) - c.begin());
      const int to = std::min(j, n_out - 1) / b.phi_o, po = std::min(j, n_out - 1) % b.phi_o;
      const double z0 = std::cos(kPi * to / b.theta_o), z1 = std::cos(kPi * (to + 1) / b.theta_o);
      theta_o = std::acos(std::clamp(z0 + (z1 - z0) * U(rng), -1.0, 1.0));
      phi_o = -kPi + 2.0 * kPi * (po + U(rng)) / b.phi_o;
    }
    else {
      theta_o = std::acos(1.0 - 2.0 * U(rng));
      phi_o = -kPi + 2.0 * kPi * U(rng);
    }
    const int to = rdm::bin_of(theta_o, 0.0, kPi, b.theta_o), po = rdm::bin_of(phi_o, -kPi, kPi, b.phi_o);
    d.X.block<3, 1>(0, k) = train::entry_direction(theta_i, phi_i);
    d.X.block<3, 1>(3, k) = train::entry_direction(theta_o, phi_o);
    const float *v = &maps.m[maps.map_index(ti, pi, to, po)];
    d.Y(0, k) = v[0], d.Y(1, k) = v[1], d.Y(2, k) = v[2];
  }
  return d;
}

/* The conditioned network's inputs: the pooled network's six and the bend's two, psi drawn uniformly over the sector
 * (its maps average over it), so that the network sees psi continuous rather than at K points. */
train::Mlp<float>::Mat with_bend(const train::Mlp<float>::Mat &X, const BentMaps &b, uint64_t seed)
{
  train::Mlp<float>::Mat Z(8, X.cols());
  Z.topRows(6) = X;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(-0.5, 0.5);
  const double kR = b.radius > 0.0 ? 1.0 / b.radius : 0.0;
  for (long j = 0; j < X.cols(); j++) {
    const double psi = 2.0 * kPi * (b.sector + U(rng)) / b.sectors;
    Z(6, j) = float(kR * std::cos(psi));
    Z(7, j) = float(kR * std::sin(psi));
  }
  return Z;
}

void append(train::Dataset *to, const train::Mlp<float>::Mat &X, const train::Mlp<float>::Mat &Y)
{
  const long n0 = to->X.cols();
  to->X.conservativeResize(X.rows(), n0 + X.cols());
  to->Y.conservativeResize(Y.rows(), n0 + Y.cols());
  to->X.rightCols(X.cols()) = X;
  to->Y.rightCols(Y.cols()) = Y;
}

/* Mean over incident bins (by solid angle) of |E_net / E_map - 1|, the network's M energy per bin by a stratified
 * sphere of exits against the map's; bins without paths or M energy are skipped. */
struct EnergyError {
  double mean_abs = 0.0, mean = 0.0;
};

/* What the energy check needs of a map, kept from its one load: its bins and path counts (the maps without their R
 * and M arrays) and its M energy per incident bin. */
struct MapEnergy {
  rdm::RdmMaps maps;
  std::vector<double> E;
};

/* The network's M energy per incident bin of the map's (rgb, row-major [theta_i][phi_i]; zero where the map has no
 * paths): a stratified sphere of exits at each bin centre, with the bend of the map's sector centre. */
std::vector<double> net_energy(const train::Mlp<float> &net, const MapEnergy &me, const BentMaps &b, bool bend)
{
  const rdm::RdmMaps &maps = me.maps;
  const rdm::MapResolution &bins = maps.bins;
  constexpr int kT = 32, kP = 64; /* exits: cos theta_o and phi_o stratified */
  std::vector<double> E(size_t(bins.theta_i) * bins.phi_i * 3, 0.0);
  for (int ti = 0; ti < bins.theta_i; ti++) {
    const double theta_i = 0.5 * kPi * (ti + 0.5) / bins.theta_i;
    for (int pi = 0; pi < bins.phi_i; pi++) {
      const size_t ii = maps.incident_index(ti, pi);
      if (maps.count[ii] == 0) {
        continue;
      }
      const double phi_i = -kPi + 2.0 * kPi * (pi + 0.5) / bins.phi_i;
      train::Mlp<float>::Mat X(bend ? 8 : 6, kT * kP);
      const Eigen::Vector3f wi = train::entry_direction(theta_i, phi_i);
      for (int k = 0; k < kT * kP; k++) {
        const double theta_o = std::acos(1.0 - 2.0 * ((k / kP) + 0.5) / kT), phi_o = -kPi + 2.0 * kPi * ((k % kP) + 0.5) / kP;
        const Eigen::Vector3f wo = train::entry_direction(theta_o, phi_o);
        X.block<3, 1>(0, k) = wi;
        X.block<3, 1>(3, k) = wo;
        if (bend) {
          X(6, k) = float(b.bend_cos());
          X(7, k) = float(b.bend_sin());
        }
      }
      const train::Mlp<float>::Mat Y = net.forward(X);
      for (int c = 0; c < 3; c++) {
        E[ii * 3 + size_t(c)] = double(Y.row(c).sum()) * 4.0 * kPi / (kT * kP);
      }
    }
  }
  return E;
}

/* Mean over incident bins (by solid angle) of |E_net / E_map - 1|; bins without paths or M energy are skipped. */
EnergyError energy_error(const std::vector<double> &E_net, const MapEnergy &me)
{
  const rdm::RdmMaps &maps = me.maps;
  double sum = 0.0, signed_sum = 0.0, weight = 0.0;
  for (int ti = 0; ti < maps.bins.theta_i; ti++) {
    for (int pi = 0; pi < maps.bins.phi_i; pi++) {
      const size_t ii = maps.incident_index(ti, pi);
      for (int c = 0; c < 3; c++) {
        const double e_map = me.E[ii * 3 + size_t(c)];
        if (maps.count[ii] == 0 || !(e_map > 0.0)) {
          continue;
        }
        const double r = E_net[ii * 3 + size_t(c)] / e_map - 1.0, w = maps.incident_solid_angle(ti);
        sum += w * std::abs(r);
        signed_sum += w * r;
        weight += w;
      }
    }
  }
  return weight > 0.0 ? EnergyError{sum / weight, signed_sum / weight} : EnergyError{};
}

/* The M calibration of a network on one map, as the bake's (model/calibration.h): per incident bin the map's M energy
 * over the network's, both summed over the calibration's window in phi_i (same theta_i), clamped as its ratios. */
std::vector<float> m_calibration(const std::vector<double> &E_net, const MapEnergy &me)
{
  const rdm::MapResolution &bins = me.maps.bins;
  const int half = model::calibration_window_half(bins.phi_i);
  std::vector<float> c(size_t(bins.theta_i) * bins.phi_i * 3, 1.0f);
  for (int ti = 0; ti < bins.theta_i; ti++) {
    for (int pi = 0; pi < bins.phi_i; pi++) {
      for (int ch = 0; ch < 3; ch++) {
        double a = 0.0, b = 0.0;
        for (int d = -half; d <= half; d++) {
          const size_t ii = me.maps.incident_index(ti, (pi + d + bins.phi_i) % bins.phi_i) * 3 + size_t(ch);
          a += me.E[ii];
          b += E_net[ii];
        }
        if (a > 1e-9 && b > 1e-9) {
          c[me.maps.incident_index(ti, pi) * 3 + size_t(ch)] = std::clamp(float(a / b), model::kCalibrationMin, model::kCalibrationMax);
        }
      }
    }
  }
  return c;
}

}  // namespace

int main(int argc, char **argv)
{
  CLI::App app{"M conditioned on the bend against M pooled over bends, trained on straight and bent maps"};
  std::vector<std::string> specs;
  std::string out, samples_text = "4e6";
  int steps = 20000, batch = 4096, hidden = 21, threads = 0;
  uint64_t seed = 1;
  bool no_pooled = false;
  app.add_flag("--no-pooled", no_pooled, "Train the conditioned network alone (the file has no pooled one)");
  app.add_option("--maps", specs, "FILE (a bent gather's, which records its bend) or RADIUS:SECTOR:SECTORS:FILE "
                 "(radius 0: straight), checked against the file's record where it has one")->required();
  app.add_option("--samples", samples_text, "Training samples over all maps (validation: a tenth)");
  app.add_option("--steps", steps)->capture_default_str();
  app.add_option("--batch", batch)->capture_default_str();
  app.add_option("--hidden", hidden, "Hidden units of both layers")->capture_default_str();
  app.add_option("--threads", threads)->capture_default_str();
  app.add_option("--seed", seed, "Initial weights and mini-batches (the samples stay)")->capture_default_str();
  double energy_share = 0.0;
  app.add_option("--energy-share", energy_share, "Share of the samples whose exit is drawn from the map's M energy "
                 "(0: all uniform on the sphere, the bake's)")->check(CLI::Range(0.0, 1.0))->capture_default_str();
  double forward_share = 0.0, forward_cone = 30.0;
  app.add_option("--forward-share", forward_share, "Share of the samples whose exit is drawn uniformly in the cone of "
                 "--forward-cone degrees about -w_i (the light through the ply; 0: none)")->check(CLI::Range(0.0, 1.0));
  app.add_option("--forward-cone", forward_cone)->check(CLI::Range(1.0, 90.0))->capture_default_str();
  app.add_option("--out", out, "The two networks (JSON: the kernel's flat arrays)")->required();
  CLI11_PARSE(app, argc, argv);
  try {
    std::vector<BentMaps> sets;
    for (const std::string &s : specs) {
      sets.push_back(parse_spec(s));
    }
    const int samples = int(std::stod(samples_text));
    const int per_map = std::max(1, samples / int(sets.size()));
    train::Dataset tr_bent, va_bent, tr_pool, va_pool;
    std::vector<MapEnergy> energies;
    std::string preset;
    for (size_t i = 0; i < sets.size(); i++) {
      rdm::RdmMaps maps = rdm::load_maps(sets[i].path);
      BentMaps &b = sets[i];
      if (maps.bend_sectors > 0 && b.sectors > 0 &&
          (maps.bend_radius != b.radius || maps.bend_sector != b.sector || maps.bend_sectors != b.sectors)) {
        throw std::runtime_error(b.path + " records radius " + std::to_string(maps.bend_radius) + ", sector " +
                                 std::to_string(maps.bend_sector) + " of " + std::to_string(maps.bend_sectors) +
                                 ", not what --maps says");
      }
      if (b.sectors == 0) {
        if (maps.bend_sectors == 0) {
          throw std::runtime_error(b.path + " records no bend: give it as RADIUS:SECTOR:SECTORS:FILE");
        }
        b.radius = maps.bend_radius, b.sector = maps.bend_sector, b.sectors = maps.bend_sectors;
      }
      if (i == 0) {
        preset = maps.preset.name;
      }
      else if (maps.preset.name != preset) {
        throw std::runtime_error(sets[i].path + " is " + maps.preset.name + "'s, not " + preset + "'s");
      }
      const train::Dataset tr = sample_m_by_energy(maps, per_map, 1000 + 2 * i, false, energy_share, forward_share,
                                                          forward_cone * kDeg);
      const train::Dataset va = sample_m_by_energy(maps, std::max(1, per_map / 10), 1001 + 2 * i, true, energy_share,
                                                          forward_share, forward_cone * kDeg);
      append(&tr_pool, tr.X, tr.Y);
      append(&va_pool, va.X, va.Y);
      append(&tr_bent, with_bend(tr.X, sets[i], 5000 + 2 * i), tr.Y);
      append(&va_bent, with_bend(va.X, sets[i], 5001 + 2 * i), va.Y);
      MapEnergy me{rdm::RdmMaps{}, maps.energy(maps.m)};
      maps.r = {}, maps.m = {}, maps.r_se = {}, maps.m_se = {};
      me.maps = std::move(maps);
      energies.push_back(std::move(me));
    }
    /* Per-channel target scale, as the bake's exp head (D14). */
    Eigen::VectorXf scale(3);
    for (int c = 0; c < 3; c++) {
      scale(c) = tr_pool.Y.row(c).mean();
      for (train::Dataset *d : {&tr_bent, &va_bent, &tr_pool, &va_pool}) {
        d->Y.row(c) /= scale(c);
      }
    }
    auto train = [&](int inputs, const train::Dataset &tr, const train::Dataset &va, const char *name) {
      train::MlpShape shape{{inputs, hidden, hidden, 3}, ny::kMlpHeadExp};
      train::TrainOptions o;
      o.steps = steps;
      o.batch = batch;
      o.learning_rate = 1e-2f;
      o.final_learning_rate_fraction = 0.05f;
      o.loss = train::Loss::kRelativeMse;
      o.seed = seed;
      o.threads = threads;
      o.record_every = std::max(1, steps / 100);
      const train::TrainResult r = train::train_network(shape, tr, va, o);
      if (r.diverged) {
        throw std::runtime_error(std::string(name) + ": " + r.message);
      }
      std::printf("%-11s %s: %d samples, %d steps in %.1f s; relative MSE train %.4f, validation %.4f\n", name,
                  train::format_widths(shape.widths).c_str(), int(tr.X.cols()), r.steps_done, r.seconds, r.train_loss,
                  r.validation_loss);
      train::Mlp<float> net = r.net;
      train::Mlp<float>::Vec p = net.params();
      for (int c = 0; c < 3; c++) {
        p(p.size() - 3 + c) += std::log(scale(c)); /* exp(z + log s) = s exp(z) */
      }
      net.set_params(p);
      return net;
    };
    const train::Mlp<float> bent = train(8, tr_bent, va_bent, "conditioned");
    std::optional<train::Mlp<float>> pool;
    if (!no_pooled) {
      pool = train(6, tr_pool, va_pool, "pooled");
    }
    std::printf("\nM energy per incident bin against each map's, mean |E_net / E_map - 1| (and E_net / E_map - 1),\n"
                "solid-angle weighted:\n");
    std::printf("%-8s %-10s %20s %20s\n", "radius", "sector", "conditioned", "pooled");
    nlohmann::json calibration = nlohmann::json::array();
    for (size_t i = 0; i < sets.size(); i++) {
      const BentMaps &b = sets[i];
      const std::vector<double> E_bent = net_energy(bent, energies[i], b, true);
      const EnergyError c = energy_error(E_bent, energies[i]),
                        p = pool ? energy_error(net_energy(*pool, energies[i], b, false), energies[i]) : EnergyError{};
      calibration.push_back({{"radius", b.radius}, {"sector", b.sector}, {"sectors", b.sectors},
                             {"theta_bins", energies[i].maps.bins.theta_i}, {"phi_bins", energies[i].maps.bins.phi_i},
                             {"c_M", m_calibration(E_bent, energies[i])}});
      std::printf("%-8g %d/%-8d %10.1f%% (%+6.1f%%) %10.1f%% (%+6.1f%%)\n", b.radius, b.sector, b.sectors,
                  100.0 * c.mean_abs, 100.0 * c.mean, 100.0 * p.mean_abs, 100.0 * p.mean);
      std::fflush(stdout);
    }
    nlohmann::json j = {{"preset", preset},
                        {"inputs", "conditioned: w_i, w_o (entry frame), kappa R cos psi, kappa R sin psi; pooled: "
                                   "w_i, w_o"},
                        {"output", "S_M |cos theta_o| (RGB)"},
                        {"maps", specs},
                        {"conditioned", bent.to_flat()},
                        {"conditioned_calibration", calibration}};
    if (pool) {
      j["pooled"] = pool->to_flat();
    }
    std::ofstream(out) << j.dump(1);
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "bench_bent_m: %s\n", e.what());
    return 1;
  }
  return 0;
}
