// SPDX-License-Identifier: Apache-2.0
// A synthetic neural yarn model for the tests: seeded random networks in a plausible output range and a
// small calibration table near identity, an R azimuth table far from uniform and the R lobe's nodes (used by test_yarn_bsdf.cpp
// and test_fallback.cpp).
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/model/r_shape.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/train/mlp.h"

namespace neuralyarn::testing {

/* A model with seeded random networks whose outputs sit in a plausible range (P_T ~ 0.1-0.5, rho_R ~ 1,
 * M ~ 0.05); `t_bias` moves the T network's output (-40: an opaque yarn, P_T ~ 0, with the calibration's
 * dP_T made 0 too); `m_outputs` 6 makes M two-sided (kernel/yarn_bsdf.h), `r_outputs` 3 the R network RGB (D65). */
inline model::YarnModel synthetic_model(const char *preset, uint64_t seed, double m_bias = -3.0, double t_bias = -1.0,
                                        int m_outputs = 3, int r_outputs = 1)
{
  model::YarnModel m;
  m.preset = find_preset(preset);
  auto make = [&](std::vector<int> widths, ny::MlpHead head, uint64_t s, double bias) {
    train::Mlp<float> net(train::MlpShape{widths, head}, s);
    train::Mlp<float>::Vec p = net.params() * 0.6f;
    const int out = widths.back();
    for (int c = 0; c < out; c++) {
      p(p.size() - out + c) += float(bias);
    }
    net.set_params(p);
    model::NetworkRecord r;
    r.shape = net.shape();
    r.flat = net.to_flat();
    return r;
  };
  m.T = make({3, 7, 7, 1}, ny::kMlpHeadSigmoid, seed, t_bias);
  m.R = make({3, 7, 7, r_outputs}, ny::kMlpHeadExp, seed + 1, 0.0);
  m.M = make({6, 21, 21, m_outputs}, ny::kMlpHeadExp, seed + 2, m_bias);
  m.proxy = {0.3, 0.35, 0.9, 0.7};
  m.albedo_M = {0.2, 0.3, 0.4};
  /* A 2 x 4 calibration table near identity, so every test also runs through yarn_calibration(). */
  m.calibration.theta_bins = 2;
  m.calibration.phi_bins = 4;
  std::mt19937 rng(static_cast<uint32_t>(seed));
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  for (int k = 0; k < 8; k++) {
    m.calibration.values.push_back(t_bias < -20.0 ? 0.0f : 0.05f * U(rng));
    for (int j = 1; j < ny::kYarnCalStride; j++) {
      m.calibration.values.push_back(1.0f + 0.2f * U(rng));
    }
  }
  /* A 2 x 4 x 6 R shape table, far from uniform (densities 0.1-1.9 times the mean) and with TT shares of
   * 0.1-0.9, so every test also runs through yarn_r_azimuth() and the TT part: each row normalised,
   * sum nu pi / 6 = 1. */
  m.r_shape.theta_bins = 2;
  m.r_shape.phi_bins = 4;
  m.r_shape.azimuth_bins = 6;
  for (int row = 0; row < 8; row++) {
    float v[6], sum = 0.0f;
    for (float &x : v) {
      x = 1.0f + 0.9f * U(rng);
      sum += x;
    }
    for (float x : v) {
      m.r_shape.values.push_back(x / (sum * 3.14159265f / 6.0f));
    }
    for (int c = 0; c < 3; c++) {
      m.r_shape.values.push_back(0.5f + 0.4f * U(rng));
    }
  }
  /* The R lobe's nodes (the bake's free path), so every test also runs through them; silk's untwisted
   * fibers included. */
  m.r_free_path = model::r_free_path(m);
  return m;
}

/* The same for a 3-ply yarn (ply twist 0.5, the shipped plying) whose R nodes are the fibers of its visible
 * ply surface (docs/decisions.md D51), the free path 0. */
inline model::YarnModel synthetic_yarn_model(const char *preset, uint64_t seed)
{
  model::YarnModel m = synthetic_model(preset, seed);
  m.structure.plies = 3;
  m.structure.ply_twist = 0.5;
  m.structure.surface_alpha = -0.1;
  m.r_free_path = 0.0;
  m.r_surface_spread = model::kRSurfaceSpread;
  m.r_frames = model::r_surface_frames(m, m.r_surface_spread);
  return m;
}

}  // namespace neuralyarn::testing
