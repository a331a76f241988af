// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/forward_peak.h"

#include <cmath>
#include <string>

#include <Eigen/Core>
#include <tbb/parallel_for.h>

#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/lobe_fidelity.h"
#include "neuralyarn/presets.h" /* ParameterError */
#include "neuralyarn/thread_limit.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

namespace {

Eigen::Vector3d dir(double theta, double phi)
{
  return Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
}

/* lobe_fidelity.h's incident_sub_direction(), the directions the measure integrates the model over. */
Eigen::Vector3d incident_sub(const rdm::MapResolution &b, int ti, int pi, int s, int sub)
{
  const ny::Vec3 w = incident_sub_direction(b, ti, pi, s, sub);
  return Eigen::Vector3d(w.x, w.y, w.z);
}

Eigen::Vector3d incident_centre(const rdm::MapResolution &b, int ti, int pi)
{
  return dir(rdm::bin_center(ti, 0.0, 0.5 * kPi, b.theta_i), rdm::bin_center(pi, -kPi, kPi, b.phi_i));
}

/* Outgoing direction s of sub x sub inside bin (to, po), uniform in solid angle. */
Eigen::Vector3d outgoing_sub(const rdm::MapResolution &b, int to, int po, int s, int sub)
{
  const double c0 = std::cos(kPi * to / b.theta_o), c1 = std::cos(kPi * (to + 1) / b.theta_o);
  const double u = (s / sub + 0.5) / sub, v = (s % sub + 0.5) / sub;
  return dir(std::acos(c0 + u * (c1 - c0)), -kPi + 2.0 * kPi * (po + v) / b.phi_o);
}

void check_options(const ForwardPeakOptions &o)
{
  if (!(o.cone_deg > 0.0 && o.cone_deg < o.ring_deg && o.ring_deg <= 90.0)) {
    throw ParameterError("forward peak", "needs 0 < cone < ring <= 90 degrees");
  }
  if (!(o.kappa_min > 0.0 && o.kappa_min < o.kappa_max && std::isfinite(o.kappa_max) && o.kappa_steps >= 2 &&
        o.kappa_steps <= 1000))
  {
    throw ParameterError("forward peak", "needs 0 < kappa_min < kappa_max (finite) and 2..1000 steps");
  }
  if (!(o.beta_min_deg > 0.0 && o.beta_min_deg < o.beta_max_deg && o.beta_max_deg <= 90.0 &&
        o.gamma_min_deg > 0.0 && o.gamma_min_deg < o.gamma_max_deg && o.gamma_max_deg <= 180.0 &&
        o.arc_steps >= 2 && o.arc_steps <= 100))
  {
    throw ParameterError("forward peak", "needs 0 < beta_min < beta_max <= 90, 0 < gamma_min < gamma_max <= 180 "
                                         "degrees and 2..100 arc steps");
  }
  if (!(o.sub >= 1 && o.sub <= 16)) {
    throw ParameterError("forward peak", "needs 1..16 sub-directions per side");
  }
}

}  // namespace

double luminance(const double rgb[3]) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

double vmf_density(double cos_psi, double kappa)
{
  /* kappa e^{kappa (c - 1)} / (2 pi (1 - e^{-2 kappa})): no overflow for any kappa. */
  return kappa * std::exp(kappa * (cos_psi - 1.0)) / (2.0 * kPi * -std::expm1(-2.0 * kappa));
}

double arc_density(const ny::Vec3 &wi_f, const ny::Vec3 &wo_f, double beta, double gamma)
{
  const double dtheta = double(ny::theta_of(wo_f)) + double(ny::theta_of(wi_f));
  double dphi = std::remainder(double(ny::phi_of(wo_f)) - double(ny::phi_of(wi_f)) - kPi, 2.0 * kPi);
  double az = 0.0;
  for (int k = -1; k <= 1; k++) { /* wrapped: widths up to ~60 degrees need the neighbours */
    const double x = (dphi + 2.0 * kPi * k) / gamma;
    az += std::exp(-0.5 * x * x);
  }
  const double lon = std::exp(-0.5 * (dtheta / beta) * (dtheta / beta));
  return lon * az / (2.0 * kPi * beta * gamma * std::max(double(ny::cos_theta(wo_f)), 1e-6));
}

