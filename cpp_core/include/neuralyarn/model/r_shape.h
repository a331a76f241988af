// SPDX-License-Identifier: Apache-2.0
//
// Fits the R lobe's shape table (kernel/yarn_bsdf.h) to the R map: the azimuthal density nu(phi~_o | w_i) of
// its reflection part, for the surface fibers' mutual shadowing and masking that the fiber's uniform R
// azimuth does not have (docs/decisions.md D18), and the share tau(w_i) (RGB) of its TT part, the light
// that passes through one surface fiber and leaves upward (D21).
//
// Per table cell of incident directions and per channel, the R map is summed over cells of pooled
// outgoing bins (about 12 degrees), and so is the model's lobe (integrated over the same map bins as
// model/lobe_fidelity.h does) in na + 1 pieces: the reflection part with a uniform azimuth, split by the
// phi~_o bin each sample came from, and the TT part. A non-negative least-squares fit
//     map = sum_k b_k R_k + d TT
// gives both at once: tau = d E_TT / (d E_TT + sum_k b_k E_k) (E: the pieces' energies) and the
// reflection's relative density b_k, averaged over the channels and normalised (sum nu_k pi / n = 1), so
// the lobe's energy is unchanged. The two parts differ in their longitudinal width (beta_R against beta_TT)
// and azimuth (the reflection cone against the forward direction), which is what tells them apart. A phi~_o
// bin that the lobe hardly reaches keeps the row's mean; densities stay within 20x of uniform.
#pragma once

#include <Eigen/Dense>

#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::model {

struct RShapeOptions {
  int theta_bins = 11, phi_bins = 24, azimuth_bins = 16;
  bool fit_tt = true; /* false: tau = 0 (the reflection part only, as model layout 3) */
};

/* The R lobe's mean free path to its fiber (kernel/yarn_bsdf.h), in ply radii: a fraction
 * kRFreePathScale of the free path of a ray across the cross-section's fibers, pi / (2 sqrt(N rho)) (N
 * fibers of radius sqrt(rho / N) in a unit disc), chosen by measurement (docs/decisions.md D38). 0 for a
 * yarn-level model (not measured there). */
constexpr double kRFreePathScale = 0.6;
double r_free_path(const YarnModel &model);

/* The share of a yarn's visible ply surface whose fibers a yarn-level model's R nodes are, when the bake
 * chooses them (docs/decisions.md D51: the central 60 % fitted the maps better than all of it). */
constexpr double kRSurfaceSpread = 0.6;
/* The kernel array's R node frames (kYarnRNodes x kYarnRFrameStride floats, kernel/yarn_bsdf.h) for a
 * yarn-level model: the fibers of its plies' visible surface (geometry::visible_surface_frames of the
 * model's preset and structure, one packing), each frame's tangent T and normal N as the rotation
 * M R_x(a) P whose rows are T, N x T, N. Throws ParameterError for a ply-level model or a spread outside (0, 1]. */
std::vector<float> r_surface_frames(const YarnModel &model, double spread);
/* Sets a model's surface spread and the frames that follow from it (none for 0). */
void set_r_surface_spread(YarnModel *model, double spread);
/* An R node is the free path's or a surface fiber: ParameterError when both are asked for (> 0). */
void require_one_r_node_kind(double free_path, double surface_spread);

/* The table for `model` (its current table is ignored; its free path is used) on `maps` (same preset). */
RShapeTable fit_r_shape(const YarnModel &model, const rdm::RdmMaps &maps, const RShapeOptions &options = {});

/* min |A x - y|^2 subject to x >= 0, from the normal equations G = A^T A, h = A^T y (Lawson and Hanson's
 * active-set method). */
Eigen::VectorXd nonnegative_least_squares(const Eigen::MatrixXd &G, const Eigen::VectorXd &h);

}  // namespace neuralyarn::model
