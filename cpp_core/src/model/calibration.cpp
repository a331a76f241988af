// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/calibration.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

#include <tbb/parallel_for.h>

#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/model/mlp_lanes.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/thread_limit.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

namespace {

/* map / network, or 1 where there is nothing to calibrate. Energies below 1e-5 are Monte Carlo noise in
 * the map (a bin of 20 000 paths resolves about 1e-4). */
float ratio(double map, double net)
{
  constexpr double kFloor = 1e-5;
  if (!(net > kFloor) || !(map > kFloor)) {
    return 1.0f;
  }
  return float(map / net);
}
}  // namespace

ny::Rgb white_furnace(const ny::YarnBsdfParams &p, const ny::Vec3 &wi)
{
  const ny::YarnLobes l = ny::yarn_lobes(p, wi);
  return ny::make_rgb(l.P_T) + ny::yarn_energy_R(l) + m_lobe_energy(p, l);
}

std::vector<ny::Vec3> furnace_directions(const rdm::MapResolution &bins, int sub, bool edge)
{
  std::vector<ny::Vec3> dirs;
  for (int ti = 0; ti < bins.theta_i; ti++) {
    for (int pi = 0; pi < bins.phi_i; pi++) {
      for (int s = 0; s < sub * sub; s++) {
        dirs.push_back(incident_sub_direction(bins, ti, pi, s, sub));
      }
    }
  }
  if (edge) {
    /* theta_i 89.975 deg: beyond the last bin centre the table is constant while the lobes still change. */
    const rdm::MapResolution fine{1800, bins.phi_i, bins.theta_o, bins.phi_o};
    for (int pi = 0; pi < bins.phi_i; pi++) {
      dirs.push_back(incident_sub_direction(fine, fine.theta_i - 1, pi, 0, 1));
    }
  }
  return dirs;
}

FurnaceMax white_furnace_max(const ny::YarnBsdfParams &p, const std::vector<ny::Vec3> &dirs, int threads)
{
  const auto limit = thread_limit(threads);
  std::vector<double> worst(dirs.size());
  tbb::parallel_for(size_t(0), dirs.size(), [&](size_t i) {
    const ny::Rgb e = white_furnace(p, dirs[i]);
    /* NaN is the worst value: it must not hide behind a comparison. */
    worst[i] = std::isnan(e.r) || std::isnan(e.g) || std::isnan(e.b) ? std::nan("")
                                                                       : std::max({e.r, e.g, e.b});
  });
  FurnaceMax f;
  for (size_t i = 0; i < dirs.size(); i++) {
    if (std::isnan(worst[i]) || f.index < 0 || worst[i] > f.value) {
      f = {worst[i], int(i), dirs[i]};
      if (std::isnan(worst[i])) {
        break;
      }
    }
  }
  return f;
}

ExitGrid::ExitGrid(int nt, int np) : theta_bins(nt), phi_bins(np), solid_angle(size_t(nt))
{
  if (nt < 2 || nt % 2 != 0 || np < 1) {
    throw std::invalid_argument("exit grid: theta bins must be even and at least 2, phi bins at least 1");
  }
  for (int to = 0; to < nt; to++) {
    const double t0 = kPi * to / nt, t1 = kPi * (to + 1) / nt;
    solid_angle[size_t(to)] = (std::cos(t0) - std::cos(t1)) * 2.0 * kPi / np;
    for (int po = 0; po < np; po++) {
      const ny::Vec3 wo = train::entry_vec3(0.5 * (t0 + t1), -kPi + 2.0 * kPi * (po + 0.5) / np);
      x.push_back(wo.x);
      y.push_back(wo.y);
      z.push_back(wo.z);
    }
  }
}

