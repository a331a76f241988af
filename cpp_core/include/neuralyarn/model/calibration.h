// SPDX-License-Identifier: Apache-2.0
//
// Energy calibration of a trained model (docs/decisions.md D16): per incident bin of the maps, the ratio
// of the map's R and M energies to what the R-energy and M networks integrate to there. The networks are
// small and smooth; they get the shape of the lobes right but not their energies (docs/benchmarks.md),
// which the renderer shows directly as a too bright or too dark cloth. The table
// (kernel/yarn_bsdf.h yarn_calibration, bilinear between bin centres) removes that error and keeps the
// networks' shapes.
#pragma once

#include <vector>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::model {

/* Ratios are clamped to this range; a bin where either energy is (nearly) zero gets 1. */
constexpr float kCalibrationMin = 0.01f, kCalibrationMax = 100.0f;

/* A midpoint grid of exit directions over the sphere: nt (even, so that the equator is a cell boundary)
 * rows in polar angle theta_o from the normal, np cells in azimuth, row-major, and each row's exact cell
 * solid angle. Built once and shared by every incident direction. */
struct ExitGrid {
  ExitGrid(int nt, int np);
  int theta_bins, phi_bins;
  std::vector<float> x, y, z; /* the directions' components */
  std::vector<double> solid_angle;
};

/* Exits the M network runs on at once on the host (model/mlp_lanes.h). */
constexpr int kMLanes = 16;

/* yarn_eval_M(p, l, w_o) at n <= kMLanes exits at once (x, y, z: their components, yarn frame), bit for bit
 * what the kernel gives for each alone (its network's lanes sum in the kernel's order; a two-sided network's
 * side is each exit's own). */
void yarn_eval_M_lanes(const ny::YarnBsdfParams &p, const ny::YarnLobes &l, int n, const float *x, const float *y,
                       const float *z, ny::Rgb *out);

/* The M lobe's energy (S_M |cos theta_o|, calibration included) by the midpoint rule on grid g: all in
 * `up`, or with `split` the upper hemisphere's (theta_o < 90 deg) in `up` and the lower's in `down`. Bit for
 * bit the sum of yarn_eval_M over the cells in row-major order (the network on 16 exits at once). */
void m_lobe_energy_split(const ny::YarnBsdfParams &p, const ny::YarnLobes &l, const ExitGrid &g, bool split,
                         double up[3], double down[3]);

/* Integral of the M lobe over the sphere on a fixed 64 x 128 grid, whatever the maps' resolution (M lobes
 * are tens of degrees wide). */
ny::Rgb m_lobe_energy(const ny::YarnBsdfParams &p, const ny::YarnLobes &l);

/* White furnace (after pbrt-v4's Hair.WhiteFurnace): the energy the model scatters from w_i under a uniform
 * white environment, P_T + the R lobe's exact energy (weight_R / 2) + the M lobe's integral. */
ny::Rgb white_furnace(const ny::YarnBsdfParams &p, const ny::Vec3 &wi);

/* Directions to evaluate the furnace at: sub x sub inside every incident cell of `bins` (uniform in cos
 * theta_i and phi_i; sub = 1: the bin centres, where the calibration table is bounded), and with `edge`
 * theta_i 89.975 deg at each phi_i bin centre (beyond the last centre the table is constant while the lobes
 * change; D26 holds it at the last row). */
std::vector<ny::Vec3> furnace_directions(const rdm::MapResolution &bins, int sub, bool edge);

/* The largest channel of white_furnace over `dirs`, and where (NaN, if any, wins). */
struct FurnaceMax {
  double value = 0.0;
  int index = -1; /* into dirs */
  ny::Vec3 wi{};
};
FurnaceMax white_furnace_max(const ny::YarnBsdfParams &p, const std::vector<ny::Vec3> &dirs, int threads = 0);

/* Directions per cell side at which bound_between_centres() evaluates the furnace. */
constexpr int kBoundSub = 5;

/* Incident bins on each side of a bin in the calibration's window over phi_i (same theta_i): about 20 degrees
 * in all, 5 of the paper's 90 bins, which divides the maps' per-bin noise by sqrt(5) and keeps the structure
 * at 20-degree scale; a single bin on maps of 10 degrees or coarser. */
int calibration_window_half(int phi_bins);

/* The table for `model` (its networks; its current table is ignored) on `maps` (same preset), at the maps'
 * incident resolution, bounded between its centres by bound_between_centres() at bound_sub (0: not, only
 * for tests of the centres themselves). */
EnergyCalibration calibrate_energy(const YarnModel &model, const rdm::RdmMaps &maps, int threads = 0,
                                   int bound_sub = kBoundSub);

/* Where bound_between_centres() evaluates the furnace: sub x sub directions, uniform in theta_i and phi_i, in
 * every cell between neighbouring centres of a theta_bins x phi_bins table (theta_i from 0, phi_i periodic),
 * and along the last row. */
std::vector<ny::Vec3> centre_cell_directions(int theta_bins, int phi_bins, int sub);

/* What bound_between_centres() changed: nodes whose c_R or c_M it lowered, and the smallest factor. */
struct CentreBound {
  int nodes = 0;
  double smallest = 1.0;
};

/* Bounds the model's calibration table between its centres (docs/decisions.md D28). The table is bounded at
 * its centres, but bilinear factors meet networks (P_T above all) that vary inside a cell, so P_T + E_R + E_M
 * exceeded 1 between them (cotton 1.047 at theta_i 86.6 deg). The furnace is evaluated at sub x sub
 * directions in every cell between neighbouring centres (below the first row, and along the last row, which
 * serves every w_i past it, D26); each node's c_R and c_M are multiplied, per channel, by the smallest factor
 * (1 - P_T) / (E_R + E_M) that any direction it weighs needs. Those energies are linear in the four nodes'
 * factors, so afterwards no evaluated direction scatters more than it receives; applying it twice changes
 * nothing. dP_T is untouched. */
CentreBound bound_between_centres(YarnModel *model, int sub = kBoundSub, int threads = 0);

}  // namespace neuralyarn::model
