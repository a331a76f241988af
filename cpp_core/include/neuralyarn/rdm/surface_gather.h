// SPDX-License-Identifier: Apache-2.0
//
// The surface level's measurement (issue 18, docs/decisions.md D44): where a cloth's yarns are below a pixel it
// renders as a surface, whose BSDF is the cloth's far-field scattering. It is measured as the maps are, by
// random walks — one level up: through a flat patch of the pattern's curves (plies or yarns), each hit
// scattered by the curve's model exactly as the native closure renders it (kernel/yarn_bsdf.h's sampler with
// the T lobe as a straight continuation; a ray that continued into a tube passes its exit, as the renderer's
// back-facing rule has it).
//
// By reciprocity the walk starts from the viewer: a path enters the patch against a view direction w_v,
// uniformly over one period of the pattern in the patch's middle, and where it leaves is the light direction
// w_l. So the maps hold, per view, what a surface returns toward the viewer from light at w_l: f |cos theta_l|
// per solid angle — the quantity a renderer's closure weights are fitted to (model/surface_fit.h). The cloth is
// taken as isotropic about its normal (the view's azimuth is drawn uniformly, the light's is recorded relative
// to it); the two faces are measured apart (a knit's face and back differ).
//
// Frame: the patch's mid-plane is z = 0, its face toward +z. Side 0 views from +z, side 1 from -z (measured
// in the mirrored frame z -> -z, so that for both the viewer is "up").
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "neuralyarn/geometry/ply.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/units.h"

namespace neuralyarn::rdm {

struct SurfaceGatherOptions {
  uint64_t paths = 4'000'000; /* over both sides and every view bin, equally */
  uint64_t seed = 1;
  int threads = 0;       /* 0: all cores; the maps are the same for any count */
  int view_bins = 8;     /* cos theta_v in equal bins of (0, 1] */
  int light_theta = 16;  /* |cos theta_l| in equal bins of (0, 1] per hemisphere: equal solid angles */
  int light_phi = 24;    /* the light's azimuth relative to the view's, equal bins of [0, 2 pi) */
  int max_events = 1024; /* a path cut here is counted as lost */
  /* The entry rectangle: one period of the pattern centred on (centre_x, centre_y). */
  double centre_x = 0, centre_y = 0, period_x = 0, period_y = 0;
  std::function<void(uint64_t done, uint64_t total)> progress;
};

struct SurfaceMaps {
  int view_bins = 0, light_theta = 0, light_phi = 0;
  /* [side][view][hemisphere (0 the viewer's, 1 the far one)][theta][phi][rgb]: the mean of f |cos theta_l|
   * over the bin (energy per steradian per unit entering energy). */
  std::vector<double> D;
  std::vector<double> tau;       /* [side][view]: what leaves straight through (gaps and the curves' T) */
  std::vector<double> scattered; /* [side][view][rgb]: the rest that leaves (the integral of D) */
  uint64_t paths = 0, paths_lost = 0, paths_past_edges = 0;
  double absorbed[3] = {0, 0, 0}; /* per path */
  double seconds = 0;

  double bin_solid_angle() const { return 2.0 * kPi / (double(light_theta) * double(light_phi)); }
  /* Of D's red value. */
  size_t index(int side, int view, int hemisphere, int theta, int phi) const
  {
    return ((((size_t(side) * size_t(view_bins) + size_t(view)) * 2 + size_t(hemisphere)) * size_t(light_theta) +
             size_t(theta)) * size_t(light_phi) + size_t(phi)) * 3;
  }
  /* Bin centres: cos theta_v, |cos theta_l| and the relative azimuth (radians). */
  double view_cos(int view) const { return (view + 0.5) / view_bins; }
  double light_cos(int theta) const { return (theta + 0.5) / light_theta; }
  double light_phi_centre(int phi) const { return 2.0 * kPi * (phi + 0.5) / light_phi; }
};

/* Walks through `curves` (every curve the same number of points; radius per curve), each hit scattered by
 * `model`. Throws ParameterError for bad options (no paths, bins out of [1, 256], an entry rectangle not
 * positive, finite and inside the patch) and std::invalid_argument for curves EmbreePly refuses. A path that
 * leaves from within one period of the patch's edge (where an endless cloth might have sent it back) is
 * still recorded, and counted in paths_past_edges: the patch must be wide enough that they are few. */
SurfaceMaps gather_surface(const geometry::CurveSet &curves, const model::YarnModel &model,
                           const SurfaceGatherOptions &options);

}  // namespace neuralyarn::rdm
