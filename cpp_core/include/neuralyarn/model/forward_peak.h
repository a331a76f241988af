// SPDX-License-Identifier: Apache-2.0
//
// The forward peak of the M lobe (docs/decisions.md D41). Light that grazes a ply scatters into the fibers
// it grazes and carries on along them: from theta_i ~ 75 deg on, a fifth to a half of the maps' M energy
// leaves within 12 degrees of straight on (-w_i), in a peak tens to hundreds of times the radiance around
// it, which the small M network renders at 0.5-0.9 of its energy and smears over its surroundings.
//
// This fits that peak per incident bin as a von Mises-Fisher lobe about -w_i,
//
//   S_fwd(w_i, w_o) = w(w_i) vMF(w_o; -w_i, kappa(w_i)),   vMF = kappa exp(kappa (cos psi - 1)) / (2 pi (1 - e^-2kappa)),
//
// w (RGB) its energy, on top of the maps' radiance around it: per incident bin, the excess over the mean
// radiance of the ring kRingDeg (12-20 degrees from -w_i) inside the cone (within 12 degrees), against the
// lobe integrated over the same map bins (the incident bin's extent included: the maps hold the peak
// blurred by it), least squares in w for each kappa of a log grid refined by golden sections. The sums run
// over a window of incident bins in phi_i (the calibration's, docs/decisions.md D16: ~20 degrees), because a
// bin holds a few thousand M paths. A window whose excess is not positive in luminance, or whose lobe does
// not reduce the excess's L1, gets w = 0.
//
// Or, `shape` = arc, as the surface fibers' own TT form (D41: grazing light that meets fibers tilted by the
// twist leaves on their cones, an arc through -w_i), in the surface-fiber frame (kernel/frames.h, the maps'
// surface twist):
//
//   S_fwd(w_i, w_o) = w(w_i) N(theta~_o; -theta~_i, beta) N(phi~_o; phi~_i + pi, gamma) / cos theta~_o,
//
// a normal in theta~ about the specular cone and a wrapped normal in azimuth about straight on, searched
// over a log grid of (beta, gamma).
//
// An instrument (`neuralyarn check --forward-peaks [spot|arc]`). With two maps the excess's own noise is
// reported beside: the share of the mean map's excess that no lobe can explain, half the L1 of the two
// maps' difference (docs/benchmarks.md).
#pragma once

#include <array>
#include <vector>

#include "neuralyarn/kernel/frames.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::model {

enum class ForwardShape { kSpot, kArc };

struct ForwardPeakOptions {
  ForwardShape shape = ForwardShape::kSpot;
  double beta_min_deg = 0.5, beta_max_deg = 16.0;   /* arc: the longitudinal width's search range */
  double gamma_min_deg = 1.0, gamma_max_deg = 60.0; /* arc: the azimuthal width's                */
  int arc_steps = 12;                               /* arc: log grid per width                    */
  double cone_deg = 12.0;                /* the peak's cone about -w_i                          */
  double ring_deg = 20.0;                /* its surroundings: cone_deg .. ring_deg              */
  double kappa_min = 30.0, kappa_max = 3000.0; /* the search range (1/sqrt(kappa): 10.5 .. 1.0 deg) */
  int kappa_steps = 24;                  /* log grid                                            */
  int sub = 3;                           /* sub-directions per side of an incident and outgoing bin */
  int threads = 0;
};

/* One incident bin's peak: its energy w (RGB, the M map's unit: S |cos theta_o| integrated over w_o), its
 * concentration, and how much of the cone's excess the lobe explains (1 - L1 of the residual / L1 of the
 * excess, luminance; 0 where w = 0). */
struct ForwardPeak {
  std::array<double, 3> w{0.0, 0.0, 0.0};
  double kappa = 0.0;             /* spot */
  double beta = 0.0, gamma = 0.0; /* arc, radians */
  double explained = 0.0;
  /* With two maps: 1 - (L1 of half their excesses' difference) / L1 of the mean's excess, the most any lobe
   * can explain of the mean map's noisy excess; -1 without. */
  double ceiling = -1.0;
};

struct ForwardPeakTable {
  int theta_bins = 0, phi_bins = 0;
  std::vector<ForwardPeak> peaks; /* [theta_i][phi_i] */
  const ForwardPeak &at(int ti, int pi) const { return peaks[size_t(ti) * size_t(phi_bins) + size_t(pi)]; }
};

/* Rec. 709 luminance of an RGB triple, as the evaluation harness weighs channels. */
double luminance(const double rgb[3]);

/* The von Mises-Fisher density on the sphere at cos psi from its mode, concentration kappa > 0. */
double vmf_density(double cos_psi, double kappa);

/* The unit-energy lobe about -w_i integrated over outgoing map bin (to, po) and averaged over incident bin
 * (ti, pi), sub x sub directions each. */
double forward_lobe_in_bin(const rdm::MapResolution &bins, int ti, int pi, int to, int po, double kappa, int sub);

/* The arc's unit-energy density in solid angle (wi_f, wo_f in the surface-fiber frame). */
double arc_density(const ny::Vec3 &wi_f, const ny::Vec3 &wo_f, double beta, double gamma);

/* The peaks of the maps' M lobe, one per incident bin; with `maps_b` (same resolution and preset) fitted to
 * the mean of both, and each bin's ceiling from their difference. Throws ParameterError for options out of
 * range or maps that do not match. */
ForwardPeakTable fit_forward_peaks(const rdm::RdmMaps &maps, const ForwardPeakOptions &options = {},
                                   const rdm::RdmMaps *maps_b = nullptr);

}  // namespace neuralyarn::model
