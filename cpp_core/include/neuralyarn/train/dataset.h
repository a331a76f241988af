// SPDX-License-Identifier: Apache-2.0
//
// Training data drawn from the radiance distribution maps (issue 4): directions are sampled uniformly in
// solid angle (so the loss weighs every direction equally, not every bin), jittered within their bins, and
// paired with the bin's value. A deterministic tenth of the incident bins is held out for validation.
//
// Network inputs are Cartesian unit vectors in the entry (yarn-local) frame, x = ply axis, z = normal, as
// the paper and the authors' code use: T sees w_i (3 values), M sees (w_i, w_o) (6 values).
#pragma once

#include <cstdint>

#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/train/mlp.h"

namespace neuralyarn::train {

struct Dataset {
  Mlp<float>::Mat X; /* inputs, one column per sample  */
  Mlp<float>::Mat Y; /* targets, one column per sample */
};

/* True for the incident bins held out for validation (about one in ten, fixed by the bin index). */
bool is_validation_bin(const rdm::MapResolution &bins, int theta_i, int phi_i);

/* P(T | w_i) samples: w_i uniform over the upper hemisphere restricted to training (or validation) bins,
 * target the bin's P(T). */
Dataset sample_transmission(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation);

/* The unit vector of polar angle theta (from the normal) and azimuth phi = atan2(y, x) in the entry frame. */
Eigen::Vector3f entry_direction(double theta, double phi);

}  // namespace neuralyarn::train
