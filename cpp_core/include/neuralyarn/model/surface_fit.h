// SPDX-License-Identifier: Apache-2.0
//
// The surface level's BSDF for stock Cycles (issue 18, docs/decisions.md D44): the cloth's measured far field
// (rdm/surface_gather.h) as built-in closures that any Blender renders — transparent() for what passes
// straight through the cloth, and a weighted sum of diffuse, translucent and GGX lobes about the surface
// normal, the weights functions of the view angle only (a shader never sees the light), one table per face:
//
//   sum_k W_k(cos theta_v) lobe_k(w_v, w_l),   T(cos theta_v) transparent().
//
// Per view bin the RGB weights are fitted to the measured maps over every light bin, as the fallback fits a
// ply's (model/fallback.h, D17): non-negative least squares of the relative error, |sum_k W_k lobe_k - D| /
// (D + eps) with eps = rel_eps E / 4 pi, under the constraint sum_k W_k albedo_k = E (E the view's scattered
// energy), so that uniform light returns the measured albedo for every view.
//
// A renderer reads the tables at x = kSurfaceFront * cos theta_v (front face) or kSurfaceBackStart + kSurfaceFront
// * cos theta_v (the back face, Cycles' Backfacing = 1): one curve over x in [0, 1] per lobe holds both faces
// (surface_curve), linear between the view bins' centres and beyond the end ones (clamped to the stored ranges).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "neuralyarn/model/cycles_lobes.h"
#include "neuralyarn/rdm/surface_gather.h"

namespace neuralyarn::model {

constexpr const char *kSurfaceFormat = "neuralyarn-surface 1";
constexpr double kSurfaceFront = 0.49, kSurfaceBackStart = 0.51;

struct SurfaceLobe {
  std::string closure; /* "diffuse", "translucent" or "ggx" */
  double alpha = 0.0;  /* ggx: Cycles' alpha (isotropic; the Glossy node's roughness is its square root) */
};

struct SurfaceBsdf {
  int view_bins = 0;
  std::vector<SurfaceLobe> lobes;
  std::vector<float> transparent; /* [side][view] */
  std::vector<float> W;           /* [side][view][lobe][rgb] */
  std::vector<float> albedo;      /* [side][view][rgb]: the measured scattered energy E (transparent apart) */
  std::vector<float> fit_error;   /* [side][view]: energy-weighted relative L1 of the fit against the maps */
  nlohmann::json source = nlohmann::json::object(); /* what was measured: model, patch, paths, seed */

  double view_cos(int view) const { return (view + 0.5) / view_bins; }
};

struct SurfaceFitOptions {
  std::vector<double> ggx_alphas = {0.2, 0.5, 1.0};
  double rel_eps = 0.25;
  int subsamples = 4; /* per bin and dimension: the lobes' mean over a bin */
};

SurfaceBsdf fit_surface(const rdm::SurfaceMaps &maps, const SurfaceFitOptions &options = {});

/* A lobe's f |cos theta_l| (Cycles' eval), view v and light l in the frame z = the normal on the viewer's side. */
double surface_lobe_eval(const SurfaceLobe &lobe, const cycles_lobes::Dir &v, const cycles_lobes::Dir &l);

/* The tables at a view cosine, as the renderer interpolates them: the transparent weight, then each lobe's RGB. */
struct SurfaceAt {
  double transparent = 0.0;
  std::vector<std::array<double, 3>> W;
};
SurfaceAt surface_at(const SurfaceBsdf &s, int side, double cos_v);

/* `samples` values of one curve over x in [0, 1] (both faces, see the top): lobe k's RGB weight, or with
 * k = -1 the transparent weight (grey). */
std::vector<std::array<double, 3>> surface_curve(const SurfaceBsdf &s, int k, int samples);

nlohmann::json surface_to_json(const SurfaceBsdf &s);
/* Validates everything; throws std::runtime_error starting with `where` and naming the key. */
SurfaceBsdf surface_from_json(const nlohmann::json &j, const std::string &where);
void save_surface(const SurfaceBsdf &s, const std::string &path);
SurfaceBsdf load_surface(const std::string &path);

}  // namespace neuralyarn::model
