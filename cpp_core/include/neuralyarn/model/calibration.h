// SPDX-License-Identifier: Apache-2.0
//
// Energy calibration of a trained model (docs/decisions.md D16): per incident bin of the maps, the ratio
// of the map's R and M energies to what the R-energy and M networks integrate to there. The networks are
// small and smooth; they get the shape of the lobes right but their energies were 4-8 % (R) and 9-24 % (M)
// off the maps, which the renderer sees directly as a too bright or too dark cloth. The table
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

/* Integral of the M lobe (S_M |cos theta_o|, calibration included) over the sphere: midpoint rule on a
 * fixed 64 x 128 (theta_o, phi_o) grid with exact cell solid angles, whatever the maps' resolution (M lobes
 * are tens of degrees wide). */
ny::Rgb m_lobe_energy(const ny::YarnBsdfParams &p, const ny::YarnLobes &l);

/* White furnace (after pbrt-v4's Hair.WhiteFurnace): the energy the model scatters from w_i under a uniform
 * white environment, P_T + the R lobe's exact energy (weight_R / 2) + the M lobe's integral. */
ny::Rgb white_furnace(const ny::YarnBsdfParams &p, const ny::Vec3 &wi);

/* Directions to evaluate the furnace at: sub x sub inside every incident cell of `bins` (uniform in cos
 * theta_i and phi_i; sub = 1: the bin centres, where the calibration table is bounded), and with `edge`
 * theta_i 89.975 deg at each phi_i bin centre (beyond the last centre the table is constant while the lobes
 * change). Between centres and at the edge the models still exceed 1 (docs/benchmarks.md, "Stability"). */
std::vector<ny::Vec3> furnace_directions(const rdm::MapResolution &bins, int sub, bool edge);

/* The largest channel of white_furnace over `dirs`, and where (NaN, if any, wins). */
struct FurnaceMax {
  double value = 0.0;
  int index = -1; /* into dirs */
  ny::Vec3 wi{};
};
FurnaceMax white_furnace_max(const ny::YarnBsdfParams &p, const std::vector<ny::Vec3> &dirs, int threads = 0);

/* The table for `model` (its networks; its current table is ignored) on `maps` (same preset), at the maps'
 * incident resolution. */
EnergyCalibration calibrate_energy(const YarnModel &model, const rdm::RdmMaps &maps, int threads = 0);

}  // namespace neuralyarn::model
