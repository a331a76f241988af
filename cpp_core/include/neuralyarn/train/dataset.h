// SPDX-License-Identifier: Apache-2.0
//
// Training data drawn from the radiance distribution maps (issue 4). Directions are sampled uniformly in
// solid angle (so the loss weighs every direction equally, not every bin, whose solid angles differ by
// 30x between pole and equator), jittered within their bins, and paired with the map's value there. A
// deterministic tenth of the incident bins is held out for validation.
//
// Network inputs are Cartesian unit vectors in the entry (yarn-local) frame, x = ply axis, z = normal, as
// the paper and the authors' code use: T and R see w_i (3 values), M sees (w_i, w_o) (6 values).
#pragma once

#include <cstdint>
#include <vector>

#include "neuralyarn/kernel/platform.h"
#include "neuralyarn/rdm/gather.h"
#include "neuralyarn/train/mlp.h"

namespace neuralyarn::train {

struct Dataset {
  Mlp<float>::Mat X; /* inputs, one column per sample  */
  Mlp<float>::Mat Y; /* targets, one column per sample */
};

/* True for the incident bins held out for validation (about one in ten, fixed by the bin index). */
bool is_validation_bin(const rdm::MapResolution &bins, int theta_i, int phi_i);

/* A function of w_i tabulated per incident bin (`channels` values per bin), sampled at n directions
 * uniform on the upper hemisphere restricted to training (or validation) bins that received paths. The
 * target is the bilinear interpolation between bin centres (clamped in theta, periodic in phi) when
 * `interpolate`, else the bin's own value. */
Dataset sample_incident_table(const rdm::RdmMaps &maps, const std::vector<float> &table, int channels, int n,
                              uint64_t seed, bool validation, bool interpolate);

/* P(T | w_i) (the map's p_t), bilinearly interpolated. */
Dataset sample_transmission(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation);

/* The R-energy factor rho_R per incident bin and channel, the R map's energy over the analytic lobe's at the bin
 * centre (kernel/yarn_bsdf.h, yarn_reflection_weight): one channel, their channel means over F(theta~_i) / 2 (the
 * colour left to F, a one-output network); three (RGB, decisions D65), each channel's energy over the channel mean
 * of F / 2. Other channel counts throw ParameterError. */
std::vector<float> reflection_scale_table(const rdm::RdmMaps &maps, int channels = 1);
Dataset sample_reflection_scale(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation, int channels = 1);

/* S_M |cos theta_o| samples: w_i uniform on the upper hemisphere (training or validation bins), w_o
 * uniform on the sphere, target the M map's RGB value of their bin. Two-sided (D45): six target rows, the
 * value in rows 0-2 where w_o leaves upward (z >= 0) and in rows 3-5 where it leaves downward, NaN (no
 * target) in the other three. */
Dataset sample_multiple_scattering(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation,
                                   bool two_sided = false);

/* The unit vector of polar angle theta (from the normal) and azimuth phi = atan2(y, x) in the entry frame. */
Eigen::Vector3f entry_direction(double theta, double phi);
/* The same as the kernel's vector, for evaluating the model's lobes there. */
ny::Vec3 entry_vec3(double theta, double phi);

}  // namespace neuralyarn::train