void yarn_eval_M_lanes(const ny::YarnBsdfParams &p, const ny::YarnLobes &l, int n, const float *x, const float *y,
                       const float *z, ny::Rgb *out)
{
  if (!l.valid) {
    std::fill_n(out, n, ny::make_rgb(0.0f)); /* yarn_eval_M's zero */
    return;
  }
  /* The input (w_e, w_o): w_e shared by every lane, w_o lane-minor; lanes past n repeat the last exit and are
   * left out. */
  constexpr int L = kMLanes;
  const float we[3] = {l.we.x, l.we.y, l.we.z};
  float in[3 * L], o[6 * L];
  for (int k = 0; k < L; k++) {
    const int e = std::min(k, n - 1);
    in[0 * L + k] = x[e];
    in[1 * L + k] = y[e];
    in[2 * L + k] = z[e];
  }
  if (p.m_two_sided) {
    mlp_forward_io_lanes<6, 6, L, 3>(p.net_M, we, in, o);
  }
  else {
    mlp_forward_io_lanes<6, 3, L, 3>(p.net_M, we, in, o);
  }
  for (int k = 0; k < n; k++) {
    const int side = p.m_two_sided && !(z[k] >= 0.0f) ? 3 : 0; /* as yarn_eval_M: wo.z >= 0 the upper outputs */
    out[k] = ny::make_rgb(o[side * L + k], o[(side + 1) * L + k], o[(side + 2) * L + k]) * l.scale_M;
  }
}

void m_lobe_energy_split(const ny::YarnBsdfParams &p, const ny::YarnLobes &l, const ExitGrid &g, bool split,
                         double up[3], double down[3])
{
  for (int c = 0; c < 3; c++) {
    up[c] = down[c] = 0.0;
  }
  if (!l.valid) {
    return; /* yarn_eval_M's zero */
  }
  const int nt = g.theta_bins, np = g.phi_bins;
  ny::Rgb v[kMLanes];
  for (int to = 0; to < nt; to++) {
    const double dO = g.solid_angle[size_t(to)];
    double *e = split && 2 * to >= nt ? down : up;
    for (int po = 0; po < np; po += kMLanes) {
      const int n = std::min(kMLanes, np - po);
      const size_t q = size_t(to) * size_t(np) + size_t(po);
      yarn_eval_M_lanes(p, l, n, &g.x[q], &g.y[q], &g.z[q], v);
      for (int k = 0; k < n; k++) {
        e[0] += v[k].r * dO;
        e[1] += v[k].g * dO;
        e[2] += v[k].b * dO;
      }
    }
  }
}

ny::Rgb m_lobe_energy(const ny::YarnBsdfParams &p, const ny::YarnLobes &l)
{
  static const ExitGrid grid(64, 128);
  double e[3], unused[3];
  m_lobe_energy_split(p, l, grid, false, e, unused);
  return ny::make_rgb(float(e[0]), float(e[1]), float(e[2]));
}

int calibration_window_half(int phi_bins)
{
  return std::max(0, int(std::lround((20.0 / (360.0 / phi_bins) - 1.0) / 2.0)));
}

