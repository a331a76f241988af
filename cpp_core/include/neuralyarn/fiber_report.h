// SPDX-License-Identifier: Apache-2.0
//
// What `neuralyarn fiber` reports about a fiber preset: its albedo as a function of the incident
// longitudinal angle (analytic, and by Monte Carlo through the sampler as a cross-check), the TT
// azimuth model compared with the authors' Gaussian (the picture of its lobe: plots.h).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "neuralyarn/presets.h"

namespace neuralyarn {

struct AlbedoRow {
  double theta_i_deg = 0.0;
  ny::Rgb fresnel{};     /* F_R(theta_i)                                     */
  ny::Rgb analytic{};    /* F + (1 - F) C_TT                                 */
  ny::Rgb mc_mean{};     /* mean sample weight: the same integral by sampling */
  ny::Rgb mc_stderr{};   /* its standard error                               */
  double p_R = 0.0;      /* probability that the sampler picks R             */
};

/* One row per incident angle (phi_i = 0). `samples` sample() calls per row, seeded with `seed`. */
std::vector<AlbedoRow> fiber_albedo_table(const FiberPreset &preset, const std::vector<double> &theta_i_deg,
                                          int samples, uint64_t seed);

/* The TT azimuth: the paper's von Mises (kappa = 1/gamma^2) against the authors' Gaussian (standard
 * deviation gamma, truncated to [-pi, pi] and renormalised), both as densities on the circle. */
struct AzimuthComparison {
  double gamma_rad = 0.0;
  double kappa = 0.0;
  double peak_von_mises = 0.0; /* density at phi_d = 0 */
  double peak_gaussian = 0.0;
  double l1_distance = 0.0;    /* integral |vM - Gaussian| d(phi), in [0, 2] */
};
AzimuthComparison compare_tt_azimuth(double gamma_rad);

}  // namespace neuralyarn
