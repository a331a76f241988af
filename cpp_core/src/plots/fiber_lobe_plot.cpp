// SPDX-License-Identifier: Apache-2.0
//
// `neuralyarn fiber --out`: a picture of a fiber preset's scattering lobe (OpenImageIO).
#include "neuralyarn/plots.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/units.h"

namespace neuralyarn {

namespace {

using OIIO::ImageBuf;
using OIIO::ImageSpec;
namespace IBA = OIIO::ImageBufAlgo;

void text(ImageBuf &img, int x, int y, const std::string &s, int size = 14)
{
  const float white[3] = {0.9f, 0.9f, 0.9f};
  /* A missing font only loses the labels, never the plot. */
  if (!IBA::render_text(img, x, y, s, size, "DejaVuSans", white)) {
    (void)img.geterror();
  }
}

void line(ImageBuf &img, double x0, double y0, double x1, double y1, const float *color)
{
  IBA::render_line(img, int(std::lround(x0)), int(std::lround(y0)), int(std::lround(x1)), int(std::lround(y1)),
                   OIIO::cspan<float>(color, 3));
}

}  // namespace

void write_fiber_lobe_plot(const FiberPreset &preset, double theta_i_deg, double phi_i_deg, const std::string &path)
{
  const ny::FiberBsdfParams params = preset.fiber_params();
  const float th_i = float(theta_i_deg * kDeg), ph_i = float(phi_i_deg * kDeg);
  const ny::Vec3 wi = ny::direction_from_angles(th_i, ph_i);
  const ny::FiberLobes lobes = ny::fiber_lobes(params, wi);

  const int panel = 512, header = 40, W = 2 * panel, H = panel + header;
  ImageBuf img(ImageSpec(W, H, 3, OIIO::TypeDesc::FLOAT));
  const float bg[3] = {0.08f, 0.08f, 0.09f};
  IBA::fill(img, OIIO::cspan<float>(bg, 3));

  /* Left: polar plot in the plane spanned by the fiber tangent x and the incident azimuth a. A direction
   * at in-plane angle psi is cos(psi) a + sin(psi) x; psi = theta on the incident side. The radius is
   * sqrt(eval / max) per channel so that the broad TT lobe stays visible next to a sharp R peak. */
  const ny::Vec3 a = ny::make_vec3(0.0f, std::sin(ph_i), std::cos(ph_i));
  const ny::Vec3 xt = ny::make_vec3(1.0f, 0.0f, 0.0f);
  const int n_psi = 2048;
  std::vector<ny::Rgb> vals(n_psi);
  float vmax = 0.0f;
  for (int i = 0; i < n_psi; i++) {
    const double psi = -kPi + 2 * kPi * (i + 0.5) / n_psi;
    const ny::Vec3 wo = a * float(std::cos(psi)) + xt * float(std::sin(psi));
    vals[i] = ny::fiber_eval_lobes(lobes, wo);
    vmax = std::max({vmax, vals[i].r, vals[i].g, vals[i].b});
  }
  const double cx = panel / 2.0, cy = header + panel / 2.0, rmax = panel * 0.45;
  const float grey[3] = {0.35f, 0.35f, 0.35f}, white[3] = {1.0f, 1.0f, 1.0f};
  for (int ring = 1; ring <= 4; ring++) {
    const double r = rmax * ring / 4.0;
    for (int i = 0; i < 256; i++) {
      const double t0 = 2 * kPi * i / 256, t1 = 2 * kPi * (i + 1) / 256;
      line(img, cx + r * std::cos(t0), cy + r * std::sin(t0), cx + r * std::cos(t1), cy + r * std::sin(t1), grey);
    }
  }
  line(img, cx - rmax, cy, cx + rmax, cy, grey); /* the fiber axis */
  /* Incident direction (screen x = tangent component, screen up = a component). */
  line(img, cx, cy, cx + rmax * wi.x, cy - rmax * ny::dot(wi, a), white);
  const float colors[3][3] = {{1.0f, 0.25f, 0.25f}, {0.25f, 1.0f, 0.25f}, {0.35f, 0.5f, 1.0f}};
  for (int ch = 0; ch < 3; ch++) {
    double px = 0, py = 0;
    for (int i = 0; i <= n_psi; i++) {
      const int k = i % n_psi;
      const double psi = -kPi + 2 * kPi * (k + 0.5) / n_psi;
      const float v = ch == 0 ? vals[k].r : (ch == 1 ? vals[k].g : vals[k].b);
      const double r = vmax > 0 ? rmax * std::sqrt(std::max(0.0f, v) / vmax) : 0.0;
      const double x = cx + r * std::sin(psi), y = cy - r * std::cos(psi);
      if (i > 0) {
        line(img, px, py, x, y, colors[ch]);
      }
      px = x;
      py = y;
    }
  }

  /* Right: eval over (phi_o horizontal, theta_o vertical), three decades on a log scale per channel. */
  for (int y = 0; y < panel; y++) {
    const double th_o = kPi / 2 - kPi * (y + 0.5) / panel;
    for (int x = 0; x < panel; x++) {
      const double ph_o = -kPi + 2 * kPi * (x + 0.5) / panel;
      const ny::Rgb v = ny::fiber_eval_lobes(lobes, ny::direction_from_angles(float(th_o), float(ph_o)));
      float px[3];
      const float c[3] = {v.r, v.g, v.b};
      for (int ch = 0; ch < 3; ch++) {
        px[ch] = (vmax > 0 && c[ch] > 0) ? std::clamp((std::log10(c[ch] / vmax) + 3.0f) / 3.0f, 0.0f, 1.0f) : 0.0f;
      }
      img.setpixel(panel + x, header + y, px, 3);
    }
  }
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%s fiber lobe, theta_i = %.1f deg, phi_i = %.1f deg", preset.name.c_str(),
                theta_i_deg, phi_i_deg);
  text(img, 10, 18, buf, 16);
  text(img, 10, 36, "left: longitudinal plane, radius ~ sqrt(f cos), RGB curves; right: log10 f cos over (phi_o, theta_o)", 12);

  if (!img.write(path)) {
    throw std::runtime_error("cannot write '" + path + "': " + img.geterror());
  }
}

}  // namespace neuralyarn
