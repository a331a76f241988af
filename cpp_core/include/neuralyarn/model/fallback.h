// SPDX-License-Identifier: Apache-2.0
//
// View-dependent fallback tables for renderers that cannot run the neural yarn closure (stock Blender:
// the OSL fallback of osl/ and the addon's node-group fallback). Those can only weight built-in closures
// by functions of the view direction, because a shader never sees the light. By reciprocity the energy
// that reaches the viewer through each lobe equals that lobe's directional albedo with the view direction
// as the model's incident direction w_i, so the tables hold, per view direction in the yarn frame,
//
//   P_T       the transmission probability (calibration's dP_T included), the weight of transparent();
//   E_R       the R lobe's energy, integral of S_R |cos| over w_o: exactly c_R rho_R F(theta~_i) / 2
//             (kernel/yarn_bsdf.h; checked against quadrature around the specular cone in the tests);
//   E_M_up    the M lobe's energy that leaves through the upper hemisphere (w_o.n > 0),
//   E_M_down  and through the lower one (w_o.n < 0, the light that comes through the yarn from behind);
//
// all computed with the kernel functions exactly as the renderer evaluates them (yarn_lobes with the
// calibration table, yarn_eval_M). P_T + E_R + E_M_up + E_M_down is the model's albedo for that view.
//
// What the fallbacks render (version 2): P_T transparent() plus a weighted sum of built-in closures,
//
//   sum_k W_k(view) lobe_k,   lobes (fallback_lobes()): GGX about the surface fibers' tangent t_f with
//   alpha_x from beta_R, beta_M / 2, beta_M, 2.5 beta_M (none below kFallbackAlphaMin) and alpha_y = 1
//   (uniform in the half-vector's azimuth, like the model's R lobe), diffuse(n), translucent(n);
//
// with the RGB weights W_k fitted per view cell to the model's R + M lobes (yarn_eval_lobes) over all light
// directions: non-negative least squares of the *relative* error, |sum_k W_k lobe_k - S| / (S + eps) with
// eps = 0.1 E / 4 pi (E the view's R + M albedo), under the constraint sum_k W_k albedo_k = E (a heavily
// weighted row), so that under uniform light the fallback still returns the model's albedo for every
// view. Relative, not absolute, error: an absolute fit spends everything on the highlight's peak and
// leaves tails several times too bright, which covers most of a rendered yarn (docs/decisions.md D17).
//
// Cells: theta (longitudinal, asin(w.x)) and phi (azimuth about the tangent, atan2(w.y, w.z), 0 on the
// normal), both over (-90, 90) degrees, values at the cell centres
//   theta_i = -90 + (i + 1/2) 180 / theta_bins,   phi_j = -90 + (j + 1/2) 180 / phi_bins   (degrees),
// front-facing views only (a thick curve is only ever seen from |phi| < 90 degrees). Users interpolate
// bilinearly between centres and clamp at the edges.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "neuralyarn/model/cycles_lobes.h"

namespace neuralyarn::model {

struct YarnModel;

constexpr int kFallbackVersion = 2;

/* A built-in Cycles closure of the fallbacks (model/cycles_lobes.h). */
struct FallbackLobe {
  std::string closure; /* "ggx", "diffuse" or "translucent" */
  double alpha_x = 0.0, alpha_y = 0.0; /* ggx: roughness along t_f and across (Cycles' alpha) */
};

struct FallbackTables {
  int theta_bins = 18, phi_bins = 18;
  std::vector<float> P_T;      /* [theta][phi]      */
  std::vector<float> E_R;      /* [theta][phi][rgb] */
  std::vector<float> E_M_up;   /* [theta][phi][rgb] */
  std::vector<float> E_M_down; /* [theta][phi][rgb] */
  std::vector<FallbackLobe> lobes; /* fallback_lobes() of the scalars below */
  std::vector<float> W;            /* [theta][phi][lobe][rgb]: the fitted weights */

  /* Scalars the fallbacks need, copied from the model (radians). */
  double beta_R_rad = 0.0;      /* longitudinal width of the surface fibers' R lobe        */
  double twist_tilt_rad = 0.0;  /* phi~ = atan(pi alpha): surface-fiber tangent t_f = (cos, -sin, 0) */
  double beta_M_rad = 0.0;      /* M proxy: longitudinal width                              */
  double gamma_M_rad = 0.0;     /* M proxy: azimuthal width (von Mises concentration 1/gamma^2) */
  double kappa_M = 0.0;         /* M proxy: weight of the (theta, phi) lobe against uniform  */
  double kappa_M_up = 0.0;      /* the lobe's share of the proxy's mass in the upper hemisphere */
  std::array<double, 3> C_R{};  /* the surface fibers' R colour (linear RGB)               */

