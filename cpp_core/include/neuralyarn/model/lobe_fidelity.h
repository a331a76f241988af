// SPDX-License-Identifier: Apache-2.0
//
// The 4D fidelity of a model's lobes (issue 17): the R and M lobes compared with radiance distribution
// maps per (w_i, w_o) cell, not only their totals per w_i. A model can match every per-direction energy
// (the calibration table makes it do so) and still put that energy in the wrong directions; under uniform
// light nobody sees it, under a rim or back light everybody does.
//
// Both sides are binned the same way: energies (value x solid angle, summed) in cells of pooled map bins,
// averaged over the incident bins of a pooled incident group. The model side integrates over the map
// bins too: M (tens of degrees wide) at every map bin centre for 2 x 2 incident directions inside the
// incident bin; R (1-7 degrees wide, narrower than a map bin) by stratified sampling of its own lobe,
// which puts its exact energy into the cells it reaches.
//
// Measures, per theta_i row (summed over its phi_i groups, the three channels and all cells):
//   l1_raw      = sum |x - n| / sum n               n = the maps' mean (A, or (A + B) / 2)
//   noise_floor = sum |A - B| / 2 / sum n           the expected L1 distance of n from the truth
//                                                   (exact for Gaussian bin noise: E|A - B| / 2 = E|n - t|)
//   l1          = sum sqrt(max(0, (x - A)(x - B))) / sum n
// (x - A)(x - B) is an unbiased estimate of the squared error (x - t)^2 whatever the noise, so l1 is the
// model's energy-weighted relative L1 error with the map noise removed: to first order where the model
// error exceeds the noise; where the model is exact it reads 0.6 of the noise floor (the expectation of
// sqrt(max(0, e1 e2)) against that of |e1 + e2| / 2 for independent Gaussians), so the floor must stay well
// below the error one wants to resolve. Where it is, l1 reads the error slightly low and l1_raw slightly
// high, by about floor^2 / (2 error) each, and the truth lies between them (tests/cpp/test_lobe_fidelity.cpp:
// a 10 % error through a 1.4-3 % floor reads 9.3-9.8 % and 10.0-10.1 %). Without a second map, l1 = l1_raw.
// Energy ratios model / maps per band of the exit angle theta_o from the ply normal (30-degree bands,
// reflection 0-90, transmission 90-180), near the ply axis (w_o within 30 degrees of +-x) and near the
// forward direction (w_o within 12 degrees of -w_i) say where the energy goes wrong.
#pragma once

#include <array>
#include <functional>
#include <vector>

#include <nlohmann/json.hpp>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::model {

/* Incident directions per side of an incident bin in the R lobe's quadrature (the measure, the bake's shape fit
 * and its choice of free path): at 2 x 2 the R lobe's L1 against the maps is that of 4 x 4 within 0.6 point per
 * theta_i bin, at a third of the time (D48; docs/benchmarks.md, "Training speed"). */
constexpr int kRSub = 2;

/* Cells: map bins pooled to about this many degrees (in theta and phi, incident phi and both outgoing
 * angles); incident theta is never pooled (the report is per theta_i bin). */
struct LobePooling {
  double cell_deg = 12.0;
};

enum class Lobe { kR, kM };

/* Bands of the exit direction: theta_o from the ply normal in 30-degree steps, "axial", "forward" and
 * "through" (the last three overlap the others). Forward: within kLobeForwardDeg of -w_i, where grazing light
 * that scatters on along the fibers it grazes leaves in a narrow peak (docs/decisions.md D41). Through: w_i
 * and w_o both within kLobeThroughDeg of the plane normal to the ply axis, w_o on the far side of the ply
 * (w_o.z < 0): what a camera facing the ply sees of a light behind it. */
constexpr int kLobeBands = 9;
constexpr int kLobeAxialBand = 6;
constexpr int kLobeForwardBand = 7;
constexpr int kLobeThroughBand = 8;
constexpr double kLobeForwardDeg = 12.0;
constexpr double kLobeThroughDeg = 15.0;

/* Pooled energies of one lobe on one grid: [theta_i][phi_i group][cell][rgb] and the bands
 * [theta_i][phi_i group][band][rgb]. */
