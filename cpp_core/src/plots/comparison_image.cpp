// SPDX-License-Identifier: Apache-2.0
//
// `neuralyarn check --image`, `bake --image`: the model's lobes beside the maps for one incident direction
// (OpenImageIO).
#include "neuralyarn/plots.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/fidelity.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

void write_comparison_image(const YarnModel &model, const rdm::RdmMaps &maps, double theta_i_deg, double phi_i_deg,
                            const std::string &path)
{
  const std::vector<float> flat = model.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const rdm::MapResolution &b = maps.bins;
  const int ti = rdm::bin_of(theta_i_deg * kDeg, 0.0, 0.5 * kPi, b.theta_i);
  const int pi = rdm::bin_of(phi_i_deg * kDeg, -kPi, kPi, b.phi_i);
  const ny::Vec3 wi = train::entry_vec3(rdm::bin_center(ti, 0.0, 0.5 * kPi, b.theta_i),
                                        rdm::bin_center(pi, -kPi, kPi, b.phi_i));
  const ny::YarnLobes l = ny::yarn_lobes(p, wi);
  const int scale = std::max(1, 360 / b.phi_o), pw = b.phi_o * scale, ph = b.theta_o * scale;
  const int gap = 8, header = 24, W = 4 * pw + 3 * gap, H = ph + header;
  OIIO::ImageBuf img(OIIO::ImageSpec(W, H, 3, OIIO::TypeDesc::FLOAT));
  const float bg[3] = {0.08f, 0.08f, 0.09f};
  OIIO::ImageBufAlgo::fill(img, OIIO::cspan<float>(bg, 3));
  /* Panels: 0 M map, 1 M network, 2 R map, 3 R analytic. Each pair shares its map's maximum. */
  auto value = [&](int panel, int to, int po) {
    const double th = rdm::bin_center(to, 0.0, kPi, b.theta_o), ph_o = rdm::bin_center(po, -kPi, kPi, b.phi_o);
    const ny::Vec3 wo = train::entry_vec3(th, ph_o);
    const float *mm = &maps.m[maps.map_index(ti, pi, to, po)];
    const float *rr = &maps.r[maps.map_index(ti, pi, to, po)];
    switch (panel) {
      case 0:
        return ny::make_rgb(mm[0], mm[1], mm[2]);
      case 1:
        return ny::yarn_eval_M(p, l, wo);
      case 2:
        return ny::make_rgb(rr[0], rr[1], rr[2]);
      default:
        return ny::yarn_eval_R(p, l, wo);
    }
  };
  float vmax[2] = {0, 0};
  for (int to = 0; to < b.theta_o; to++) {
    for (int po = 0; po < b.phi_o; po++) {
      for (int pair = 0; pair < 2; pair++) {
        const ny::Rgb v = value(2 * pair, to, po);
        vmax[pair] = std::max({vmax[pair], v.r, v.g, v.b});
      }
    }
  }
  for (int panel = 0; panel < 4; panel++) {
    const float vm = vmax[panel / 2];
    for (int to = 0; to < b.theta_o; to++) {
      for (int po = 0; po < b.phi_o; po++) {
        const ny::Rgb v = value(panel, to, po);
        float px[3];
        for (int c = 0; c < 3; c++) {
          const double x = channel(v, c);
          /* Two and a half decades on a log scale. */
          px[c] = (vm > 0 && x > 0) ? float(std::clamp((std::log10(x / vm) + 2.5) / 2.5, 0.0, 1.0)) : 0.0f;
        }
        for (int dy = 0; dy < scale; dy++) {
          for (int dx = 0; dx < scale; dx++) {
            img.setpixel(panel * (pw + gap) + po * scale + dx, header + to * scale + dy, px, 3);
          }
        }
      }
    }
  }
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%s  theta_i %.0f phi_i %.0f deg | M map | M network | R map | R analytic (log10, 2.5 decades)",
                model.preset.name.c_str(), theta_i_deg, phi_i_deg);
  const float white[3] = {0.9f, 0.9f, 0.9f};
  if (!OIIO::ImageBufAlgo::render_text(img, 6, 17, buf, 14, "DejaVuSans", white)) {
    (void)img.geterror();
  }
  if (!img.write(path)) {
    throw std::runtime_error("cannot write '" + path + "': " + img.geterror());
  }
}

}  // namespace neuralyarn::model
