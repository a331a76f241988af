// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/fiber_report.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/random.h"
#include "neuralyarn/units.h"

namespace neuralyarn {

std::vector<AlbedoRow> fiber_albedo_table(const FiberPreset &preset, const std::vector<double> &theta_i_deg,
                                          int samples, uint64_t seed)
{
  const ny::FiberBsdfParams params = preset.fiber_params();
  std::vector<AlbedoRow> rows;
  for (size_t k = 0; k < theta_i_deg.size(); k++) {
    AlbedoRow row;
    row.theta_i_deg = theta_i_deg[k];
    const ny::Vec3 wi = ny::direction_from_angles(float(theta_i_deg[k] * kDeg), 0.0f);
    const ny::FiberLobes lobes = ny::fiber_lobes(params, wi);
    row.fresnel = lobes.energy_R;
    row.analytic = ny::fiber_albedo(lobes);
    row.p_R = lobes.p_R;

    /* Each row has its own stream so that rows do not depend on each other's sample counts. */
    Rng rng(seed * 0x9E3779B97F4A7C15ull + k);
    double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
    for (int s = 0; s < samples; s++) {
      const float u0 = uniform_float(rng), u1 = uniform_float(rng), u2 = uniform_float(rng);
      ny::Vec3 wo;
      ny::Rgb w;
      float pdf;
      if (!ny::fiber_sample(params, wi, u0, u1, u2, [&] { return uniform_float(rng); }, &wo, &w, &pdf)) {
        continue;
      }
      const double c[3] = {w.r, w.g, w.b};
      for (int i = 0; i < 3; i++) {
        sum[i] += c[i];
        sum2[i] += c[i] * c[i];
      }
    }
    double mean[3], err[3];
    for (int i = 0; i < 3; i++) {
      mean[i] = samples > 0 ? sum[i] / samples : 0.0;
      const double var = samples > 1 ? std::max(0.0, sum2[i] / samples - mean[i] * mean[i]) : 0.0;
      err[i] = samples > 1 ? std::sqrt(var / (samples - 1)) : 0.0;
    }
    row.mc_mean = ny::make_rgb(float(mean[0]), float(mean[1]), float(mean[2]));
    row.mc_stderr = ny::make_rgb(float(err[0]), float(err[1]), float(err[2]));
    rows.push_back(row);
  }
  return rows;
}

AzimuthComparison compare_tt_azimuth(double gamma_rad)
{
  AzimuthComparison c;
  c.gamma_rad = gamma_rad;
  c.kappa = 1.0 / (gamma_rad * gamma_rad);
  /* Mass of N(0, gamma) inside [-pi, pi]: the authors' Gaussian renormalised on the circle. */
  const double norm = std::erf(kPi / (gamma_rad * std::sqrt(2.0)));
  auto gauss = [&](double x) { return std::exp(-0.5 * x * x / (gamma_rad * gamma_rad)) / (gamma_rad * std::sqrt(2 * kPi) * norm); };
  auto vm = [&](double x) { return double(ny::von_mises_pdf(float(x), float(c.kappa))); };
  c.peak_von_mises = vm(0.0);
  c.peak_gaussian = gauss(0.0);
  /* Composite Simpson on [-pi, pi]; 20000 intervals resolve widths down to 0.01 degrees. */
  const int n = 20000;
  const double h = 2 * kPi / n;
  double sum = 0.0;
  for (int i = 0; i <= n; i++) {
    const double x = -kPi + i * h;
    const double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    sum += w * std::fabs(vm(x) - gauss(x));
  }
  c.l1_distance = sum * h / 3.0;
  return c;
}

}  // namespace neuralyarn
