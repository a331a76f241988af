// SPDX-License-Identifier: Apache-2.0
//
// Fits the R lobe's azimuthal density nu(phi~_o | w_i) (kernel/yarn_bsdf.h yarn_r_azimuth) to the R map:
// the surface fibers' mutual shadowing and masking, which the fiber's uniform R azimuth does not have
// (docs/decisions.md D18).
//
// Per table cell of incident directions, the R map's energy and the uniform-azimuth lobe's energy (the
// model's own R lobe integrated over the same map bins by stratified sampling, as model/lobe_fidelity.h
// does) are summed per phi~_o bin of the map bins' centres; their ratio is the shape the uniform lobe
// lacks (binning effects cancel in it). Each row is then normalised (sum nu_k pi / n = 1), so the lobe's
// energy is unchanged. Ratios are clamped to [1/20, 20] against a row's mean and a phi~_o bin where the
// lobe puts (almost) nothing keeps the row's mean.
#pragma once

#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::model {

struct RAzimuthOptions {
  int theta_bins = 11, phi_bins = 24, azimuth_bins = 16;
};

/* The table for `model` (its current table is ignored) on `maps` (same preset). */
RAzimuthTable fit_r_azimuth(const YarnModel &model, const rdm::RdmMaps &maps, const RAzimuthOptions &options = {});

}  // namespace neuralyarn::model
