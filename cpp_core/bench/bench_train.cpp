// SPDX-License-Identifier: Apache-2.0
//
// Training benchmarks (docs/benchmarks.md, "Training"):
//
//   bench_train --maps M.nyrdm                       time per epoch and loss of the M network (ours)
//   bench_train --maps M.nyrdm --export DIR          also writes the dataset and initial weights that
//                                                    scripts/bench_torch_train.py trains with PyTorch
//   bench_train --maps P.nyrdm --ablation            the paper's architecture x activation ablation
//
// The data is the M network's training set exactly as `neuralyarn train` builds it (targets normalised
// per channel); every run starts from the same seeded weights and uses the same batch schedule.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "neuralyarn/rdm/map_file.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/train/trainer.h"

using namespace neuralyarn;

namespace {

void normalise(train::Dataset *d, const Eigen::VectorXf &scale)
{
  for (int c = 0; c < d->Y.rows(); c++) {
    d->Y.row(c) /= scale(c);
  }
}

void write_raw(const std::string &path, const train::Mlp<float>::Mat &m)
{
  /* Column-major, one sample per column: row-major [samples][features] for numpy. */
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char *>(m.data()), std::streamsize(m.size() * sizeof(float)));
}

const char *act_name(train::Activation a)
{
  return a == train::Activation::kPrelu ? "PReLU" : a == train::Activation::kRelu ? "ReLU" : "ELU";
}

}  // namespace

int bench_main(int argc, char **argv)
{
  CLI::App app{"Training benchmarks"};
  std::string maps_path, widths = "6-21-21-3", export_dir;
  int samples = 2000000, batch = 4096, epochs = 5, threads = 0;
  float lr = 1e-2f;
  bool ablation = false;
  app.add_option("--maps", maps_path, "Map file")->required();
  app.add_option("--widths", widths)->capture_default_str();
  app.add_option("--samples", samples)->capture_default_str();
  app.add_option("--batch", batch)->capture_default_str();
  app.add_option("--epochs", epochs)->capture_default_str();
  app.add_option("--lr", lr)->capture_default_str();
  app.add_option("--threads", threads)->capture_default_str();
  app.add_option("--export", export_dir, "Write dataset + initial weights for the PyTorch script");
  app.add_flag("--ablation", ablation, "Architectures x activations of the paper's ablation");
  CLI11_PARSE(app, argc, argv);

  const rdm::RdmMaps maps = rdm::load_maps(maps_path);
  train::Dataset tr = train::sample_multiple_scattering(maps, samples, 1000004, false);
  train::Dataset va = train::sample_multiple_scattering(maps, samples / 10, 1000005, true);
  Eigen::VectorXf scale(3);
  for (int c = 0; c < 3; c++) {
    scale(c) = tr.Y.row(c).mean();
  }
  normalise(&tr, scale);
  normalise(&va, scale);
  const int steps_per_epoch = (samples + batch - 1) / batch;
  std::printf("maps %s (%s), %d samples, batch %d (%d steps per epoch), lr %g, threads %d\n", maps_path.c_str(),
              maps.preset.name.c_str(), samples, batch, steps_per_epoch, lr, threads);

  auto run = [&](const std::vector<int> &w, train::Activation act, int n_epochs, bool print_epoch) {
    train::MlpShape shape{w, ny::kMlpHeadExp, act};
    const train::Mlp<float> init(shape, 2);
    train::TrainOptions o;
    o.steps = n_epochs * steps_per_epoch;
    o.batch = batch;
    o.learning_rate = lr;
    o.final_learning_rate_fraction = 1.0f; /* constant, as the PyTorch side */
    o.threads = threads;
    o.initial = &init;
    o.record_every = 0;
    const auto t0 = std::chrono::steady_clock::now();
    const train::TrainResult r = train::train_network(shape, tr, va, o);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (print_epoch) {
      std::printf("ours  %-16s %-5s %2d epochs: %.3f s/epoch, final train loss %.4f, validation %.4f\n",
                  train::format_widths(w).c_str(), act_name(act), n_epochs, s / n_epochs, r.train_loss,
                  r.validation_loss);
    }
    return r;
  };

  if (!export_dir.empty()) {
    std::filesystem::create_directories(export_dir);
    write_raw(export_dir + "/X.f32", tr.X);
    write_raw(export_dir + "/Y.f32", tr.Y);
    write_raw(export_dir + "/Xv.f32", va.X);
    write_raw(export_dir + "/Yv.f32", va.Y);
    const train::Mlp<float> init(train::MlpShape{train::parse_widths(widths), ny::kMlpHeadExp}, 2);
    nlohmann::json j = {{"widths", train::parse_widths(widths)}, {"samples", samples}, {"validation", samples / 10},
                        {"batch", batch}, {"epochs", epochs}, {"lr", lr}, {"kernel_array", init.to_flat()}};
    std::ofstream(export_dir + "/setup.json") << j.dump(1);
    std::printf("exported the dataset and initial weights to %s\n", export_dir.c_str());
  }

  if (!ablation) {
    run(train::parse_widths(widths), train::Activation::kPrelu, epochs, true);
    return 0;
  }
  std::printf("\nablation (%d epochs each; loss = MSE of the per-channel-normalised M targets)\n", epochs);
  std::printf("%-18s %10s %10s %10s   params\n", "architecture", "PReLU", "ReLU", "ELU");
  for (const char *arch : {"6-21-64-64-21-3", "6-21-64-21-3", "6-21-21-3", "6-16-16-3"}) {
    const std::vector<int> w = train::parse_widths(arch);
    double loss[3];
    int k = 0;
    for (train::Activation a : {train::Activation::kPrelu, train::Activation::kRelu, train::Activation::kElu}) {
      loss[k++] = run(w, a, epochs, false).validation_loss;
    }
    std::printf("%-18s %10.4f %10.4f %10.4f   %d\n", arch, loss[0], loss[1], loss[2],
                ny::mlp_param_count(int(w.size()) - 1, w.data()) - int(w.size()) - 2);
    std::fflush(stdout);
  }
  return 0;
}

int main(int argc, char **argv)
{
  /* A map file that cannot be read or widths the maps cannot train: the message and a non-zero exit. */
  try {
    return bench_main(argc, argv);
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "bench_train: error: %s\n", e.what());
    return 1;
  }
}
