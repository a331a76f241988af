// SPDX-License-Identifier: Apache-2.0
//
// The aggregated yarn BSDF of the paper (Sec. 3), done as the paper writes it:
//
//   S(w_i, w_o) = S_T + S_R + S_M
//   S_T = P_T(w_i) delta(w_i + w_o)                                  a true delta transmission lobe
//   S_R = rho_R(w_i) [(1 - tau) S_f^R + tau S_f^TT](w~_i, w~_o)   if w_i.n > 0 and w_o.n > 0, else 0
//   S_M = c_M(w_i) e(w_i) MLP_M(w_i, w_o),  e = max(1 - P_T(w_i), e_min)   (models S_M |cos theta_o|)
//         a two-sided MLP_M (6 -> 6) gives the upward exits (w_o.z >= 0) in outputs 0-2, the downward in 3-5
//
// in the yarn frame of frames.h (x = yarn tangent, z = normal of the bounding cylinder), w~ = M w the
// surface-fiber frame rotated by phi~ = atan(pi alpha) about n. S_f^R is the R lobe of the Khungurn
// fiber BSDF (fiber_bsdf.h with C_TT = 0), S_f^TT its TT lobe (the light that passes through one surface
// fiber and leaves upward: the maps' "R" is any single event, docs/decisions.md D21), both restricted to
// the upper half of the azimuths and each normalised to half the energy. The paper weights R by 1 - P_T(w_i); measured against the
// gathered R map that factor is off by 0.6x at normal incidence to 6x at grazing incidence, so rho_R(w_i)
// is a third tiny network (exp head) trained on the map's R energy: the lobe's energy is exactly
// rho_R F(theta~_i) / 2 (docs/decisions.md D13). With one output (3-7-7-1) the energy's colour is the Fresnel
// factor's, F of the fiber's C_R; with three (3-7-7-3, decisions D65) the network carries the colour, rho_R (RGB)
// times the channel mean of F: the map's single events include the light that passes through a surface fiber
// (tinted by C_TT, not C_R), which for silk's C_R (0.745, 0.008, 0.07) makes the maps' green 16x F's toward
// grazing light, a colour a scalar network could only leave to the calibration. The M network learns
// S_M |cos| / (1 - P_T): the M energy falls from 0.3 to 0.04 within 15 degrees of grazing because the light
// passes through, which the T network already captures; divided by it, M is smooth there (D15).
//
// An energy calibration table over the maps' incident bins, bilinear in (theta_i, phi_i), corrects the
// three energies per incident direction: dP_T is added to P_T, c_R (RGB) multiplies the R weight, c_M (RGB) the M
// network. It is computed once at bake time (model/calibration.h) from the maps' energies against the
// networks' at each incident bin centre. The networks give the shape of the lobes and are smooth; their
// energies are off the maps by more than a renderer may show as a too bright or too dark cloth; the
// table removes that (docs/decisions.md D16). A model without a
// table (zero bins) uses dP_T = 0, c = 1.
//
// The R lobe's azimuth: the fiber's own R lobe is uniform in azimuth about the fiber, but in a ply the
// surface fibers shadow and mask each other, so the maps hold 0.7x the uniform lobe's share near the normal
// and 1.5-2x less toward grazing exits, and the other way round for grazing light (docs/decisions.md D18).
// An optional table holds the azimuthal density nu(phi~_o | w_i) over the upper half of phi~_o in
// [-pi/2, pi/2], fitted to the R map at bake time (model/r_shape.h): linear between bin centres and flat
// at both ends, each row normalised so that its integral is exactly 1, and bilinear in w_i; the uniform
// lobe's 1/pi is replaced by nu. The lobe's energy stays exactly rho_R F / 2 (a mixture of normalised rows
// is normalised), so the calibration and every energy of the model are unchanged by it.
//
// The TT share tau (RGB, on the same rows): for grazing light up to 0.7 of the maps' single events pass
// through a surface fiber (forward, near the horizon, tinted by C_TT) instead of reflecting off it. S_f^TT
// is the fiber's own: gbar(theta~_o; -theta~_i, beta_TT) longitudinally and a normal of width gamma_TT
// about the forward azimuth phi~_i + pi, truncated to the upper half and normalised there. Where that
// azimuth is so far below the horizon that the truncated normal holds no float mass, tau is 0. Both
// parts hold rho_R F / 2, so the energy identity above holds for any tau.
//
// The R lobe's fiber is not the surface fiber under the entry point (docs/decisions.md D38). Light entering
// the ply travels a free path s before its first event, s ~ Exp(lambda) (lambda: the model's free path, in
// ply radii). The fiber it meets sits deeper, where the helices are less tilted (twist alpha (1 - s w_i.z)),
// and around the ply's circumference by an angle a = -w_i.y s, where the ply's normal is rotated by a about
// the axis. So S_R is the mean of the single-fiber lobe over kYarnRNodes such fibers (s at the midpoints of
// Exp(lambda)'s quantiles), each in its own frame: w -> M(alpha (1 - s w_i.z)) R_x(a) w. Every node's lobe
// holds rho_R F / 2, so their mean does, exactly. Azimuth table rows are those of w_i. lambda = 0: one node,
// the surface fiber (layouts before 5). A yarn-level model may carry its nodes' own frames instead (layout 6,
// docs/decisions.md D51): the fibers of the plies' visible surface, whose normals turn over the ridges and whose
// fibers slope out of the envelope's plane, each w -> M_q R_x(a_q) P_q w from the array (lambda is then 0).
//
// Both arguments point away from the surface. The first is the direction the maps call incident (the
// light side when the maps were gathered; a path tracer passes the direction toward the previous vertex,
// using reciprocity), the second the one that is evaluated or sampled. eval returns S |cos theta_o|, the
// map's own quantity, without the delta lobe.
//
// Importance sampling (paper Sec. 3.4), with the fixes of docs/decisions.md D12:
//   lobe T with p_T = P_T(w_i), R with (1 - p_T) kappa_R, M with (1 - p_T)(1 - kappa_R);
//   R: with q_TT (tau's share of the R energy) the TT part: theta~_o ~ TN(-theta~_i, beta_TT), phi~_o ~ the
//      truncated normal above; otherwise theta~_o ~ TN(-theta~_i, beta_R) on [-pi/2, pi/2], phi~_o uniform
//      on the upper half [-pi/2, pi/2];
//   M: with kappa_M, theta~_o ~ TN(-theta~_i, beta_M), phi~_o ~ vonMises(0, gamma_M^-2) (centred on n);
//      otherwise uniform on the sphere.
// Every density is in the surface-fiber frame (the rotation about n preserves solid angle), and the fit
// (host code, fit/proxy.h) uses exactly these functions. The non-delta pdf is returned *conditional on
// not choosing T*, i.e. it integrates to 1; the full mixture density is (1 - p_T) times it. That is what
// both users need: a renderer that keeps T as a separate transparent closure (Cycles) uses the
// conditional pdf directly, and yarn_sample() reports the selection probability alongside.
//
// The networks are read from a flat float array (kernel/mlp.h layout) whose header is described at
// yarn_params_from_flat(); the Cycles patch uploads exactly this array to a lookup table.
#pragma once

#include "fiber_bsdf.h"
#include "frames.h"
#include "mlp.h"
#include "platform.h"
#include "sampling.h"