  /* FNV-1a 64 of the model's kernel_flat() bytes when the tables were computed: the loader uses it to
   * reject tables left stale by a later `fit` or a hand-edited model. */
  std::string kernel_flat_hash;

  size_t cells() const { return size_t(theta_bins) * size_t(phi_bins); }
  double theta_center(int i) const; /* radians */
  double phi_center(int j) const;   /* radians */
};

/* Quadrature of the M energies: midpoint rule on an nt x np grid of polar angle (from the normal) and
 * azimuth about the normal, exact cell solid angles; nt must be even so that the equator is a cell
 * boundary. The rule converges as h^2; the default grid is finer than model/calibration.h
 * m_lobe_energy's, within 0.1 % of the M energy (tests/cpp/test_fallback.cpp MQuadratureHasConverged). */
struct FallbackOptions {
  int theta_bins = 18, phi_bins = 18;
  int quad_theta = 256, quad_phi = 512;
  /* The weight fit: light directions on a fit_theta x fit_phi midpoint grid of the surface-fiber frame's
   * (theta, phi) (0.35 x 2.8 degrees: 3 cells per half width of silk's 1-degree R lobe), and the relative
   * error's eps as a fraction of the mean R + M value E / 4 pi. */
  int fit_theta = 512, fit_phi = 128;
  double fit_rel_eps = 0.1;
  int threads = 0; /* 0: all cores */
};

FallbackTables compute_fallback(const YarnModel &model, const FallbackOptions &options = {});

/* The narrowest GGX lobe a fallback uses: a stock GGX closure as narrow as a glossy fiber's R lobe renders
 * garments as glitter that the native closure does not show; the floor was chosen by measuring that
 * sparkle and the fallback's error per light (docs/decisions.md D60). */
constexpr double kFallbackAlphaMin = 0.1;

/* The lobes the weights refer to, from the scalars (beta_R_rad, beta_M_rad): alpha = 0.9147 beta gives a
 * GGX the half width at half maximum in theta_o of a Gaussian of width beta (the slope's half width
 * alpha sqrt(sqrt 2 - 1) doubled, against beta sqrt(2 ln 2)); clamped to [kFallbackAlphaMin, 1], the M
 * ladder's base (beta_M's alpha) to at least 2 kFallbackAlphaMin so that its three lobes stay distinct. */
std::vector<FallbackLobe> fallback_lobes(const FallbackTables &scalars);

/* A lobe's eval (f |cos theta_o|, Cycles' convention) and directional albedo, view v and light o in the
 * lobe frame (x = t_f, z = n): the fit's and the tests' one dispatch over the closures. */
double fallback_lobe_eval(const FallbackLobe &lobe, const cycles_lobes::Dir &v, const cycles_lobes::Dir &o);
/* n: the GGX albedo's quadrature (cycles_lobes::ggx_albedo). */
double fallback_lobe_albedo(const FallbackLobe &lobe, const cycles_lobes::Dir &v, int n = 256);

/* The fallback as stock Blender renders it (osl/neural_yarn_fallback.osl.in and the add-on's node body do
 * the same): the weights at the view interpolated bilinearly between cell centres and clamped at the
 * edges, each lobe in the surface fibers' frame (x = t_f, z = n). Directions in the yarn frame, both away
 * from the surface, `view` toward the viewer. */
struct FallbackAt {
  double P_T = 0.0;
  std::vector<double> W; /* [lobe][rgb] */
};
FallbackAt fallback_at(const FallbackTables &f, const cycles_lobes::Dir &view);
/* sum_k W_k(view) lobe_k(view, light): f |cos theta_light| per channel, as the renderer evaluates it. */
std::array<double, 3> fallback_eval(const FallbackTables &f, const cycles_lobes::Dir &view,
                                    const cycles_lobes::Dir &light);
/* What the fallback returns under a uniform white environment: P_T + sum_k W_k(view) albedo_k(view). */
std::array<double, 3> fallback_albedo(const FallbackTables &f, const cycles_lobes::Dir &view, int n = 256);

/* FNV-1a 64 of a float array's bytes, as 16 lowercase hex digits. */
std::string fnv1a64_hex(const std::vector<float> &values);

nlohmann::json fallback_to_json(const FallbackTables &f);
/* Validates sizes, ranges and finiteness and that the scalars and hash agree with `model` (whose other
 * parts are already loaded); throws ModelError naming the key, prefixed by `where`. The hash must be
 * `written_flat_hash` if given (the kernel array as the file holds it, in an older layout); the tables
 * returned name the model's array in the current layout. */
FallbackTables fallback_from_json(const nlohmann::json &j, const YarnModel &model, const std::string &where,
                                  const std::string *written_flat_hash = nullptr);

}  // namespace neuralyarn::model
