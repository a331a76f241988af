// SPDX-License-Identifier: Apache-2.0
//
// The built-in Cycles closures the stock-Blender fallbacks combine (model/fallback.h), evaluated on the
// host exactly as Cycles 4.x evaluates them, so that the fallback's lobe weights can be fitted to the
// model's BSDF. Written from the formulas (Walter et al. 2007, Heitz 2014), checked against Cycles'
// kernel/closure/bsdf_microfacet.h and bsdf_diffuse.h of Blender 4.3 (tests/cpp/test_fallback.cpp checks
// the normalisations by quadrature). Cycles' convention: both directions point away from the surface;
// `wi` is the view (sd->wi), `wo` the light; eval returns f |cos theta_o|.
//
// Local frame: x = the lobe's tangent T (alpha_x is along it), z = the shading normal N, y = z x x.
//
//   ggx: microfacet("ggx", N, T, alpha_x, alpha_y, eta, 0) in OSL, the Glossy BSDF (GGX, anisotropic) in
//        nodes. Single scattering, no Fresnel (Cycles' MicrofacetFresnel::NONE for that closure), height-
//        correlated Smith masking: f cos_o = D(h) / (4 cos_i (1 + Lambda(wi) + Lambda(wo))), zero unless both
//        directions are above N (and the geometric normal, equal to N on a thick curve);
//   diffuse: cos_o / pi above N;   translucent: |cos_o| / pi below N.
#pragma once

#include <algorithm>
#include <cmath>

#include "neuralyarn/units.h"

namespace neuralyarn::model::cycles_lobes {

struct Dir {
  double x, y, z;
};

/* Smith's Lambda of the anisotropic GGX distribution for direction v. */
inline double ggx_lambda(double ax, double ay, const Dir &v)
{
  const double t = (ax * ax * v.x * v.x + ay * ay * v.y * v.y) / std::max(v.z * v.z, 1e-300);
  return 0.5 * (std::sqrt(1.0 + t) - 1.0);
}

/* The anisotropic GGX normal distribution D(h), h a unit vector with h.z > 0. */
inline double ggx_D(double ax, double ay, const Dir &h)
{
  const double d = h.x * h.x / (ax * ax) + h.y * h.y / (ay * ay) + h.z * h.z;
  return 1.0 / (kPi * ax * ay * d * d);
}

inline double ggx_eval(double ax, double ay, const Dir &wi, const Dir &wo)
{
  if (!(wi.z > 0.0) || !(wo.z > 0.0)) {
    return 0.0;
  }
  Dir h{wi.x + wo.x, wi.y + wo.y, wi.z + wo.z};
  const double len = std::sqrt(h.x * h.x + h.y * h.y + h.z * h.z);
  if (!(len > 0.0)) {
    return 0.0;
  }
  h = {h.x / len, h.y / len, h.z / len};
  return ggx_D(ax, ay, h) / (4.0 * wi.z * (1.0 + ggx_lambda(ax, ay, wi) + ggx_lambda(ax, ay, wo)));
}

/* Directional albedo of ggx_eval for view wi: integral of ggx_eval over wo. Importance sampling of
 * D(h) h.z on an n x n stratified grid (deterministic): wo = reflect(wi, h), whose density is
 * D h.z / (4 |wi.h|), so each sample weighs G2 |wi.h| / (wi.z h.z). Converges to well below 0.1 % at
 * n = 256 for alpha_x down to 0.001 (the integrand is smooth in the half-vector's slope). */
inline double ggx_albedo(double ax, double ay, const Dir &wi, int n = 256)
{
  if (!(wi.z > 0.0)) {
    return 0.0;
  }
  const double li = ggx_lambda(ax, ay, wi);
  double sum = 0.0;
  for (int a = 0; a < n; a++) {
    const double u1 = (a + 0.5) / n;
    const double r = std::sqrt(u1 / (1.0 - u1)); /* the slope's radius of the unit GGX */
    for (int b = 0; b < n; b++) {
      const double ph = 2.0 * kPi * (b + 0.5) / n;
      Dir h{-ax * r * std::cos(ph), -ay * r * std::sin(ph), 1.0}; /* stretched slope -> normal */
      const double len = std::sqrt(h.x * h.x + h.y * h.y + 1.0);
      h = {h.x / len, h.y / len, h.z / len};
      const double vh = wi.x * h.x + wi.y * h.y + wi.z * h.z;
      if (!(vh > 0.0)) {
        continue;
      }
      const Dir wo{2.0 * vh * h.x - wi.x, 2.0 * vh * h.y - wi.y, 2.0 * vh * h.z - wi.z};
      if (!(wo.z > 0.0)) {
        continue;
      }
      sum += vh / (wi.z * h.z * (1.0 + li + ggx_lambda(ax, ay, wo)));
    }
  }
  return sum / (double(n) * n);
}

inline double diffuse_eval(const Dir &wo) { return std::max(wo.z, 0.0) / kPi; }
inline double translucent_eval(const Dir &wo) { return std::max(-wo.z, 0.0) / kPi; }

}  // namespace neuralyarn::model::cycles_lobes