struct LobeGrid {
  rdm::MapResolution bins;
  int phi_i_groups = 0, theta_o_cells = 0, phi_o_cells = 0;
  std::vector<double> cells, bands;
  /* The map bins' centre directions in the entry frame, which the bands test (derived from `bins` once, not
   * per map bin): [theta_i][phi_i] and [theta_o][phi_o]. */
  std::vector<std::array<double, 3>> incident_dirs, outgoing_dirs;
  size_t groups() const { return size_t(bins.theta_i) * size_t(phi_i_groups); }
  size_t cells_per_group() const { return size_t(theta_o_cells) * size_t(phi_o_cells); }
  /* The cell of outgoing map bin (to, po) within a group. */
  size_t outgoing_cell(int to, int po) const;
};

/* An empty grid (zeros) for maps of resolution `bins`. */
LobeGrid make_lobe_grid(const rdm::MapResolution &bins, const LobePooling &pooling = {});

/* The maps' lobe (maps.r or maps.m) pooled. */
LobeGrid pool_map_lobe(const rdm::RdmMaps &maps, Lobe lobe, const LobePooling &pooling = {});

/* The model's lobe, integrated over the same bins and pooled (calibration included, as rendered). */
LobeGrid model_lobe_grid(const YarnModel &model, const rdm::MapResolution &bins, Lobe lobe,
                         const LobePooling &pooling = {});

/* Incident direction `s` of an n x n stratification of incident bin (ti, pi), uniform in solid angle. */
ny::Vec3 incident_sub_direction(const rdm::MapResolution &bins, int ti, int pi, int s, int n);

/* The R lobe of `p` integrated over the map bins for incident bin (ti, pi): kRSub x kRSub incident directions
 * inside the bin, each lobe node by node (kernel/yarn_bsdf.h), each node by 32 x 64 stratified samples of
 * each part of its own proposal (reflection:
 * truncated normal in theta~, uniform phi~ on the upper half; TT, where it has a share: the two truncated
 * normals), combined by the balance heuristic; add(to, po, energy) receives every sample's share of the
 * lobe's energy, averaged over the incident directions. Used by the measure and the R shape fit. */
void integrate_r_lobe(const ny::YarnBsdfParams &p, const rdm::MapResolution &bins, int ti, int pi,
                      const std::function<void(int to, int po, const ny::Rgb &energy)> &add);

/* The same integration with the lobe's two parts apart (kernel/yarn_bsdf.h yarn_eval_R_parts, each with the
 * lobe's whole weight over the number of nodes), the sample's azimuth phi~_o about its node's fiber and the
 * TT share tau of its incident direction: the R shape fit. */
void integrate_r_parts(const ny::YarnBsdfParams &p, const rdm::MapResolution &bins, int ti, int pi,
                       const std::function<void(int to, int po, float phi_f, const ny::Rgb &R, const ny::Rgb &TT,
                                                const ny::Rgb &tau)> &add);

/* Adds `value` (RGB, energy) of one map bin (ti, pi, to, po) to a grid, with weight `w`. */
void add_to_lobe_grid(LobeGrid *grid, int ti, int pi, int to, int po, const double value[3], double w);

struct LobeComparison {
  std::vector<double> theta_i_deg;       /* bin centres                               */
  std::vector<double> l1, l1_raw, noise_floor; /* per theta_i bin (noise_floor empty without B) */
  /* Per theta_i bin: model / maps energy per band (0 where the maps hold (almost) nothing). */
  std::vector<std::array<double, kLobeBands>> band_ratio;
  std::vector<std::array<double, kLobeBands>> band_share; /* the maps' energy share per band */
  std::vector<double> reflection_ratio, transmission_ratio; /* per theta_i bin                  */
  bool noise_removed = false;
  /* Worst l1 over the theta_i bins but the last (grazing), and the last one. */
  double l1_max_but_grazing = 0, l1_grazing = 0;
  nlohmann::json to_json() const;
};

/* Compares pooled grids: the model x against maps A and, if given, an independent B (same grid). */
LobeComparison compare_lobes(const LobeGrid &model, const LobeGrid &a, const LobeGrid *b = nullptr);

struct LobeFidelity {
  LobeComparison R, M;
  double seconds = 0;
  nlohmann::json to_json() const;
};

/* Both lobes of `model` against maps A (and an independent B of the same preset and resolution). */
LobeFidelity check_lobes(const YarnModel &model, const rdm::RdmMaps &a, const rdm::RdmMaps *b = nullptr,
                         const LobePooling &pooling = {});

}  // namespace neuralyarn::model