namespace ny {

/* Layout of the model's flat array (all floats; counts and offsets are exact integers below 2^24). */
enum YarnFlatField {
  kYarnFlatVersion = 0,   /* kYarnFlatFormat                                                  */
  kYarnFlatSize = 1,      /* total number of floats                                           */
  kYarnFlatAlpha = 2,     /* twist alpha                                                      */
  kYarnFlatC_R = 3,       /* 3 floats: the surface fibers' C_R                                */
  kYarnFlatBeta_R = 6,    /* radians                                                          */
  kYarnFlatKappa_R = 7,   /* P(R | not T)                                                     */
  kYarnFlatBeta_M = 8,    /* radians                                                          */
  kYarnFlatGamma_M = 9,   /* radians (von Mises concentration 1 / gamma_M^2)                  */
  kYarnFlatKappa_M = 10,  /* weight of the (theta, phi) lobe inside M                         */
  kYarnFlatAlbedo_M = 11, /* 3 floats: M albedo averaged over w_i (a closure-weight estimate) */
  kYarnFlatOffset_T = 14, /* offset of the T network                                          */
  kYarnFlatOffset_R = 15, /* offset of the R-energy network                                   */
  kYarnFlatOffset_M = 16, /* offset of the M network                                          */
  kYarnFlatOffset_Cal = 17,   /* offset of the calibration table ([theta_i][phi_i][dP_T, c_R rgb, c_M rgb]) */
  kYarnFlatCalThetaBins = 18, /* its bins over theta_i in [0, pi/2] (0: no table)                 */
  kYarnFlatCalPhiBins = 19,   /* its bins over phi_i in [-pi, pi)                                 */
  kYarnFlatOffset_Az = 20,    /* offset of the R azimuth table ([theta_i][phi_i][phi~_o] densities)  */
  kYarnFlatAzThetaBins = 21,  /* its bins over theta_i in [0, pi/2] (0: no table, uniform azimuth)  */
  kYarnFlatAzPhiBins = 22,    /* its bins over phi_i in [-pi, pi)                                 */
  kYarnFlatAzBins = 23,       /* its bins over phi~_o in [-pi/2, pi/2]; a row is those densities and tau rgb */
  kYarnFlatBeta_TT = 24,      /* radians: the surface fibers' TT lobe (R part's TT share)         */
  kYarnFlatGamma_TT = 25,     /* radians                                                          */
  kYarnFlatFreePath = 26,     /* lambda: the R lobe's mean free path to its fiber, ply radii (0: surface fiber) */
  kYarnFlatOffset_RFrames = 27, /* offset of the R nodes' own frames (kYarnRNodes x kYarnRFrameStride), 0: none */
  kYarnFlatHeader = 28
};
constexpr float kYarnFlatFormat = 6.0f;
/* The R lobe's fibers when the free path is positive (one, the surface fiber, when it is 0). */
constexpr int kYarnRNodes = 4;
/* Node q's free path over lambda: the midpoint of Exp(1)'s q-th quantile, -log(1 - (q + 1/2) / kYarnRNodes)
 * (a function, not a table: device code reads no namespace-scope arrays). */
NY_KERNEL_FN float yarn_r_node_path(int q)
{
  return q == 0 ? 0.13353139f : q == 1 ? 0.47000363f : q == 2 ? 0.98082925f : 2.07944154f;
}
/* Floats per R node frame: the node's rotation w -> M_q R_x(a_q) P_q w as three (cos, sin) pairs, P_q and M_q about
 * the yarn normal (as the twist M), R_x about the yarn axis: P_q (c, s), a_q (c, s), M_q (c, s). */
constexpr int kYarnRFrameStride = 6;
/* Largest free path a model may carry (ply radii). */
constexpr float kYarnMaxFreePath = 2.0f;
constexpr int kYarnCalStride = 7; /* dP_T, c_R.r, c_R.g, c_R.b, c_M.r, c_M.g, c_M.b */

/* Floats per row of the R shape table: az_bins densities nu, then tau r, g, b. */
NY_KERNEL_FN int yarn_r_shape_stride(int az_bins) { return az_bins + 3; }

struct YarnBsdfParams {
  NY_GLOBAL const float *net_T; /* 3 -> 1, sigmoid head: P_T(w_i)          */
  NY_GLOBAL const float *net_R; /* 3 -> 1 or 3 -> 3 (RGB), exp head: rho_R(w_i) */
  bool r_rgb;                   /* net_R has three outputs: the R energy's colour is the network's (D65) */
  NY_GLOBAL const float *net_M; /* 6 -> 3 or two-sided 6 -> 6, exp head: S_M |cos theta_o| */
  bool m_two_sided;
  TwistRotation twist;
  float alpha;     /* the surface fibers' twist, from which the R nodes' twists follow */
  float free_path; /* lambda, ply radii */
  NY_GLOBAL const float *r_frames; /* the R nodes' own frames (a yarn's visible ply surface, D51), or null */
  FiberBsdfParams fiber; /* C_R, beta_R of the surface fibers; C_TT = 0 (R only) */
  float kappa_R;
  float beta_M, gamma_M, kappa_M;
  Rgb albedo_M;
  NY_GLOBAL const float *cal; /* energy calibration table, or null */
  int cal_theta_bins, cal_phi_bins;
  NY_GLOBAL const float *az;  /* R shape table (azimuth densities, TT share), or null (uniform azimuth, no TT) */
  int az_theta_bins, az_phi_bins, az_bins;
};

/* The validation of a flat array runs on the host, before a renderer uploads it (its messages are string
 * literals, which a device's address spaces do not take as `const char *`). */
#ifndef NY_KERNEL_DEVICE

/* Checks one network of a flat array: the header at `offset`, its size within [offset, end), its input and
 * output widths and head. */
NY_KERNEL_FN bool yarn_flat_network_ok(NY_GLOBAL const float *f, int offset, int end, int inputs, int outputs, int head)
{
  if (offset < kYarnFlatHeader + (f[kYarnFlatOffset_RFrames] != 0.0f ? kYarnRNodes * kYarnRFrameStride : 0) ||
      offset + 3 > end)
  {
    return false;
  }
  const float Lf = f[offset];
  if (!(Lf >= 1.0f && Lf <= (float)kMlpMaxLayers) || Lf != (float)(int)Lf || offset + (int)Lf + 3 > end) {
    return false;
  }
  const int L = (int)Lf;
  int widths[kMlpMaxLayers + 1];
  for (int l = 0; l <= L; l++) {
    const float w = f[offset + 1 + l];
    if (!(w >= 1.0f && w <= (float)kMlpMaxWidth) || w != (float)(int)w) {
      return false;
    }
    widths[l] = (int)w;
  }
  return widths[0] == inputs && widths[L] == outputs && f[offset + L + 2] == (float)head &&
         offset + mlp_param_count(L, widths) <= end;
}

/* Validates a flat array of n floats before a renderer uploads it (everything yarn_params_from_flat() and
 * the evaluation rely on). Returns null if it is valid, otherwise what is wrong. */
NY_KERNEL_FN const char *yarn_flat_check(NY_GLOBAL const float *f, int n)
{
  if (n < kYarnFlatHeader) {
    return "shorter than the header";
  }
  for (int i = 0; i < n; i++) {
    if (!is_finite(f[i])) {
      return "holds a non-finite number";
    }
  }
  if (f[kYarnFlatVersion] != kYarnFlatFormat) {
    return "has another layout version than this build reads";
  }
  if (f[kYarnFlatSize] != (float)n) {
    return "its size field disagrees with its length";
  }
  if (!(f[kYarnFlatKappa_R] >= 0.0f && f[kYarnFlatKappa_R] <= 1.0f && f[kYarnFlatKappa_M] >= 0.0f &&
        f[kYarnFlatKappa_M] <= 1.0f && f[kYarnFlatBeta_R] > 0.0f && f[kYarnFlatBeta_M] > 0.0f &&
        f[kYarnFlatGamma_M] > 0.0f && f[kYarnFlatBeta_TT] > 0.0f && f[kYarnFlatGamma_TT] > 0.0f &&
        f[kYarnFlatFreePath] >= 0.0f && f[kYarnFlatFreePath] <= kYarnMaxFreePath))
  {
    return "has sampling parameters out of range";
  }
  const float oF = f[kYarnFlatOffset_RFrames];
  if (oF != 0.0f) {
    /* Each node's frame is the free path's or its own: not both. */
    if (oF != (float)kYarnFlatHeader || f[kYarnFlatFreePath] != 0.0f ||
        kYarnFlatHeader + kYarnRNodes * kYarnRFrameStride > n ||
        !(f[kYarnFlatOffset_T] >= oF + (float)(kYarnRNodes * kYarnRFrameStride)))
    {
      return "has R node frames out of place";
    }
    for (int i = 0; i < kYarnRNodes * kYarnRFrameStride; i += 2) {
      const float c = f[kYarnFlatHeader + i], sn = f[kYarnFlatHeader + i + 1];
      if (!(fabsf(c * c + sn * sn - 1.0f) <= 1e-4f)) {
        return "has an R node frame that is not a rotation";
      }
    }
  }
  const float oT = f[kYarnFlatOffset_T], oR = f[kYarnFlatOffset_R], oM = f[kYarnFlatOffset_M],
              oC = f[kYarnFlatOffset_Cal], oA = f[kYarnFlatOffset_Az];
  if (!(oT >= 0.0f && oT <= oR && oR <= oM && oM <= oC && oC <= oA && oA <= (float)n) || oA != (float)(int)oA) {
    return "has network offsets out of order";
  }
  if (!yarn_flat_network_ok(f, (int)oT, (int)oR, 3, 1, kMlpHeadSigmoid)) {
    return "has a malformed T network (3 -> 1, sigmoid head)";
  }
  if (!yarn_flat_network_ok(f, (int)oR, (int)oM, 3, 1, kMlpHeadExp) &&
      !yarn_flat_network_ok(f, (int)oR, (int)oM, 3, 3, kMlpHeadExp))
  {
    return "has a malformed R network (3 -> 1 or 3 -> 3, exp head)";
  }
  if (!yarn_flat_network_ok(f, (int)oM, (int)oC, 6, 3, kMlpHeadExp) &&
      !yarn_flat_network_ok(f, (int)oM, (int)oC, 6, 6, kMlpHeadExp))
  {
    return "has a malformed M network (6 -> 3 or 6 -> 6, exp head)";
  }
  const float nt = f[kYarnFlatCalThetaBins], np = f[kYarnFlatCalPhiBins];
  if (!(nt >= 0.0f && np >= 0.0f && nt <= 4096.0f && np <= 4096.0f) || nt != (float)(int)nt ||
      np != (float)(int)np || (int)oC + (int)nt * (int)np * kYarnCalStride != (int)oA)
  {
    return "has a calibration table of the wrong size";
  }
  const float at = f[kYarnFlatAzThetaBins], ap = f[kYarnFlatAzPhiBins], ab = f[kYarnFlatAzBins];
  const bool no_table = at == 0.0f && ap == 0.0f && ab == 0.0f;
  if (!no_table && (!(at >= 1.0f && ap >= 1.0f && ab >= 2.0f && at <= 1024.0f && ap <= 1024.0f && ab <= 1024.0f) ||
                    at != (float)(int)at || ap != (float)(int)ap || ab != (float)(int)ab))
  {
    return "has an R azimuth table of the wrong shape";
  }
  const int stride = yarn_r_shape_stride((int)ab);
  if ((int)oA + (no_table ? 0 : (int)at * (int)ap * stride) != n) {
    return "has an R azimuth table of the wrong size";
  }
  for (int i = (int)oA; i < n; i++) {
    if (!(f[i] >= 0.0f)) {
      return "has a negative R azimuth density";
    }
    if ((i - (int)oA) % stride >= (int)ab && !(f[i] <= 1.0f)) {
      return "has an R TT share above 1";
    }
  }
  return nullptr;
}

/* Fields an older layout's header lacks: layout 4 the free path and the R node frames' offset, layout 5 the
 * offset; 0 for this layout or any other. */
NY_KERNEL_FN int yarn_flat_missing_fields(NY_GLOBAL const float *f, int n)
{
  if (n < 1) {
    return 0;
  }
  return f[kYarnFlatVersion] == 4.0f ? 2 : f[kYarnFlatVersion] == 5.0f ? 1 : 0;
}

/* A layout 4 or 5 array as this layout: `out` (n + yarn_flat_missing_fields floats) gets the missing fields
 * as 0 (free path 0, no node frames) at the header's end and every offset and the size moved past them. It
 * renders exactly as the older array did. Returns false, leaving `out` alone, if `f` is not a layout 4 or 5
 * array whose offsets lie in it. */
NY_KERNEL_FN bool yarn_flat_upgrade(NY_GLOBAL const float *f, int n, float *out)
{
  const int missing = yarn_flat_missing_fields(f, n);
  const int header_old = kYarnFlatHeader - missing;
  if (missing == 0 || n < header_old || f[kYarnFlatSize] != (float)n) {
    return false;
  }
  const int offsets[5] = {kYarnFlatOffset_T, kYarnFlatOffset_R, kYarnFlatOffset_M, kYarnFlatOffset_Cal,
                          kYarnFlatOffset_Az};
  for (int k = 0; k < 5; k++) {
    if (!(f[offsets[k]] >= (float)header_old && f[offsets[k]] <= (float)n)) {
      return false;
    }
  }
  for (int i = 0; i < header_old; i++) {
    out[i] = f[i];
  }
  for (int i = header_old; i < kYarnFlatHeader; i++) {
    out[i] = 0.0f;
  }
  for (int i = header_old; i < n; i++) {
    out[i + missing] = f[i];
  }
  out[kYarnFlatVersion] = kYarnFlatFormat;
  out[kYarnFlatSize] = (float)(n + missing);
  for (int k = 0; k < 5; k++) {
    out[offsets[k]] = f[offsets[k]] + (float)missing;
  }
  return true;
}

#endif /* NY_KERNEL_DEVICE */

/* Reads the parameters from a flat array that the host has validated (model/model.h does). */
NY_KERNEL_FN YarnBsdfParams yarn_params_from_flat(NY_GLOBAL const float *f)
{
  YarnBsdfParams p;
  p.net_T = f + (int)f[kYarnFlatOffset_T];
  p.net_R = f + (int)f[kYarnFlatOffset_R];
  p.r_rgb = p.net_R[(int)p.net_R[0] + 1] == 3.0f; /* its output width (validated: 1 or 3) */
  p.net_M = f + (int)f[kYarnFlatOffset_M];
  p.m_two_sided = p.net_M[(int)p.net_M[0] + 1] == 6.0f; /* its output width (validated: 3 or 6) */
  p.twist = make_twist_rotation(f[kYarnFlatAlpha]);
  p.alpha = f[kYarnFlatAlpha];
  p.free_path = f[kYarnFlatFreePath];
  p.r_frames = f[kYarnFlatOffset_RFrames] != 0.0f ? f + (int)f[kYarnFlatOffset_RFrames] : nullptr;
  p.fiber.C_R = make_rgb(f[kYarnFlatC_R], f[kYarnFlatC_R + 1], f[kYarnFlatC_R + 2]);
  p.fiber.C_TT = make_rgb(0.0f);
  p.fiber.beta_R = f[kYarnFlatBeta_R];
  p.fiber.beta_TT = f[kYarnFlatBeta_TT];
  p.fiber.gamma_TT = f[kYarnFlatGamma_TT];
  p.kappa_R = f[kYarnFlatKappa_R];
  p.beta_M = f[kYarnFlatBeta_M];
  p.gamma_M = f[kYarnFlatGamma_M];
  p.kappa_M = f[kYarnFlatKappa_M];
  p.albedo_M = make_rgb(f[kYarnFlatAlbedo_M], f[kYarnFlatAlbedo_M + 1], f[kYarnFlatAlbedo_M + 2]);
  p.cal_theta_bins = (int)f[kYarnFlatCalThetaBins];
  p.cal_phi_bins = (int)f[kYarnFlatCalPhiBins];
  p.cal = (p.cal_theta_bins > 0 && p.cal_phi_bins > 0) ? f + (int)f[kYarnFlatOffset_Cal] : nullptr;
  p.az_theta_bins = (int)f[kYarnFlatAzThetaBins];
  p.az_phi_bins = (int)f[kYarnFlatAzPhiBins];
  p.az_bins = (int)f[kYarnFlatAzBins];
  p.az = p.az_theta_bins > 0 ? f + (int)f[kYarnFlatOffset_Az] : nullptr;
  return p;
}

/* Bilinear weights of a table over incident directions (theta_i in [0, pi/2], nt bins, clamped; phi_i in
 * [-pi, pi), np bins, periodic) between bin centres: the four entries' indices [theta][phi] and weights. */
NY_KERNEL_FN void yarn_incident_bilinear(int nt, int np, Vec3 wi, NY_PRIVATE int idx[4], NY_PRIVATE float w[4])
{
  const float ft = clampf(acosf(clampf(wi.z, -1.0f, 1.0f)) * (2.0f * kInvPi) * (float)nt - 0.5f, 0.0f, (float)(nt - 1));
  float fp = (fast_atan2(wi.y, wi.x) + kPi) * kInvTwoPi * (float)np - 0.5f;
  fp = fp < 0.0f ? fp + (float)np : fp;
  const int t0 = (int)ft < nt - 1 ? (int)ft : nt - 1, t1 = t0 + 1 < nt ? t0 + 1 : nt - 1;
  const int p0 = (int)fp < np - 1 ? (int)fp : np - 1, p1 = p0 + 1 < np ? p0 + 1 : 0;
  const float wt = ft - (float)t0, wp = fp - (float)p0;
  idx[0] = t0 * np + p0, idx[1] = t0 * np + p1, idx[2] = t1 * np + p0, idx[3] = t1 * np + p1;
  w[0] = (1.0f - wt) * (1.0f - wp), w[1] = (1.0f - wt) * wp, w[2] = wt * (1.0f - wp), w[3] = wt * wp;
}

/* Energy calibration at w_i (yarn frame, w_i.z > 0): bilinear between bin centres, clamped in theta,
 * periodic in phi. Writes dP_T (0 without a table), c_R and c_M (1 without a table). */
NY_KERNEL_FN void yarn_calibration(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi, NY_PRIVATE float *dP_T,
                                   NY_PRIVATE Rgb *c_R, NY_PRIVATE Rgb *c_M)
{
  if (!p.cal) {
    *dP_T = 0.0f;
    *c_R = make_rgb(1.0f);
    *c_M = make_rgb(1.0f);
    return;
  }
  int idx[4];
  float w[4];
  yarn_incident_bilinear(p.cal_theta_bins, p.cal_phi_bins, wi, idx, w);
  float c[kYarnCalStride];
  for (int k = 0; k < kYarnCalStride; k++) {
    c[k] = w[0] * p.cal[idx[0] * kYarnCalStride + k] + w[1] * p.cal[idx[1] * kYarnCalStride + k] +
           w[2] * p.cal[idx[2] * kYarnCalStride + k] + w[3] * p.cal[idx[3] * kYarnCalStride + k];
  }
  *dP_T = c[0];
  *c_R = make_rgb(c[1], c[2], c[3]);
  *c_M = make_rgb(c[4], c[5], c[6]);
}

/* Everything that depends on w_i only: most of an eval's cost (two networks, the calibration, the
 * longitudinal normalisers; docs/benchmarks.md). A renderer computes it once per shading point
 * (yarn_lobes(p, w_i)) and passes it to yarn_eval_lobes(), yarn_pdf_lobes() and yarn_sample_lobes() for every
 * w_o there; yarn_eval(), yarn_pdf() and yarn_sample() recompute it per call. */
/* One fiber of the R lobe (see the top): w -> its fiber frame M_q R_x(a_q) w. */
struct YarnRNode {
  TwistRotation pre;    /* P_q: identity but for a node with its own frame */
  float ca, sa;         /* cos, sin of a_q */
  TwistRotation twist;  /* M_q */
  LongitudinalLobe m_R, m_TT;
  TruncatedNormal tn_R, tn_TT, tn_TT_phi; /* theta~_o of both parts, phi~_o (upper half) of the TT part */
};

struct YarnLobes {
  bool valid;     /* w_i strictly above the surface; otherwise the BSDF is zero */
  Vec3 wi;        /* yarn frame            */
  Vec3 we;        /* yarn_energy_direction(w_i): the M network's w_i input */
  Vec3 wi_f;      /* surface-fiber frame   */
  float P_T;      /* P(T | w_i)            */
  Rgb weight_R;   /* c_R rho_R F(theta~_i): the R lobe's energy is half of it (upper half of azimuths) */
  Rgb scale_M;    /* c_M e(w_i): the factor on the M network's output */
  float p_T, p_R, p_M; /* lobe selection probabilities, summing to 1 */
  TruncatedNormal tn_M;
  float kappa_vm; /* von Mises concentration of the M azimuth */
  NY_GLOBAL const float *az_row[4]; /* the R azimuth table's rows around w_i and their weights (az_bins 0: uniform) */
  float az_w[4];
  int az_bins;
  Rgb tau;        /* the R part's TT share (0 without a table or where the TT azimuth has no mass) */
  float q_TT;     /* the TT part's share of the R energy: its selection probability within R */
  int n_R;        /* R nodes in use: kYarnRNodes, or 1 (free path 0: the surface fiber, frame = the base one) */
  YarnRNode node[kYarnRNodes];
};

/* Whether node q turns first by its own P_q (a node of the R frames; the free path's nodes have none). */
NY_KERNEL_FN bool yarn_r_node_has_pre(NY_PRIVATE const YarnRNode &n) { return n.pre.c != 1.0f || n.pre.s != 0.0f; }

/* R_x(a) w about the yarn axis, given cos a and sin a (R_x(-a) with -sin a). */
NY_KERNEL_FN Vec3 yarn_rotate_about_axis(float ca, float sa, Vec3 w)
{
  return make_vec3(w.x, ca * w.y - sa * w.z, sa * w.y + ca * w.z);
}

/* w (yarn frame) in node q's fiber frame, and back. */
NY_KERNEL_FN Vec3 yarn_to_r_node(NY_PRIVATE const YarnRNode &n, Vec3 w)
{
  if (yarn_r_node_has_pre(n)) {
    w = yarn_to_surface_fiber(n.pre, w);
  }
  return yarn_to_surface_fiber(n.twist, yarn_rotate_about_axis(n.ca, n.sa, w));
}

NY_KERNEL_FN Vec3 r_node_to_yarn(NY_PRIVATE const YarnRNode &n, Vec3 w_f)
{
  const Vec3 v = yarn_rotate_about_axis(n.ca, -n.sa, surface_fiber_to_yarn(n.twist, w_f));
  return yarn_r_node_has_pre(n) ? surface_fiber_to_yarn(n.pre, v) : v;
}

/* yarn_to_r_node() for the R nodes' lanes (yarn_R_lanes, yarn_r_nodes_setup_lanes): the node's rotation as its three
 * (cos, sin) pairs, P_q always applied (the identity (1, 0) for the free path's nodes: the same value), and w's
 * components as floats: through a TwistRotation or a Vec3 argument GCC 12 keeps such a loop scalar. */
NY_KERNEL_FN Vec3 yarn_to_r_node_lanes(float pc, float ps, float ca, float sa, float tc, float ts, float x, float y,
                                       float z)
{
  const Vec3 v = yarn_rotate_about_axis(ca, sa, make_vec3(pc * x - ps * y, ps * x + pc * y, z));
  return make_vec3(tc * v.x - ts * v.y, ts * v.x + tc * v.y, v.z);
}

NY_KERNEL_FN float yarn_transmission(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi)
{
  const float in[3] = {wi.x, wi.y, wi.z};
  float out[1];
  mlp_forward_io<3, 1>(p.net_T, in, out);
  return clampf(out[0], 0.0f, 1.0f);
}

/* The R lobe's weight (twice its energy) given the calibration's c_R: c_R rho_R F(theta~_i) with F the fiber's
 * Fresnel factor (RGB, the energy's colour) where rho_R is one number, c_R rho_R average(F) where rho_R is RGB
 * (D65). */
NY_KERNEL_FN Rgb yarn_reflection_weight(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi, Rgb F, Rgb c_R)
{
  const float in[3] = {wi.x, wi.y, wi.z};
  if (p.r_rgb) {
    float out[3];
    mlp_forward_io<3, 3>(p.net_R, in, out);
    return c_R * make_rgb(out[0], out[1], out[2]) * average(F);
  }
  float out[1];
  mlp_forward_io<3, 1>(p.net_R, in, out);
  return F * c_R * out[0];
}

/* Smallest escape factor 1 - P_T the M network is multiplied by (and its targets were divided by). */
constexpr float kYarnMinEscape = 0.02f;

NY_KERNEL_FN float yarn_escape(float P_T) { return maxf(1.0f - P_T, kYarnMinEscape); }

/* The direction whose energies (P_T, the R lobe's weight, the M network's input and scale) serve w_i: w_i
 * itself, but beyond the calibration table's last theta_i centre that centre's direction at the same
 * azimuth. The table bounds the white furnace at its centres; past the last one it is constant while the
 * networks and the Fresnel factor keep changing toward grazing, where the sum reached 1.2 x the light
 * received (docs/benchmarks.md, "White furnace"). The lobes' shapes keep the true w_i. */
NY_KERNEL_FN Vec3 yarn_energy_direction(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi)
{
  if (!p.cal || !(wi.z > 0.0f)) {
    return wi;
  }
  const float cos_c = cosf(((float)p.cal_theta_bins - 0.5f) * kHalfPi / (float)p.cal_theta_bins);
  const float t2 = wi.x * wi.x + wi.y * wi.y;
  if (wi.z >= cos_c || !(t2 > 0.0f)) {
    return wi;
  }
  const float s = sqrtf((1.0f - cos_c * cos_c) / t2);
  return make_vec3(wi.x * s, wi.y * s, cos_c);
}

/* P_T(w_i) given the energy direction and the calibration's dP_T there. */
NY_KERNEL_FN float yarn_calibrated_transmission(NY_PRIVATE const YarnBsdfParams &p, Vec3 we, float dP_T)
{
  return clampf(yarn_transmission(p, we) + dP_T, 0.0f, 1.0f);
}

/* P_T(w_i) alone, exactly as yarn_lobes() computes it: all that a shadow ray needs of the yarn (the T lobe is
 * its transparency), at a fraction of the lobes' cost (no R network, normalisers or truncated normals). */
NY_KERNEL_FN float yarn_transmission_probability(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi)
{
  if (!(wi.z > 0.0f)) {
    return 0.0f;
  }
  const Vec3 we = yarn_energy_direction(p, wi);
  float dP_T;
  Rgb c_R, c_M;
  yarn_calibration(p, we, &dP_T, &c_R, &c_M);
  return yarn_calibrated_transmission(p, we, dP_T);
}

/* The R nodes' means and Gaussians side by side (yarn_r_nodes_setup_lanes), before they are stored into l.node. */
struct YarnRNodeSetupLanes {
  float mu[kYarnRNodes], phi_TT[kYarnRNodes], inv_R[kYarnRNodes], inv_TT[kYarnRNodes];
  float za_R[kYarnRNodes], zb_R[kYarnRNodes], lo_R[kYarnRNodes], up_R[kYarnRNodes], mass_R[kYarnRNodes];
  float za_TT[kYarnRNodes], zb_TT[kYarnRNodes], lo_TT[kYarnRNodes], up_TT[kYarnRNodes], mass_TT[kYarnRNodes];
  float za_P[kYarnRNodes], zb_P[kYarnRNodes], lo_P[kYarnRNodes], up_P[kYarnRNodes], mass_P[kYarnRNodes];
};

/* The truncated normals and normalisers of every node from its mean (g.mu, g.phi_TT), as lanes. kTableR false: no
 * node's mean is within 6 beta_R of a bound (the R normaliser is the closed form on every lane); kTailsR false: no
 * node's theta~ interval reaches into a tail of its R Gaussian (mass 1, both tails 0 on every lane). Either gives
 * the values of the full computation (the same selections made before, for all lanes at once): a narrow R lobe
 * (cotton's 1 degree) skips the table's gathers and two erfc per node at most shading points. */
template<bool kTT, bool kTableR, bool kTailsR>
NY_KERNEL_FN void yarn_r_nodes_gaussians_lanes(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const Cos2Width &w_R,
                                               NY_PRIVATE const Cos2Width &w_TT, NY_PRIVATE YarnRNodeSetupLanes &g)
{
  const float beta_R = p.fiber.beta_R, beta_TT = p.fiber.beta_TT, gamma_TT = p.fiber.gamma_TT;
  NY_SIMD_LOOP
  for (int q = 0; q < kYarnRNodes; q++) {
    const float m = g.mu[q];
    if (kTailsR) {
      truncated_normal_lanes(m, beta_R, -kHalfPi, kHalfPi, g.za_R[q], g.zb_R[q], g.lo_R[q], g.up_R[q], g.mass_R[q]);
    }
    else {
      g.za_R[q] = (-kHalfPi - m) / beta_R;
      g.zb_R[q] = (kHalfPi - m) / beta_R;
      g.lo_R[q] = 0.0f;
      g.up_R[q] = 0.0f;
      g.mass_R[q] = 1.0f;
    }
    g.inv_R[q] = longitudinal_inv_beta_G(beta_R, cos2_gaussian_normalizer_lanes<kTableR>(m, beta_R, w_R.half, w_R.e));
    if (kTT) {
      truncated_normal_lanes(m, beta_TT, -kHalfPi, kHalfPi, g.za_TT[q], g.zb_TT[q], g.lo_TT[q], g.up_TT[q],
                             g.mass_TT[q]);
      g.inv_TT[q] = longitudinal_inv_beta_G(beta_TT, cos2_gaussian_normalizer_lanes(m, beta_TT, w_TT.half, w_TT.e));
      truncated_normal_lanes(g.phi_TT[q], gamma_TT, -kHalfPi, kHalfPi, g.za_P[q], g.zb_P[q], g.lo_P[q], g.up_P[q],
                             g.mass_P[q]);
    }
  }
}

/* yarn_lobes' kYarnRNodes R nodes as the lanes of one vector (issue 21, decisions D64): each node's frame, its
 * theta~_i and phi~_i, then the truncated normals of its theta~ Gaussians (and the TT azimuth's, kTT) and their cos^2
 * normalisers, in loops without branches or library calls (sincos_lanes, atan2_lanes, erfc_lanes, the table's
 * normaliser; within a few float ulps of the scalar functions), then stored into l.node. A width past the
 * normaliser's table takes the scalar normaliser (its quadrature) after the loop. */
template<bool kTT>
NY_KERNEL_FN void yarn_r_nodes_setup_lanes(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi, bool with_eval,
                                           NY_PRIVATE const Cos2Width &w_R, NY_PRIVATE const Cos2Width &w_TT,
                                           NY_PRIVATE YarnLobes &l)
{
  constexpr int K = kYarnRNodes;
  /* Each node's rotation w -> M_q R_x(a_q) P_q w (P_q the identity on the free path's nodes). */
  float pc[K], ps[K], ca[K], sa[K], tc[K], ts[K];
  if (p.r_frames) { /* fibers of the visible surface: their frames from the model (D51) */
    for (int q = 0; q < K; q++) {
      NY_GLOBAL const float *r = p.r_frames + q * kYarnRFrameStride;
      pc[q] = r[0];
      ps[q] = r[1];
      ca[q] = r[2];
      sa[q] = r[3];
      tc[q] = r[4];
      ts[q] = r[5];
    }
  }
  else { /* the free path's nodes (D38): a_q = -w_i.y s_q, the twist fading with the depth s_q w_i.z */
    const float free_path = p.free_path, alpha = p.alpha;
    NY_SIMD_LOOP
    for (int q = 0; q < K; q++) {
      const float s = free_path * yarn_r_node_path(q);
      sincos_lanes(-wi.y * s, sa[q], ca[q]);
      pc[q] = 1.0f;
      ps[q] = 0.0f;
      /* make_twist_rotation(alpha max(1 - s w_i.z, 0)) written out (a structure returned here keeps the loop scalar). */
      const float t = kPi * (alpha * maxf(1.0f - s * wi.z, 0.0f));
      const float inv = 1.0f / sqrtf(1.0f + t * t);
      tc[q] = inv;
      ts[q] = t * inv;
    }
  }
  YarnRNodeSetupLanes g;
  NY_SIMD_LOOP
  for (int q = 0; q < K; q++) {
    /* theta_of() and phi_of() written out (cos_theta() through a Vec3 argument keeps the loop scalar). */
    const Vec3 w_q = yarn_to_r_node_lanes(pc[q], ps[q], ca[q], sa[q], tc[q], ts[q], wi.x, wi.y, wi.z);
    const float c = minf(sqrtf(w_q.y * w_q.y + w_q.z * w_q.z), 1.0f);
    g.mu[q] = -atan2_lanes(w_q.x, c);
    g.phi_TT[q] = kTT ? wrap_angle_lanes(atan2_lanes(w_q.y, w_q.z) + kPi) : 0.0f;
  }
  /* Which of the R Gaussian's costly parts any node needs: the table only where the lanes' normaliser is kept (eval
   * wanted, beta_R within the table). */
  const float beta_R = p.fiber.beta_R, beta_TT = p.fiber.beta_TT;
  const bool lanes_G_R = with_eval && beta_R <= kCos2TableBetaMax, lanes_G_TT = with_eval && beta_TT <= kCos2TableBetaMax;
  bool table_R = false, tails_R = false;
  for (int q = 0; q < K; q++) {
    table_R = table_R || !cos2_gaussian_closed_form_holds(kHalfPi - fabsf(g.mu[q]), beta_R);
    tails_R = tails_R || !truncated_normal_tails_cut((-kHalfPi - g.mu[q]) / beta_R, (kHalfPi - g.mu[q]) / beta_R);
  }
  table_R = table_R && lanes_G_R;
  if (table_R) {
    tails_R ? yarn_r_nodes_gaussians_lanes<kTT, true, true>(p, w_R, w_TT, g) :
              yarn_r_nodes_gaussians_lanes<kTT, true, false>(p, w_R, w_TT, g);
  }
  else {
    tails_R ? yarn_r_nodes_gaussians_lanes<kTT, false, true>(p, w_R, w_TT, g) :
              yarn_r_nodes_gaussians_lanes<kTT, false, false>(p, w_R, w_TT, g);
  }
  for (int q = 0; q < K; q++) {
    NY_PRIVATE YarnRNode &n = l.node[q];
    const float mu = g.mu[q];
    n.pre = TwistRotation{pc[q], ps[q]};
    n.ca = ca[q];
    n.sa = sa[q];
    n.twist = TwistRotation{tc[q], ts[q]};
    n.tn_R = TruncatedNormal{mu, beta_R, g.za_R[q], g.zb_R[q], g.lo_R[q], g.up_R[q], g.mass_R[q]};
    n.m_R = lanes_G_R ? LongitudinalLobe{mu, beta_R, g.inv_R[q]} :
            with_eval ? make_longitudinal_lobe(mu, w_R) : LongitudinalLobe{mu, beta_R, 0.0f};
    if (kTT) {
      n.tn_TT = TruncatedNormal{mu, beta_TT, g.za_TT[q], g.zb_TT[q], g.lo_TT[q], g.up_TT[q], g.mass_TT[q]};
      n.m_TT = lanes_G_TT ? LongitudinalLobe{mu, beta_TT, g.inv_TT[q]} :
               with_eval ? make_longitudinal_lobe(mu, w_TT, true) : LongitudinalLobe{mu, beta_TT, 0.0f};
      n.tn_TT_phi = TruncatedNormal{g.phi_TT[q], p.fiber.gamma_TT, g.za_P[q], g.zb_P[q], g.lo_P[q], g.up_P[q],
                                    g.mass_P[q]};
      if (!(g.mass_P[q] > 0.0f)) {
        l.tau = make_rgb(0.0f); /* every node's TT part must hold the lobe's energy, or none has a share */
      }
    }
    else {
      n.tn_TT = n.tn_R;
      n.m_TT = n.m_R;
      n.tn_TT_phi = TruncatedNormal{0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    }
  }
}

/* `with_eval` = false skips the cos^2 normaliser of the R lobe, which only eval needs. */
NY_KERNEL_FN YarnLobes yarn_lobes(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi, bool with_eval = true)
{
  YarnLobes l;
  l.wi = wi;
  l.we = yarn_energy_direction(p, wi);
  l.wi_f = yarn_to_surface_fiber(p.twist, wi);
  l.valid = wi.z > 0.0f;
  float dP_T = 0.0f;
  Rgb c_R = make_rgb(0.0f), c_M = make_rgb(0.0f);
  if (l.valid) {
    yarn_calibration(p, l.we, &dP_T, &c_R, &c_M);
  }
  l.P_T = l.valid ? yarn_calibrated_transmission(p, l.we, dP_T) : 0.0f;
  const float theta_i = theta_of(l.wi_f);
  const Rgb F = schlick_fresnel(p.fiber.C_R, cos_theta(yarn_to_surface_fiber(p.twist, l.we)));
  l.weight_R = l.valid ? yarn_reflection_weight(p, l.we, F, c_R) : make_rgb(0.0f);
  l.scale_M = c_M * yarn_escape(l.P_T);
  l.p_T = l.P_T;
  l.p_R = (1.0f - l.P_T) * p.kappa_R;
  l.p_M = (1.0f - l.P_T) * (1.0f - p.kappa_R);
  l.tn_M = make_truncated_normal(-theta_i, p.beta_M, -kHalfPi, kHalfPi);
  l.kappa_vm = 1.0f / (p.gamma_M * p.gamma_M);
  l.az_bins = 0;
  l.tau = make_rgb(0.0f);
  if (p.az && l.valid) {
    int idx[4];
    yarn_incident_bilinear(p.az_theta_bins, p.az_phi_bins, wi, idx, l.az_w);
    const int stride = yarn_r_shape_stride(p.az_bins);
    for (int k = 0; k < 4; k++) {
      l.az_row[k] = p.az + idx[k] * stride;
      l.tau = l.tau + make_rgb(l.az_row[k][p.az_bins], l.az_row[k][p.az_bins + 1], l.az_row[k][p.az_bins + 2]) *
                          l.az_w[k];
    }
    l.az_bins = p.az_bins;
  }
  /* The R nodes: their frames and longitudinal lobes (and, if the TT part has a share, its forward azimuth
   * phi~_i + pi truncated to the upper half: without a share it is never evaluated nor sampled, no erfc). */
  l.n_R = (p.free_path > 0.0f || p.r_frames) ? kYarnRNodes : 1;
  const bool has_tt = average(l.tau) > 0.0f;
  /* The normalisers' constants of each width once for all nodes (eval's alone). */
  Cos2Width w_R = Cos2Width{p.fiber.beta_R, 0.0f, 0.0f}, w_TT = Cos2Width{p.fiber.beta_TT, 0.0f, 0.0f};
  if (with_eval) {
    w_R = make_cos2_width(p.fiber.beta_R);
    if (has_tt) {
      w_TT = make_cos2_width(p.fiber.beta_TT);
    }
  }
  if (l.n_R == kYarnRNodes) {
    has_tt ? yarn_r_nodes_setup_lanes<true>(p, wi, with_eval, w_R, w_TT, l) :
             yarn_r_nodes_setup_lanes<false>(p, wi, with_eval, w_R, w_TT, l);
  }
  else { /* the surface fiber alone: the base frame */
    NY_PRIVATE YarnRNode &n = l.node[0];
    n.pre = TwistRotation{1.0f, 0.0f};
    n.ca = 1.0f;
    n.sa = 0.0f;
    n.twist = p.twist;
    const float theta_q = theta_of(l.wi_f);
    n.m_R = with_eval ? make_longitudinal_lobe(-theta_q, w_R)
                      : LongitudinalLobe{-theta_q, p.fiber.beta_R, 0.0f};
    n.tn_R = make_truncated_normal(-theta_q, p.fiber.beta_R, -kHalfPi, kHalfPi);
    n.tn_TT = n.tn_R;
    n.m_TT = n.m_R;
    n.tn_TT_phi = TruncatedNormal{0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    if (has_tt) {
      n.tn_TT_phi = make_truncated_normal(wrap_angle(phi_of(l.wi_f) + kPi), p.fiber.gamma_TT, -kHalfPi, kHalfPi);
      if (!(n.tn_TT_phi.mass > 0.0f)) {
        l.tau = make_rgb(0.0f); /* the TT part must hold the lobe's energy, or it has no share */
      }
      n.tn_TT = make_truncated_normal(-theta_q, p.fiber.beta_TT, -kHalfPi, kHalfPi);
      n.m_TT = with_eval ? make_longitudinal_lobe(-theta_q, w_TT, true)
                         : LongitudinalLobe{-theta_q, p.fiber.beta_TT, 0.0f};
    }
  }
  l.q_TT = 0.0f;
  const float e_R = average(l.weight_R);
  if (average(l.tau) > 0.0f && e_R > 0.0f) {
    l.q_TT = clampf(average(l.weight_R * l.tau) / e_R, 0.0f, 1.0f);
  }
  return l;
}

/* A renderer's glossy filter (Cycles' Filter Glossy, bsdf_blur): after rough bounces it may widen the glossy
 * lobes to cut the noise of caustic paths, at the price of bias. Every R node's longitudinal lobes (the
 * reflection's and the TT part's, and their proposals, which are the same Gaussians) become at least beta_min
 * wide; their weights stay, so the R lobe's energy stays, and M (already broad) is left as it is. */
NY_KERNEL_FN void yarn_lobes_blur(NY_PRIVATE YarnLobes &l, float beta_min)
{
  if (!(beta_min > 0.0f)) {
    return;
  }
  const Cos2Width w = make_cos2_width(beta_min);
  for (int q = 0; q < l.n_R; q++) {
    NY_PRIVATE YarnRNode &n = l.node[q];
    if (!(n.tn_R.sigma < beta_min) && !(n.tn_TT.sigma < beta_min)) {
      continue;
    }
    /* Both parts share the node's mean -theta~_i (yarn_lobes): one widened lobe serves either. */
    const LongitudinalLobe m = make_longitudinal_lobe(n.tn_R.mu, w, true);
    const TruncatedNormal tn = make_truncated_normal(n.tn_R.mu, beta_min, -kHalfPi, kHalfPi);
    if (n.tn_R.sigma < beta_min) {
      n.m_R = m;
      n.tn_R = tn;
    }
    if (n.tn_TT.sigma < beta_min) {
      n.m_TT = m;
      n.tn_TT = tn;
    }
  }
}

/* The longitudinal width whose Gaussian has the half width at half maximum in theta_o of a GGX lobe of roughness
 * alpha (the slope's half width alpha sqrt(sqrt 2 - 1), doubled; model/fallback.h matches the other way): how
 * a renderer's roughness, e.g. Cycles' blur roughness, becomes a width of this closure. */
NY_KERNEL_FN float yarn_beta_of_ggx_alpha(float alpha)
{
  return alpha * 1.0932373f; /* 2 sqrt(sqrt 2 - 1) / sqrt(2 ln 2) */
}

/* The R lobe's energy from w_i, exactly: half of weight_R = c_R rho_R F, the half of the fiber's R lobe whose
 * azimuths leave the surface (each of its parts integrates to it, yarn_eval_R_parts). */
NY_KERNEL_FN Rgb yarn_energy_R(NY_PRIVATE const YarnLobes &l) { return l.weight_R * 0.5f; }

/* An outgoing direction in the surface-fiber frame with the angles that every lobe's eval and pdf read:
 * computed once per w_o (two atan2 and a square root) instead of in each of them. */
struct YarnOutgoing {
  Vec3 w;
  float theta, phi, cos_theta;
};

NY_KERNEL_FN YarnOutgoing yarn_outgoing(Vec3 wo_f)
{
  YarnOutgoing o;
  o.w = wo_f;
  o.theta = theta_of(wo_f);
  o.phi = phi_of(wo_f);
  o.cos_theta = cos_theta(wo_f);
  return o;
}

/* pi nu(phi~_o | w_i) from the table (az_bins > 0): no test, so that the R nodes' lanes (yarn_R_lanes) load
 * it unconditionally; the four rows written out, not a loop, for the same reason. */
NY_KERNEL_FN float yarn_r_azimuth_table(NY_PRIVATE const YarnLobes &l, float phi)
{
  const int n = l.az_bins;
  const float f = clampf((phi + kHalfPi) * kInvPi * (float)n - 0.5f, 0.0f, (float)(n - 1));
  const int k0 = (int)f < n - 1 ? (int)f : n - 1, k1 = k0 + 1 < n ? k0 + 1 : n - 1;
  const float w = f - (float)k0;
  const float nu = l.az_w[0] * ((1.0f - w) * l.az_row[0][k0] + w * l.az_row[0][k1]) +
                   l.az_w[1] * ((1.0f - w) * l.az_row[1][k0] + w * l.az_row[1][k1]) +
                   l.az_w[2] * ((1.0f - w) * l.az_row[2][k0] + w * l.az_row[2][k1]) +
                   l.az_w[3] * ((1.0f - w) * l.az_row[3][k0] + w * l.az_row[3][k1]);
  return kPi * nu;
}

/* pi nu(phi~_o | w_i): the R lobe's azimuthal density relative to the uniform 1 / pi (1 without a table). */
NY_KERNEL_FN float yarn_r_azimuth(NY_PRIVATE const YarnLobes &l, float phi)
{
  return l.az_bins == 0 ? 1.0f : yarn_r_azimuth_table(l, phi);
}

/* Node q's two parts of the R lobe (below) are products of a factor of theta~_o and one of phi~_o: a
 * quadrature over a (theta~, phi~) grid (model/lobe_fidelity.cpp) computes each once per row and column. */
struct YarnRTheta {
  float c;          /* cos(theta~_o), the fiber's own (longitudinal) cosine */
  float L_R, L_TT;  /* the longitudinal lobes (L_TT: 0 without a TT share)  */
  float p_R, p_TT;  /* the proposal's truncated normals in theta~           */
};

struct YarnRPhi {
  float nu;    /* pi nu(phi~_o | w_i), the reflection's azimuth          */
  float p_TT;  /* the TT part's azimuth density (0 without a TT share)   */
};

NY_KERNEL_FN YarnRTheta yarn_r_theta(NY_PRIVATE const YarnLobes &l, int q, float theta, float cos_theta)
{
  NY_PRIVATE const YarnRNode &n = l.node[q];
  YarnRTheta t;
  t.c = cos_theta;
  /* A part's lobe and its proposal are one Gaussian (mean -theta~ of w_i in the node's frame, width beta_R or
   * beta_TT; yarn_lobes): one normal pdf for both, the lanes' (yarn_R_lanes), so that the host's quadratures
   * integrate exactly what the closure evaluates. */
  const float z_R = (theta - n.tn_R.mu) / n.tn_R.sigma, g_R = normal_pdf_lanes(z_R);
  t.L_R = longitudinal_eval_of(n.m_R, theta, g_R);
  t.p_R = truncated_normal_pdf_of(n.tn_R, z_R, g_R);
  t.L_TT = t.p_TT = 0.0f;
  if (l.q_TT > 0.0f) {
    const float z_TT = (theta - n.tn_TT.mu) / n.tn_TT.sigma, g_TT = normal_pdf_lanes(z_TT);
    t.L_TT = longitudinal_eval_of(n.m_TT, theta, g_TT);
    t.p_TT = truncated_normal_pdf_of(n.tn_TT, z_TT, g_TT);
  }
  return t;
}

NY_KERNEL_FN YarnRPhi yarn_r_phi(NY_PRIVATE const YarnLobes &l, int q, float phi)
{
  YarnRPhi a;
  a.nu = yarn_r_azimuth(l, phi);
  if (l.q_TT > 0.0f) {
    NY_PRIVATE const TruncatedNormal &tn = l.node[q].tn_TT_phi;
    const float z = (phi - tn.mu) / tn.sigma;
    a.p_TT = truncated_normal_pdf_of(tn, z, normal_pdf_lanes(z));
  }
  else {
    a.p_TT = 0.0f;
  }
  return a;
}

/* The two parts of node q's R lobe from their factors, w_o on the upper half (w~_o.z > 0), each with the lobe's
 * whole weight: the reflection (its azimuth density nu) and the TT part (0 where it has no share).
 * S_R |cos| = mean over the nodes of (1 - tau) R + tau TT. The cosine is the fiber's own (longitudinal), so
 * that each part's energy is exactly rho_R F / 2: half of the fiber's albedo, the half whose azimuth
 * leaves the surface. */
NY_KERNEL_FN void yarn_eval_R_factors(NY_PRIVATE const YarnLobes &l, NY_PRIVATE const YarnRTheta &t,
                                      NY_PRIVATE const YarnRPhi &a, NY_PRIVATE Rgb *R, NY_PRIVATE Rgb *TT)
{
  *R = l.weight_R * (t.L_R * kInvTwoPi * t.c * a.nu);
  *TT = l.q_TT > 0.0f ? l.weight_R * (t.L_TT * 0.5f * t.c * a.p_TT) : make_rgb(0.0f);
}

/* Smallest cos(theta~_o) used to turn a (theta, phi) density into solid angle (as fiber_bsdf.h). */
constexpr float kYarnMinCosTheta = 1e-7f;

/* Densities of node q's R proposal in solid angle from their factors, w_o on the upper half, in two parts
 * (reflection; TT, density 0 when it has no share). */
NY_KERNEL_FN void yarn_pdf_R_factors(NY_PRIVATE const YarnLobes &l, NY_PRIVATE const YarnRTheta &t,
                                     NY_PRIVATE const YarnRPhi &a, NY_PRIVATE float *pdf_R, NY_PRIVATE float *pdf_TT)
{
  const float inv_cos = 1.0f / maxf(t.c, kYarnMinCosTheta);
  *pdf_R = t.p_R * kInvPi * inv_cos;
  *pdf_TT = l.q_TT > 0.0f ? t.p_TT * a.p_TT * inv_cos : 0.0f;
}

/* Node q's two parts of the R lobe at w_o (o: w_o in the node's fiber frame). */
NY_KERNEL_FN void yarn_eval_R_parts(NY_PRIVATE const YarnLobes &l, int q, NY_PRIVATE const YarnOutgoing &o,
                                    NY_PRIVATE Rgb *R, NY_PRIVATE Rgb *TT)
{
  *R = *TT = make_rgb(0.0f);
  if (!l.valid || !(o.w.z > 0.0f)) {
    return;
  }
  yarn_eval_R_factors(l, yarn_r_theta(l, q, o.theta, o.cos_theta), yarn_r_phi(l, q, o.phi), R, TT);
}

/* Densities of node q's R proposal in solid angle (o: w_o in the node's frame). */
NY_KERNEL_FN void yarn_pdf_R_parts(NY_PRIVATE const YarnLobes &l, int q, NY_PRIVATE const YarnOutgoing &o,
                                   NY_PRIVATE float *pdf_R, NY_PRIVATE float *pdf_TT)
{
  *pdf_R = *pdf_TT = 0.0f;
  if (!(o.w.z > 0.0f)) {
    return;
  }
  yarn_pdf_R_factors(l, yarn_r_theta(l, q, o.theta, o.cos_theta), yarn_r_phi(l, q, o.phi), pdf_R, pdf_TT);
}

/* One theta~ (or phi~) Gaussian of each R node as arrays over the nodes: its truncated normal (mean, width,
 * bounds in standard scores, 1 / (sigma mass)) and the longitudinal lobe's 1 / (beta G). */
struct YarnGaussianLanes {
  float mu[kYarnRNodes], sigma[kYarnRNodes], za[kYarnRNodes], zb[kYarnRNodes], sigma_mass[kYarnRNodes],
      inv_beta_G[kYarnRNodes];
};

NY_KERNEL_FN void yarn_gaussian_lanes_set(NY_PRIVATE YarnGaussianLanes &g, int q, NY_PRIVATE const TruncatedNormal &tn,
                                          float inv_beta_G)
{
  g.mu[q] = tn.mu;
  g.sigma[q] = tn.sigma;
  g.za[q] = tn.za;
  g.zb[q] = tn.zb;
  g.sigma_mass[q] = tn.mass > 0.0f ? tn.sigma * tn.mass : NY_INFINITY; /* no mass: density 0 */
  g.inv_beta_G[q] = inv_beta_G;
}

/* truncated_normal_pdf_of() of lane q at standard score z (pdf: its normal pdf): the quotient taken always and
 * selected after, so that a loop of it has no branch. */
NY_KERNEL_FN float yarn_gaussian_lanes_pdf(NY_PRIVATE const YarnGaussianLanes &g, int q, float z, float pdf)
{
  const float v = pdf / g.sigma_mass[q];
  return (z >= g.za[q] && z <= g.zb[q]) ? v : 0.0f;
}

/* The kYarnRNodes R nodes (n_R > 1) as lanes of one vector (issue 21; yarn_R_nodes): node q's eval and pdf at w_o
 * into fr/fg/fb[q] and pd[q]
 * (S_R |cos| of that node before the mean, and its proposal's density in solid angle; 0 where w_o leaves the
 * node's fiber below its upper half). The values are those of yarn_eval_R_factors() and yarn_pdf_R_factors() in
 * the same order of operations; the loop has no branches and no library calls so that the compiler runs the
 * nodes side by side (the node data is copied to arrays first: loads of one field across an array of
 * structures do not vectorise). */
template<bool kAz, bool kTT>
NY_KERNEL_FN void yarn_R_lanes(NY_PRIVATE const YarnLobes &l, Vec3 wo, NY_PRIVATE float *fr, NY_PRIVATE float *fg,
                               NY_PRIVATE float *fb, NY_PRIVATE float *pd)
{
  /* Each node's frame (P_q, a_q, M_q), its two theta~ Gaussians (mean, width, bounds, sigma mass, the lobe's
   * 1 / (beta G)) and the TT azimuth's. */
  float pc[kYarnRNodes], ps[kYarnRNodes], ca[kYarnRNodes], sa[kYarnRNodes], tc[kYarnRNodes], ts[kYarnRNodes];
  YarnGaussianLanes R, TT, TT_phi;
  for (int q = 0; q < kYarnRNodes; q++) {
    NY_PRIVATE const YarnRNode &n = l.node[q];
    pc[q] = n.pre.c;
    ps[q] = n.pre.s;
    ca[q] = n.ca;
    sa[q] = n.sa;
    tc[q] = n.twist.c;
    ts[q] = n.twist.s;
    yarn_gaussian_lanes_set(R, q, n.tn_R, n.m_R.inv_beta_G);
    if (kTT) {
      yarn_gaussian_lanes_set(TT, q, n.tn_TT, n.m_TT.inv_beta_G);
      yarn_gaussian_lanes_set(TT_phi, q, n.tn_TT_phi, 0.0f);
    }
  }
  const Rgb w = l.weight_R, tau = l.tau;
  const float q_TT = l.q_TT;
  NY_SIMD_LOOP
  for (int q = 0; q < kYarnRNodes; q++) {
    /* cos_theta() written out (through a Vec3 argument GCC 12 keeps the loop scalar). */
    const Vec3 w_q = yarn_to_r_node_lanes(pc[q], ps[q], ca[q], sa[q], tc[q], ts[q], wo.x, wo.y, wo.z);
    const float c = minf(sqrtf(w_q.y * w_q.y + w_q.z * w_q.z), 1.0f);
    const float theta = atan2_lanes(w_q.x, c), phi = atan2_lanes(w_q.y, w_q.z);
    const float z_R = (theta - R.mu[q]) / R.sigma[q], g_R = normal_pdf_lanes(z_R);
    const float L_R = g_R * R.inv_beta_G[q];
    const float p_R = yarn_gaussian_lanes_pdf(R, q, z_R, g_R);
    const float nu = kAz ? yarn_r_azimuth_table(l, phi) : 1.0f;
    float L_TT = 0.0f, p_TT = 0.0f, a_TT = 0.0f;
    if (kTT) {
      const float z = (theta - TT.mu[q]) / TT.sigma[q], g = normal_pdf_lanes(z);
      L_TT = g * TT.inv_beta_G[q];
      p_TT = yarn_gaussian_lanes_pdf(TT, q, z, g);
      const float z_phi = (phi - TT_phi.mu[q]) / TT_phi.sigma[q];
      a_TT = yarn_gaussian_lanes_pdf(TT_phi, q, z_phi, normal_pdf_lanes(z_phi));
    }
    const bool up = w_q.z > 0.0f; /* R leaves the node's fiber on the upper half only */
    const float k_R = L_R * kInvTwoPi * c * nu, k_TT = L_TT * 0.5f * c * a_TT;
    fr[q] = up ? (1.0f - tau.r) * (w.r * k_R) + tau.r * (w.r * k_TT) : 0.0f;
    fg[q] = up ? (1.0f - tau.g) * (w.g * k_R) + tau.g * (w.g * k_TT) : 0.0f;
    fb[q] = up ? (1.0f - tau.b) * (w.b * k_R) + tau.b * (w.b * k_TT) : 0.0f;
    const float inv_cos = 1.0f / maxf(c, kYarnMinCosTheta);
    pd[q] = up ? (1.0f - q_TT) * (p_R * kInvPi * inv_cos) + q_TT * (p_TT * a_TT * inv_cos) : 0.0f;
  }
}

/* The R lobe at w_o (yarn frame; o_base: w_o in the surface-fiber frame), summed over the nodes: S_R |cos theta_o|
 * into *f_R and the R proposal's density (each node drawn with probability 1 / n_R) into *pdf_R, either or both
 * (a null pointer skips that part). */
NY_KERNEL_FN void yarn_R_nodes(NY_PRIVATE const YarnLobes &l, Vec3 wo, NY_PRIVATE const YarnOutgoing &o_base,
                               NY_PRIVATE Rgb *f_R, NY_PRIVATE float *pdf_R)
{
  if (l.n_R == 1) {
    /* The surface fiber alone: its frame is the base one, whose angles the caller has (the same values as a
     * lane's, yarn_R_lanes, without the three other lanes). */
    Rgb f = make_rgb(0.0f);
    float pdf = 0.0f;
    if (o_base.w.z > 0.0f) {
      const YarnRTheta t = yarn_r_theta(l, 0, o_base.theta, o_base.cos_theta);
      const YarnRPhi a = yarn_r_phi(l, 0, o_base.phi);
      Rgb R, TT;
      yarn_eval_R_factors(l, t, a, &R, &TT);
      f = (make_rgb(1.0f) - l.tau) * R + l.tau * TT;
      float r, tt;
      yarn_pdf_R_factors(l, t, a, &r, &tt);
      pdf = (1.0f - l.q_TT) * r + l.q_TT * tt;
    }
    if (f_R) {
      *f_R = l.valid ? f : make_rgb(0.0f);
    }
    if (pdf_R) {
      *pdf_R = pdf;
    }
    return;
  }
  float fr[kYarnRNodes], fg[kYarnRNodes], fb[kYarnRNodes], pd[kYarnRNodes];
  const bool tt = l.q_TT > 0.0f;
  if (l.az_bins > 0) {
    tt ? yarn_R_lanes<true, true>(l, wo, fr, fg, fb, pd) : yarn_R_lanes<true, false>(l, wo, fr, fg, fb, pd);
  }
  else {
    tt ? yarn_R_lanes<false, true>(l, wo, fr, fg, fb, pd) : yarn_R_lanes<false, false>(l, wo, fr, fg, fb, pd);
  }
  if (f_R) {
    Rgb sum = make_rgb(0.0f);
    for (int q = 0; q < kYarnRNodes; q++) {
      sum = sum + make_rgb(fr[q], fg[q], fb[q]);
    }
    *f_R = l.valid ? sum * (1.0f / (float)kYarnRNodes) : make_rgb(0.0f);
  }
  if (pdf_R) {
    float pdf = 0.0f;
    for (int q = 0; q < kYarnRNodes; q++) {
      pdf += pd[q];
    }
    *pdf_R = pdf / (float)kYarnRNodes;
  }
}

NY_KERNEL_FN Rgb yarn_eval_R(NY_PRIVATE const YarnLobes &l, Vec3 wo, NY_PRIVATE const YarnOutgoing &o_base)
{
  Rgb f;
  yarn_R_nodes(l, wo, o_base, &f, nullptr);
  return f;
}

NY_KERNEL_FN float yarn_pdf_R(NY_PRIVATE const YarnLobes &l, Vec3 wo, NY_PRIVATE const YarnOutgoing &o_base)
{
  float pdf;
  yarn_R_nodes(l, wo, o_base, nullptr, &pdf);
  return pdf;
}

NY_KERNEL_FN Rgb yarn_eval_R(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, Vec3 wo)
{
  return yarn_eval_R(l, wo, yarn_outgoing(yarn_to_surface_fiber(p.twist, wo)));
}

NY_KERNEL_FN Rgb yarn_eval_M(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, Vec3 wo)
{
  if (!l.valid) {
    return make_rgb(0.0f);
  }
  const float in[6] = {l.we.x, l.we.y, l.we.z, wo.x, wo.y, wo.z};
  if (p.m_two_sided) {
    /* The maps' M has an edge at the horizon (grazing light leaves just below it, D45): one output set per
     * side puts the edge where it is instead of asking a smooth network for a step. */
    float out[6];
    mlp_forward_io<6, 6>(p.net_M, in, out);
    const int k = wo.z >= 0.0f ? 0 : 3;
    return make_rgb(out[k], out[k + 1], out[k + 2]) * l.scale_M;
  }
  float out[3];
  mlp_forward_io<6, 3>(p.net_M, in, out);
  return make_rgb(out[0], out[1], out[2]) * l.scale_M;
}

/* The M proxy alone: kappa_M TN(theta~_o) vM(phi~_o) / cos theta~_o + (1 - kappa_M) / 4 pi. The fit
 * (model/proxy_fit.h) maximises the likelihood of exactly this function. */
NY_KERNEL_FN float yarn_m_proxy_pdf(NY_PRIVATE const TruncatedNormal &tn_M, float kappa_vm, float kappa_M,
                                    NY_PRIVATE const YarnOutgoing &o)
{
  const float lobe = truncated_normal_pdf(tn_M, o.theta) * von_mises_pdf(o.phi, kappa_vm) /
                     maxf(o.cos_theta, kYarnMinCosTheta);
  return kappa_M * lobe + (1.0f - kappa_M) * kInvFourPi;
}

NY_KERNEL_FN float yarn_m_proxy_pdf(NY_PRIVATE const TruncatedNormal &tn_M, float kappa_vm, float kappa_M, Vec3 wo_f)
{
  return yarn_m_proxy_pdf(tn_M, kappa_vm, kappa_M, yarn_outgoing(wo_f));
}

NY_KERNEL_FN float yarn_pdf_M_fiber(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l,
                                    NY_PRIVATE const YarnOutgoing &o)
{
  return yarn_m_proxy_pdf(l.tn_M, l.kappa_vm, p.kappa_M, o);
}

/* The non-delta sampler's density at w_o (yarn frame; o: in the surface-fiber frame), conditional on not
 * choosing T. */
NY_KERNEL_FN float yarn_pdf_fiber(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, float pdf_R,
                                  NY_PRIVATE const YarnOutgoing &o)
{
  return p.kappa_R * pdf_R + (1.0f - p.kappa_R) * yarn_pdf_M_fiber(p, l, o);
}

NY_KERNEL_FN float yarn_pdf_fiber(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, Vec3 wo,
                                  NY_PRIVATE const YarnOutgoing &o)
{
  return yarn_pdf_fiber(p, l, yarn_pdf_R(l, wo, o), o);
}

/* Non-delta part: eval = (S_R + S_M) |cos theta_o|. */
NY_KERNEL_FN Rgb yarn_eval_lobes(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, Vec3 wo)
{
  if (!l.valid) {
    return make_rgb(0.0f);
  }
  return yarn_eval_R(p, l, wo) + yarn_eval_M(p, l, wo);
}

/* Density of the non-delta sampler, conditional on not choosing T (integrates to 1 over the sphere). */
NY_KERNEL_FN float yarn_pdf_lobes(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, Vec3 wo)
{
  if (!l.valid) {
    return 0.0f;
  }
  return yarn_pdf_fiber(p, l, wo, yarn_outgoing(yarn_to_surface_fiber(p.twist, wo)));
}

/* Both at once, as a renderer asks for them (the angles of w_o computed once): yarn_eval_lobes() and
 * yarn_pdf_lobes(), bit for bit. */
NY_KERNEL_FN Rgb yarn_eval_pdf_lobes(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, Vec3 wo,
                                     NY_PRIVATE float *pdf)
{
  *pdf = 0.0f;
  if (!l.valid) {
    return make_rgb(0.0f);
  }
  const YarnOutgoing o = yarn_outgoing(yarn_to_surface_fiber(p.twist, wo));
  Rgb f_R;
  float pdf_R;
  yarn_R_nodes(l, wo, o, &f_R, &pdf_R);
  *pdf = yarn_pdf_fiber(p, l, pdf_R, o);
  return f_R + yarn_eval_M(p, l, wo);
}

NY_KERNEL_FN Rgb yarn_eval(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi, Vec3 wo, NY_PRIVATE float *pdf)
{
  const YarnLobes l = yarn_lobes(p, wi);
  if (pdf) {
    return yarn_eval_pdf_lobes(p, l, wo, pdf);
  }
  return yarn_eval_lobes(p, l, wo);
}

NY_KERNEL_FN float yarn_pdf(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi, Vec3 wo)
{
  return yarn_pdf_lobes(p, yarn_lobes(p, wi, false), wo);
}

struct YarnSample {
  Vec3 wo;      /* yarn frame */
  Rgb weight;   /* eval / pdf for the non-delta lobes; P_T / p_T = 1 for T (with include_T) */
  float pdf;    /* non-delta: conditional density (see above); T: the selection probability p_T */
  bool delta;   /* the T lobe was chosen: wo = -wi exactly */
};

/* Draws w_o with three uniform numbers in [0, 1), given the lobes of w_i (yarn_lobes() with the eval
 * normaliser). With include_T = false the T lobe is never chosen (a renderer that adds T as its own
 * transparent closure); the weight of a non-delta sample is then eval / pdf, and with include_T = true it is
 * eval / ((1 - p_T) pdf), the mixture's weight. Returns false when w_i is not above the surface or nothing is
 * scattered. */
NY_KERNEL_FN bool yarn_sample_lobes(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l, float u_lobe,
                                    float u1, float u2, bool include_T, NY_PRIVATE YarnSample *s)
{
  s->wo = make_vec3(0.0f, 0.0f, 1.0f);
  s->weight = make_rgb(0.0f);
  s->pdf = 0.0f;
  s->delta = false;
  if (!l.valid) {
    return false;
  }
  float u = u_lobe;
  if (include_T) {
    if (u < l.p_T) {
      s->wo = -l.wi;
      s->weight = make_rgb(1.0f);
      s->pdf = l.p_T;
      s->delta = true;
      return true;
    }
    if (!(l.p_T < 1.0f)) {
      return false;
    }
    u = clampf((u - l.p_T) / (1.0f - l.p_T), 0.0f, 0.99999994f);
  }
  Vec3 wo_f; /* the surface-fiber frame's, unless an R node other than the surface fiber drew w_o */
  bool base = true;
  if (u < p.kappa_R) {
    /* R: node q (each with probability 1 / n_R), then its part. */
    const int k = l.n_R == 1 ? 0 : (int)(u / p.kappa_R * (float)l.n_R);
    const int q = k < l.n_R - 1 ? k : l.n_R - 1;
    const float v = l.n_R == 1 ? u : u - p.kappa_R * (float)q / (float)l.n_R; /* within the node's share */
    NY_PRIVATE const YarnRNode &n = l.node[q];
    if (v < p.kappa_R / (float)l.n_R * l.q_TT) {
      /* R's TT part: through the fiber, forward. */
      wo_f = direction_from_angles(sample_truncated_normal(n.tn_TT, u1), sample_truncated_normal(n.tn_TT_phi, u2));
    }
    else {
      /* R: the fiber's specular cone, upper half of the azimuths. */
      wo_f = direction_from_angles(sample_truncated_normal(n.tn_R, u1), kPi * u2 - kHalfPi);
    }
    if (l.n_R > 1) {
      s->wo = r_node_to_yarn(n, wo_f);
      base = false;
    }
  }
  else {
    const float v = clampf((u - p.kappa_R) / (1.0f - p.kappa_R), 0.0f, 0.99999994f);
    if (v < p.kappa_M) {
      /* M lobe; the rescaled selection number is the von Mises acceptance variate. */
      const float v_accept = clampf(v / p.kappa_M, 0.0f, 0.99999994f);
      const float theta = sample_truncated_normal(l.tn_M, u1);
      const float phi = sample_von_mises(l.kappa_vm, u2, v_accept);
      wo_f = direction_from_angles(theta, phi);
    }
    else {
      wo_f = sample_uniform_sphere(u1, u2);
    }
  }
  if (base) {
    s->wo = surface_fiber_to_yarn(p.twist, wo_f);
  }
  const YarnOutgoing o = yarn_outgoing(base ? wo_f : yarn_to_surface_fiber(p.twist, s->wo));
  Rgb f_R;
  float pdf_R;
  yarn_R_nodes(l, s->wo, o, &f_R, &pdf_R);
  const float pdf = yarn_pdf_fiber(p, l, pdf_R, o);
  if (!(pdf > 0.0f)) {
    return false;
  }
  const Rgb f = f_R + yarn_eval_M(p, l, s->wo);
  s->pdf = pdf;
  s->weight = f * (1.0f / (include_T ? (1.0f - l.p_T) * pdf : pdf));
  return true;
}

NY_KERNEL_FN bool yarn_sample(NY_PRIVATE const YarnBsdfParams &p, Vec3 wi, float u_lobe, float u1, float u2,
                              bool include_T, NY_PRIVATE YarnSample *s)
{
  return yarn_sample_lobes(p, yarn_lobes(p, wi), u_lobe, u1, u2, include_T, s);
}

/* A closure-weight estimate of the albedo: P_T + the R lobe's exact energy + the mean M albedo. */
NY_KERNEL_FN Rgb yarn_albedo_estimate(NY_PRIVATE const YarnBsdfParams &p, NY_PRIVATE const YarnLobes &l)
{
  if (!l.valid) {
    return make_rgb(0.0f);
  }
  return make_rgb(l.P_T) + yarn_energy_R(l) + p.albedo_M;
}

}  // namespace ny