double forward_lobe_in_bin(const rdm::MapResolution &b, int ti, int pi, int to, int po, double kappa, int sub)
{
  rdm::RdmMaps g;
  g.bins = b;
  const double dO = g.outgoing_solid_angle(to) / (sub * sub);
  double sum = 0.0;
  for (int si = 0; si < sub * sub; si++) {
    const Eigen::Vector3d d = -incident_sub(b, ti, pi, si, sub);
    for (int so = 0; so < sub * sub; so++) {
      sum += vmf_density(d.dot(outgoing_sub(b, to, po, so, sub)), kappa) * dO;
    }
  }
  return sum / (sub * sub);
}

ForwardPeakTable fit_forward_peaks(const rdm::RdmMaps &maps, const ForwardPeakOptions &o, const rdm::RdmMaps *maps_b)
{
  check_options(o);
  const rdm::MapResolution &b = maps.bins;
  if (maps_b && !(maps_b->bins == b)) {
    throw ParameterError("forward peak", "the two maps have different resolutions");
  }
  ForwardPeakTable table;
  table.theta_bins = b.theta_i;
  table.phi_bins = b.phi_i;
  table.peaks.assign(size_t(b.theta_i) * size_t(b.phi_i), ForwardPeak{});
  /* The lobe's parameters: kappa (spot) or (beta, gamma) (arc), each on a log grid. */
  auto log_grid = [](double lo, double hi, int n) {
    std::vector<double> g(static_cast<size_t>(n));
    for (int k = 0; k < n; k++) {
      g[size_t(k)] = lo * std::pow(hi / lo, double(k) / (n - 1));
    }
    return g;
  };
  std::vector<std::array<double, 2>> grid;
  if (o.shape == ForwardShape::kSpot) {
    for (double k : log_grid(o.kappa_min, o.kappa_max, o.kappa_steps)) {
      grid.push_back({k, 0.0});
    }
  }
  else {
    for (double be : log_grid(o.beta_min_deg * kDeg, o.beta_max_deg * kDeg, o.arc_steps)) {
      for (double ga : log_grid(o.gamma_min_deg * kDeg, o.gamma_max_deg * kDeg, o.arc_steps)) {
        grid.push_back({be, ga});
      }
    }
  }
  const ny::TwistRotation twist = ny::make_twist_rotation(float(maps.surface_alpha()));
  const int half = calibration_window_half(b.phi_i);
  /* The outgoing bins' centre directions, which every incident bin's cone and ring are chosen from. */
  std::vector<Eigen::Vector3d> centres;
  for (int to = 0; to < b.theta_o; to++) {
    for (int po = 0; po < b.phi_o; po++) {
      centres.push_back(dir(rdm::bin_center(to, 0.0, kPi, b.theta_o), rdm::bin_center(po, -kPi, kPi, b.phi_o)));
    }
  }
  auto fiber = [&twist](const Eigen::Vector3d &w) {
    return ny::yarn_to_surface_fiber(twist, ny::make_vec3(float(w.x()), float(w.y()), float(w.z())));
  };
  const double cos_cone = std::cos(o.cone_deg * kDeg), cos_ring = std::cos(o.ring_deg * kDeg);
  const auto limit = thread_limit(o.threads);
  tbb::parallel_for(0, b.theta_i * b.phi_i, [&](int k) {
    const int ti = k / b.phi_i, pi = k % b.phi_i;
    /* The cone's cells of every incident bin of the window, with their excess over their own ring. */
    struct Cell {
      double e[3];
      double noise;                /* half the luminance of the two maps' excesses' difference */
      double dO;                   /* one sub-direction pair's share of the bin's solid angle */
      std::vector<double> cos_psi; /* spot: sub^2 incident x sub^2 outgoing directions, w_o . -w_i */
      std::vector<std::array<ny::Vec3, 2>> pairs; /* arc: the same pairs (w_i, w_o) in the surface-fiber frame */
    };
    std::vector<Cell> cells;
    for (int d = -half; d <= half; d++) {
      const int q = ((pi + d) % b.phi_i + b.phi_i) % b.phi_i;
      const Eigen::Vector3d fwd = -incident_centre(b, ti, q);
      /* The ring's mean radiance of map A and, where there is one, map B. */
      double ring_e[2][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}}, ring_o = 0.0;
      const rdm::RdmMaps *src[2] = {&maps, maps_b};
      const int n_maps = maps_b ? 2 : 1;
      std::vector<std::array<int, 2>> cone;
      for (int to = 0; to < b.theta_o; to++) {
        const double dO = maps.outgoing_solid_angle(to);
        for (int po = 0; po < b.phi_o; po++) {
          const double c = fwd.dot(centres[size_t(to) * size_t(b.phi_o) + size_t(po)]);
          if (c < cos_ring) {
            continue;
          }
          if (c >= cos_cone) {
            cone.push_back({to, po});
            continue;
          }
          for (int m = 0; m < n_maps; m++) {
            const float *v = &src[m]->m[maps.map_index(ti, q, to, po)];
            for (int ch = 0; ch < 3; ch++) {
              ring_e[m][ch] += double(v[ch]) * dO;
            }
          }
          ring_o += dO;
        }
      }
      std::vector<Eigen::Vector3d> minus_wi(size_t(o.sub * o.sub));
      for (int si = 0; si < o.sub * o.sub; si++) {
        minus_wi[size_t(si)] = -incident_sub(b, ti, q, si, o.sub);
      }
      for (const auto &tp : cone) {
        const double dO = maps.outgoing_solid_angle(tp[0]);
        Cell cell{{0.0, 0.0, 0.0}, 0.0, dO / (o.sub * o.sub * o.sub * o.sub), {}, {}};
        for (int so = 0; so < o.sub * o.sub; so++) {
          const Eigen::Vector3d wo = outgoing_sub(b, tp[0], tp[1], so, o.sub);
          for (const Eigen::Vector3d &d : minus_wi) {
            if (o.shape == ForwardShape::kArc) {
              cell.pairs.push_back({fiber(-d), fiber(wo)});
            }
            else {
              cell.cos_psi.push_back(d.dot(wo));
            }
          }
        }
        double e[2][3];
        for (int m = 0; m < n_maps; m++) {
          const float *v = &src[m]->m[maps.map_index(ti, q, tp[0], tp[1])];
          for (int ch = 0; ch < 3; ch++) {
            e[m][ch] = (double(v[ch]) - (ring_o > 0.0 ? ring_e[m][ch] / ring_o : 0.0)) * dO;
          }
        }
        for (int ch = 0; ch < 3; ch++) {
          cell.e[ch] = n_maps == 2 ? 0.5 * (e[0][ch] + e[1][ch]) : e[0][ch];
        }
        cell.noise = n_maps == 2 ? 0.5 * std::abs(luminance(e[0]) - luminance(e[1])) : 0.0;
        cells.push_back(std::move(cell));
      }
    }
    /* The unit-energy lobe over a cell's stored directions. */
    auto lobe_in_cell = [&o](const Cell &c, const std::array<double, 2> &x) {
      double sum = 0.0;
      if (o.shape == ForwardShape::kSpot) { /* vMF(c) = vMF(1) e^{kappa (c - 1)} */
        for (double cp : c.cos_psi) {
          sum += std::exp(x[0] * (cp - 1.0));
        }
        return sum * vmf_density(1.0, x[0]) * c.dO;
      }
      for (const auto &pr : c.pairs) {
        sum += arc_density(pr[0], pr[1], x[0], x[1]);
      }
      return sum * c.dO;
    };
    /* Least squares in w for given parameters: w = sum e t / sum t^2 per channel, and the residual falls by
     * (sum e t)^2 / sum t^2 (luminance), which the search maximises. */
    struct Fit {
      double et[3] = {0.0, 0.0, 0.0}, tt = 0.0, gain = -1.0;
    };
    auto fit = [&](const std::array<double, 2> &x) {
      Fit f;
      for (const Cell &c : cells) {
        const double t = lobe_in_cell(c, x);
        for (int ch = 0; ch < 3; ch++) {
          f.et[ch] += c.e[ch] * t;
        }
        f.tt += t * t;
      }
      const double eL = luminance(f.et);
      f.gain = eL > 0.0 && f.tt > 0.0 ? eL * eL / f.tt : -1.0;
      return f;
    };
    int best = -1;
    double best_gain = 0.0;
    for (size_t j = 0; j < grid.size(); j++) {
      const double g = fit(grid[j]).gain;
      if (g > best_gain) {
        best_gain = g;
        best = int(j);
      }
    }
    ForwardPeak &peak = table.peaks[size_t(k)];
    if (best < 0) {
      return;
    }
    std::array<double, 2> x = grid[size_t(best)];
    if (o.shape == ForwardShape::kSpot) {
      /* Golden-section search in log kappa between the grid's neighbours of the best. */
      double lo = std::log(grid[size_t(std::max(0, best - 1))][0]);
      double hi = std::log(grid[size_t(std::min(int(grid.size()) - 1, best + 1))][0]);
      auto gain = [&](double lk) { return fit({std::exp(lk), 0.0}).gain; };
      const double r = 0.5 * (std::sqrt(5.0) - 1.0);
      double x1 = hi - r * (hi - lo), x2 = lo + r * (hi - lo);
      double g1 = gain(x1), g2 = gain(x2);
      for (int it = 0; it < 16; it++) { /* the bracket shrinks to 0.62^16 = 5e-4 of its width */
        if (g1 >= g2) {
          hi = x2;
          x2 = x1;
          g2 = g1;
          x1 = hi - r * (hi - lo);
          g1 = gain(x1);
        }
        else {
          lo = x1;
          x1 = x2;
          g1 = g2;
          x2 = lo + r * (hi - lo);
          g2 = gain(x2);
        }
      }
      if (gain(0.5 * (lo + hi)) >= best_gain) {
        x[0] = std::exp(0.5 * (lo + hi));
      }
    }
    const Fit f = fit(x);
    if (o.shape == ForwardShape::kSpot) {
      peak.kappa = x[0];
    }
    else {
      peak.beta = x[0];
      peak.gamma = x[1];
    }
    for (int ch = 0; ch < 3; ch++) {
      /* One w for the window's bins, each of whose cells holds that bin's own excess. */
      peak.w[size_t(ch)] = std::max(0.0, f.et[ch] / f.tt);
    }
    double l1 = 0.0, l1_res = 0.0, l1_noise = 0.0;
    const double wL = luminance(peak.w.data());
    for (const Cell &c : cells) {
      const double eL = luminance(c.e);
      l1 += std::abs(eL);
      l1_res += std::abs(eL - wL * lobe_in_cell(c, x));
      l1_noise += c.noise;
    }
    peak.explained = l1 > 0.0 ? 1.0 - l1_res / l1 : 0.0;
    if (!(peak.explained > 0.0)) {
      peak = ForwardPeak{}; /* a lobe that explains nothing of the excess is noise */
    }
    peak.ceiling = maps_b && l1 > 0.0 ? 1.0 - l1_noise / l1 : -1.0;
  });
  return table;
}

}  // namespace neuralyarn::model
