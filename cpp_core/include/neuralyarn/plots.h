// SPDX-License-Identifier: Apache-2.0
//
// Pictures the command line writes (OpenImageIO): in a library of their own, `neuralyarn_plots`, so that
// only the CLI loads OpenImageIO and the ~250 libraries Debian's build of it pulls in (about 0.5 s at
// every process start; the tests and benchmarks link the core alone).
#pragma once

#include <string>
#include <vector>

#include "neuralyarn/model/model.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn {

/* A PNG (any format OpenImageIO writes, by extension): a polar plot of the fiber's lobe in the
 * longitudinal plane of w_i and a (phi_o, theta_o) map of eval, for the incident direction
 * (theta_i, phi_i) in degrees. Throws std::runtime_error when the file cannot be written. */
void write_fiber_lobe_plot(const FiberPreset &preset, double theta_i_deg, double phi_i_deg, const std::string &path);

/* An OpenEXR file of `rgb` (interleaved, row 0 the top), float, zip-compressed, written under a temporary name
 * and moved into place. Throws std::runtime_error when the file cannot be written. */
void write_rgb_exr(const std::vector<float> &rgb, int width, int height, const std::string &path);

namespace model {

/* Side-by-side PNG for one incident direction: the M map and the M network, the R map and the analytic R
 * lobe, over (phi_o horizontal, theta_o vertical), each pair on the same log scale. */
void write_comparison_image(const YarnModel &model, const rdm::RdmMaps &maps, double theta_i_deg, double phi_i_deg,
                            const std::string &path);

}  // namespace model
}  // namespace neuralyarn
