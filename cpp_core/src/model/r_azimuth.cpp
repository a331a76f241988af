// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/r_azimuth.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/presets.h" /* ParameterError */

namespace neuralyarn::model {

namespace {
constexpr double kPi = 3.14159265358979323846;

ny::Vec3 direction(double theta, double phi)
{
  return ny::make_vec3(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)),
                       float(std::cos(theta)));
}
}  // namespace

RAzimuthTable fit_r_azimuth(const YarnModel &model, const rdm::RdmMaps &maps, const RAzimuthOptions &o)
{
  if (o.theta_bins < 1 || o.phi_bins < 1 || o.azimuth_bins < 2 || o.theta_bins > 1024 || o.phi_bins > 1024 ||
      o.azimuth_bins > 1024) {
    throw ParameterError("r_azimuth", "table bins out of range");
  }
  YarnModel uniform = model;
  uniform.r_azimuth = RAzimuthTable{};
  const std::vector<float> flat = uniform.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  const rdm::MapResolution &b = maps.bins;
  const int na = o.azimuth_bins;

  /* phi~_o bin of each map bin's centre (-1: not on the upper half, where R cannot go). */
  std::vector<int> az_of(b.outgoing(), -1);
  for (int to = 0; to < b.theta_o; to++) {
    for (int po = 0; po < b.phi_o; po++) {
      const ny::Vec3 wf = ny::yarn_to_surface_fiber(
          p.twist, direction(rdm::bin_center(to, 0.0, kPi, b.theta_o), rdm::bin_center(po, -kPi, kPi, b.phi_o)));
      if (wf.z > 0.0f) {
        az_of[size_t(to) * size_t(b.phi_o) + size_t(po)] =
            std::min(na - 1, int((ny::phi_of(wf) + 0.5 * kPi) / kPi * na));
      }
    }
  }

  RAzimuthTable t;
  t.theta_bins = o.theta_bins;
  t.phi_bins = o.phi_bins;
  t.azimuth_bins = na;
  t.values.assign(size_t(o.theta_bins) * size_t(o.phi_bins) * size_t(na), 0.0f);
  const int n_sub = 4, n_theta = 32, n_phi = 64;
  tbb::parallel_for(0, o.theta_bins, [&](int tt) {
    std::vector<double> map_e(size_t(o.phi_bins) * size_t(na), 0.0), lobe_e(map_e.size(), 0.0);
    std::vector<double> bins(b.outgoing(), 0.0);
    for (int ti = 0; ti < b.theta_i; ti++) {
      if (ti * o.theta_bins / b.theta_i != tt) {
        continue;
      }
      for (int pi = 0; pi < b.phi_i; pi++) {
        const size_t row = size_t(pi * o.phi_bins / b.phi_i) * size_t(na);
        /* The maps. */
        for (int to = 0; to < b.theta_o; to++) {
          const double dO = maps.outgoing_solid_angle(to);
          for (int po = 0; po < b.phi_o; po++) {
            const int k = az_of[size_t(to) * size_t(b.phi_o) + size_t(po)];
            if (k >= 0) {
              const float *v = &maps.r[maps.map_index(ti, pi, to, po)];
              map_e[row + size_t(k)] += (v[0] + v[1] + v[2]) / 3.0 * dO;
            }
          }
        }
        /* The uniform-azimuth lobe over the same bins: stratified samples of its own proposal for n_sub^2
         * incident directions inside the bin (eval / pdf / count is each sample's share of its energy). */
        std::fill(bins.begin(), bins.end(), 0.0);
        const double t0 = 0.5 * kPi * ti / b.theta_i, t1 = 0.5 * kPi * (ti + 1) / b.theta_i;
        for (int s = 0; s < n_sub * n_sub; s++) {
          const double ct = std::cos(t0) + ((s / n_sub) + 0.5) / n_sub * (std::cos(t1) - std::cos(t0));
          const double ph = -kPi + 2.0 * kPi * (pi + (s % n_sub + 0.5) / n_sub) / b.phi_i;
          const ny::YarnLobes l = ny::yarn_lobes(p, direction(std::acos(ct), ph));
          for (int j = 0; j < n_theta; j++) {
            const float theta = ny::sample_truncated_normal(l.tn_R, (j + 0.5f) / n_theta);
            for (int k = 0; k < n_phi; k++) {
              const ny::Vec3 wo_f = ny::direction_from_angles(theta, -ny::kHalfPi + ny::kPi * (k + 0.5f) / n_phi);
              const float pdf = ny::yarn_pdf_R_fiber(l, wo_f);
              if (!(pdf > 0.0f)) {
                continue;
              }
              const ny::Vec3 wo = ny::surface_fiber_to_yarn(p.twist, wo_f);
              const int to = rdm::bin_of(std::acos(std::clamp(double(wo.z), -1.0, 1.0)), 0.0, kPi, b.theta_o);
              const int po = rdm::bin_of(std::atan2(double(wo.y), double(wo.x)), -kPi, kPi, b.phi_o);
              bins[size_t(to) * size_t(b.phi_o) + size_t(po)] +=
                  ny::average(ny::yarn_eval_R_fiber(l, wo_f)) / (pdf * n_theta * n_phi * n_sub * n_sub);
            }
          }
        }
        for (size_t q = 0; q < bins.size(); q++) {
          if (bins[q] > 0.0 && az_of[q] >= 0) {
            lobe_e[row + size_t(az_of[q])] += bins[q];
          }
        }
      }
    }
    for (int tp = 0; tp < o.phi_bins; tp++) {
      double *m = &map_e[size_t(tp) * size_t(na)], *l = &lobe_e[size_t(tp) * size_t(na)];
      double lmax = 0, msum = 0, lsum = 0;
      for (int k = 0; k < na; k++) {
        lmax = std::max(lmax, l[k]);
        msum += m[k];
        lsum += l[k];
      }
      const double mean = lsum > 0 && msum > 0 ? msum / lsum : 1.0;
      std::vector<double> r(size_t(na), 1.0);
      for (int k = 0; k < na; k++) {
        /* A bin the lobe hardly reaches carries no information about the shape: the row's mean there. */
        r[size_t(k)] = l[k] > 1e-3 * lmax && lmax > 0 ? m[k] / l[k] : mean;
        r[size_t(k)] = std::clamp(r[size_t(k)], mean / 20.0, mean * 20.0);
      }
      double sum = 0;
      for (double x : r) {
        sum += x;
      }
      float *out = &t.values[(size_t(tt) * size_t(o.phi_bins) + size_t(tp)) * size_t(na)];
      for (int k = 0; k < na; k++) {
        out[k] = sum > 0 ? float(r[size_t(k)] / (sum * kPi / na)) : float(1.0 / kPi);
      }
    }
  });
  return t;
}

}  // namespace neuralyarn::model