EnergyCalibration calibrate_energy(const YarnModel &model, const rdm::RdmMaps &maps, int threads, int bound_sub)
{
  const rdm::MapResolution &b = maps.bins;
  const std::vector<double> ER = maps.energy(maps.r), EM = maps.energy(maps.m);
  const int n = int(b.incident());
  const auto limit = thread_limit(threads);
  auto incident = [&](int k) {
    return train::entry_vec3(rdm::bin_center(k / b.phi_i, 0.0, 0.5 * kPi, b.theta_i),
                             rdm::bin_center(k % b.phi_i, -kPi, kPi, b.phi_i));
  };
  const int half = calibration_window_half(b.phi_i);
  const int window = 2 * half + 1;
  auto window_sum = [&](const std::vector<double> &v, int stride, int k, int c) {
    const int ti = k / b.phi_i, pi = k % b.phi_i;
    double sum = 0.0;
    for (int d = -half; d <= half; d++) {
      const int q = ti * b.phi_i + ((pi + d) % b.phi_i + b.phi_i) % b.phi_i;
      sum += v[size_t(q) * size_t(stride) + size_t(c)];
    }
    return sum;
  };

  YarnModel work = model;
  EnergyCalibration &c = work.calibration;
  c = EnergyCalibration{};
  c.theta_bins = b.theta_i;
  c.phi_bins = b.phi_i;
  c.values.assign(size_t(n) * ny::kYarnCalStride, 1.0f);

  /* Pass 1: dP_T. The M network's escape factor uses the corrected P_T, so M is calibrated after it. */
  {
    YarnModel bare = model;
    bare.calibration = EnergyCalibration{};
    const std::vector<float> bare_flat = bare.kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(bare_flat.data());
    std::vector<double> diff(size_t(n), 0.0);
    tbb::parallel_for(0, n, [&](int k) {
      diff[size_t(k)] = double(maps.p_t[size_t(k)]) - double(ny::yarn_transmission(p, incident(k)));
    });
    for (int k = 0; k < n; k++) {
      c.values[size_t(k) * ny::kYarnCalStride] = float(window_sum(diff, 1, k, 0) / window);
    }
  }
  /* Pass 2: c_R, c_M with dP_T in place. */
  const std::vector<float> flat = work.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  /* P_T at each bin centre as calibrated (the networks' plus the window's mean dP_T), and R and M as the
   * networks give them. */
  std::vector<double> P_T(static_cast<size_t>(n)), net_R(static_cast<size_t>(n) * 3), net_M(static_cast<size_t>(n) * 3);
  tbb::parallel_for(0, n, [&](int k) {
    const ny::YarnLobes l = ny::yarn_lobes(p, incident(k));
    P_T[size_t(k)] = double(l.P_T);
    const ny::Rgb e_m = m_lobe_energy(p, l);
    const ny::Rgb e_r = ny::yarn_energy_R(l);
    net_R[size_t(k) * 3] = e_r.r;
    net_R[size_t(k) * 3 + 1] = e_r.g;
    net_R[size_t(k) * 3 + 2] = e_r.b;
    net_M[size_t(k) * 3] = e_m.r;
    net_M[size_t(k) * 3 + 1] = e_m.g;
    net_M[size_t(k) * 3 + 2] = e_m.b;
  });
  for (int k = 0; k < n; k++) {
    float *v = &c.values[size_t(k) * ny::kYarnCalStride];
    for (int ch = 0; ch < 3; ch++) {
      v[1 + ch] = ratio(window_sum(ER, 3, k, ch), window_sum(net_R, 3, k, ch));
      v[4 + ch] = ratio(window_sum(EM, 3, k, ch), window_sum(net_M, 3, k, ch));
      /* No bin scatters more than it receives: the window's ratios scale R and M by the window's mean,
       * while P_T varies across it (the gaps between fibers), so where P_T is above the window's mean the
       * three together could exceed 1 (at grazing incidence, without this bound: tests/cpp/test_furnace.cpp).
       * The bound is 1, not the window's exit energy: that one would hand the T network's error at the bin
       * to R and M (a dark fiber's R cut by 68 % at 88 deg, docs/decisions.md D35). */
      const double scattered = v[1 + ch] * net_R[size_t(k) * 3 + size_t(ch)] + v[4 + ch] * net_M[size_t(k) * 3 + size_t(ch)];
      const double room = std::max(0.0, 1.0 - P_T[size_t(k)]);
      if (scattered > room && scattered > 0.0) {
        v[1 + ch] = float(v[1 + ch] * room / scattered);
        v[4 + ch] = float(v[4 + ch] * room / scattered);
      }
    }
    bool hit = false;
    for (int j = 1; j < ny::kYarnCalStride; j++) {
      if (v[j] < kCalibrationMin || v[j] > kCalibrationMax) {
        hit = true;
        v[j] = std::clamp(v[j], kCalibrationMin, kCalibrationMax);
      }
    }
    c.clamped += hit ? 1 : 0;
  }
  bound_between_centres(&work, bound_sub, threads);
  return work.calibration;
}

