// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/r_azimuth.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/presets.h" /* ParameterError */
#include "neuralyarn/train/dataset.h"

namespace neuralyarn::model {

namespace {
constexpr double kPi = 3.14159265358979323846;
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
      const Eigen::Vector3f w =
          train::entry_direction(rdm::bin_center(to, 0.0, kPi, b.theta_o), rdm::bin_center(po, -kPi, kPi, b.phi_o));
      const ny::Vec3 wf = ny::yarn_to_surface_fiber(p.twist, ny::make_vec3(w.x(), w.y(), w.z()));
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
  tbb::parallel_for(0, o.theta_bins, [&](int tt) {
    std::vector<double> map_e(size_t(o.phi_bins) * size_t(na), 0.0), lobe_e(map_e.size(), 0.0);
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
        /* The uniform-azimuth lobe over the same bins. */
        integrate_r_lobe(p, b, ti, pi, [&](int to, int po, const ny::Rgb &e) {
          const int k = az_of[size_t(to) * size_t(b.phi_o) + size_t(po)];
          if (k >= 0) {
            lobe_e[row + size_t(k)] += ny::average(e);
          }
        });
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
