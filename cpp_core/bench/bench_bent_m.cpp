// SPDX-License-Identifier: Apache-2.0
//
// Can the multiple-scattering network learn a ply's bend? (decisions D75, D76) Trains M on the maps of one preset's
// ply gathered straight and bent (bench_bent_gather, per radius and sector of psi) twice on the same samples: once
// conditioned on the bend, inputs (w_i, w_o, kappa R cos psi, kappa R sin psi) with kappa R = 1 / radius (0 when
// straight) and psi the sector's centre, and once pooled, inputs (w_i, w_o) alone — one far field for every bend, as
// the shipped model has. Both learn the maps' S_M |cos theta_o| itself (no escape division, no calibration), with the
// bake's M recipe (exp head, per-channel target scale, relative MSE, Adam). Prints, per map, how far each network's M
// energy per incident bin is from the map's (mean over bins of |E_net / E_map - 1|, by solid angle) and writes both
// networks (the kernel's flat arrays) for bench_bent_ply --bent-m, which renders them on a bent ply.
//
// Usage: bench_bent_m --maps FILE|RADIUS:SECTOR:SECTORS:FILE ... [--samples 4e6] [--steps 20000] [--hidden 21]
//                     [--seed 1] --out NETS.json
// (A bent gather's maps record their bend since D76; older ones are labelled. RADIUS 0: the ply straight.)
// A benchmark: prints, never a test.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

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

EnergyError energy_error(const train::Mlp<float> &net, const MapEnergy &me, const BentMaps &b, bool bend)
{
  const rdm::RdmMaps &maps = me.maps;
  const rdm::MapResolution &bins = maps.bins;
  const std::vector<double> &E = me.E;
  constexpr int kT = 32, kP = 64; /* exits: cos theta_o and phi_o stratified */
  double sum = 0.0, signed_sum = 0.0, weight = 0.0;
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
      const double domega = 4.0 * kPi / (kT * kP);
      for (int c = 0; c < 3; c++) {
        const double e_map = E[ii * 3 + size_t(c)];
        if (!(e_map > 0.0)) {
          continue;
        }
        const double e_net = double(Y.row(c).sum()) * domega;
        const double w = maps.incident_solid_angle(ti);
        sum += w * std::abs(e_net / e_map - 1.0);
        signed_sum += w * (e_net / e_map - 1.0);
        weight += w;
      }
    }
  }
  return weight > 0.0 ? EnergyError{sum / weight, signed_sum / weight} : EnergyError{};
}

}  // namespace

int main(int argc, char **argv)
{
  CLI::App app{"M conditioned on the bend against M pooled over bends, trained on straight and bent maps"};
  std::vector<std::string> specs;
  std::string out, samples_text = "4e6";
  int steps = 20000, batch = 4096, hidden = 21, threads = 0;
  uint64_t seed = 1;
  app.add_option("--maps", specs, "FILE (a bent gather's, which records its bend) or RADIUS:SECTOR:SECTORS:FILE "
                 "(radius 0: straight), checked against the file's record where it has one")->required();
  app.add_option("--samples", samples_text, "Training samples over all maps (validation: a tenth)");
  app.add_option("--steps", steps)->capture_default_str();
  app.add_option("--batch", batch)->capture_default_str();
  app.add_option("--hidden", hidden, "Hidden units of both layers")->capture_default_str();
  app.add_option("--threads", threads)->capture_default_str();
  app.add_option("--seed", seed, "Initial weights and mini-batches (the samples stay)")->capture_default_str();
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
      const train::Dataset tr = train::sample_multiple_scattering(maps, per_map, 1000 + 2 * i, false);
      const train::Dataset va = train::sample_multiple_scattering(maps, std::max(1, per_map / 10), 1001 + 2 * i, true);
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
    const train::Mlp<float> pool = train(6, tr_pool, va_pool, "pooled");
    std::printf("\nM energy per incident bin against each map's, mean |E_net / E_map - 1| (and E_net / E_map - 1),\n"
                "solid-angle weighted:\n");
    std::printf("%-8s %-10s %20s %20s\n", "radius", "sector", "conditioned", "pooled");
    for (size_t i = 0; i < sets.size(); i++) {
      const BentMaps &b = sets[i];
      const EnergyError c = energy_error(bent, energies[i], b, true), p = energy_error(pool, energies[i], b, false);
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
                        {"pooled", pool.to_flat()}};
    std::ofstream(out) << j.dump(1);
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "bench_bent_m: %s\n", e.what());
    return 1;
  }
  return 0;
}