std::vector<ny::Vec3> centre_cell_directions(int theta_bins, int phi_bins, int sub)
{
  /* Over theta_i: [0, first centre], between rows, and the last row itself (every w_i past it takes its
   * energies there, D26); over phi_i: between centres, periodic. */
  std::vector<ny::Vec3> dirs;
  for (int t = -1; t < theta_bins; t++) {
    const double t0 = t < 0 ? 0.0 : rdm::bin_center(t, 0.0, 0.5 * kPi, theta_bins);
    const double t1 = t + 1 < theta_bins ? rdm::bin_center(t + 1, 0.0, 0.5 * kPi, theta_bins) : t0;
    for (int q = 0; q < phi_bins; q++) {
      const double p0 = rdm::bin_center(q, -kPi, kPi, phi_bins), p1 = p0 + 2.0 * kPi / phi_bins;
      for (int i = 0; i < sub; i++) {
        for (int j = 0; j < sub; j++) {
          dirs.push_back(train::entry_vec3(t0 + (t1 - t0) * (i + 0.5) / sub, p0 + (p1 - p0) * (j + 0.5) / sub));
        }
      }
    }
  }
  return dirs;
}

CentreBound bound_between_centres(YarnModel *model, int sub, int threads)
{
  EnergyCalibration &c = model->calibration;
  CentreBound result;
  if (c.empty() || sub < 1) {
    return result;
  }
  const int nt = c.theta_bins, np = c.phi_bins;
  const std::vector<ny::Vec3> dirs = centre_cell_directions(nt, np, sub);
  /* Per direction: the four nodes it weighs, and per channel the factor its energy needs. */
  struct Need {
    int idx[4];
    float w[4];
    float f[3];
  };
  std::vector<Need> need(dirs.size());
  {
    const std::vector<float> flat = model->kernel_flat();
    const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
    const auto limit = thread_limit(threads);
    tbb::parallel_for(size_t(0), dirs.size(), [&](size_t k) {
      Need &n = need[k];
      const ny::YarnLobes l = ny::yarn_lobes(p, dirs[k]);
      ny::yarn_incident_bilinear(nt, np, l.we, n.idx, n.w);
      const ny::Rgb scattered = ny::yarn_energy_R(l) + m_lobe_energy(p, l);
      const double room = std::max(0.0, 1.0 - double(l.P_T));
      const float s[3] = {scattered.r, scattered.g, scattered.b};
      for (int ch = 0; ch < 3; ch++) {
        /* A relative slack above float rounding, so that a bounded table stays as it is. */
        n.f[ch] = s[ch] > room * (1.0 + 1e-5) ? float(room / s[ch]) : 1.0f;
      }
    });
  }
  /* Each node: the smallest factor over the directions it weighs (a minimum, so in any order the same). */
  std::vector<float> factor(size_t(nt) * size_t(np) * 3, 1.0f);
  for (const Need &n : need) {
    for (int k = 0; k < 4; k++) {
      if (n.w[k] > 0.0f) {
        for (int ch = 0; ch < 3; ch++) {
          float &f = factor[size_t(n.idx[k]) * 3 + size_t(ch)];
          f = std::min(f, n.f[ch]);
        }
      }
    }
  }
  for (size_t node = 0; node < size_t(nt) * size_t(np); node++) {
    bool changed = false;
    for (int ch = 0; ch < 3; ch++) {
      const float f = factor[node * 3 + size_t(ch)];
      if (f < 1.0f) {
        float *v = &c.values[node * ny::kYarnCalStride];
        v[1 + ch] *= f;
        v[4 + ch] *= f;
        changed = true;
        result.smallest = std::min(result.smallest, double(f));
      }
    }
    result.nodes += changed ? 1 : 0;
  }
  return result;
}

}  // namespace neuralyarn::model
