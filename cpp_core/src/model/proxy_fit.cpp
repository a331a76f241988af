// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/proxy_fit.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <random>

#include <tbb/parallel_for.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

namespace {

/* Uniform in solid angle within a (theta, phi) bin. */
ny::Vec3 jitter(double t_lo, double t_hi, double p_lo, double p_hi, double u1, double u2)
{
  const double c = std::cos(t_lo) + u1 * (std::cos(t_hi) - std::cos(t_lo));
  const double s = std::sqrt(std::max(0.0, 1.0 - c * c));
  const double phi = p_lo + u2 * (p_hi - p_lo);
  return ny::make_vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(c));
}

double logistic(double x) { return 1.0 / (1.0 + std::exp(-x)); }

/* Nelder-Mead (Lagarias et al. 1998 coefficients) on R^3. */
template<class F> std::array<double, 3> nelder_mead(F f, std::array<double, 3> x0, double step, int max_eval, int *evals,
                                                    double *fbest)
{
  using P = std::array<double, 3>;
  std::array<P, 4> x;
  std::array<double, 4> fx;
  for (int i = 0; i < 4; i++) {
    x[size_t(i)] = x0;
    if (i > 0) {
      x[size_t(i)][size_t(i - 1)] += step;
    }
    fx[size_t(i)] = f(x[size_t(i)]);
  }
  int n = 4;
  while (n < max_eval) {
    std::array<int, 4> idx = {0, 1, 2, 3};
    std::sort(idx.begin(), idx.end(), [&](int a, int b) { return fx[size_t(a)] < fx[size_t(b)]; });
    std::array<P, 4> xs;
    std::array<double, 4> fs;
    for (int i = 0; i < 4; i++) {
      xs[size_t(i)] = x[size_t(idx[size_t(i)])];
      fs[size_t(i)] = fx[size_t(idx[size_t(i)])];
    }
    x = xs;
    fx = fs;
    if (std::abs(fx[3] - fx[0]) < 1e-7 * (1.0 + std::abs(fx[0]))) {
      break;
    }
    P c{0, 0, 0};
    for (int i = 0; i < 3; i++) {
      for (int k = 0; k < 3; k++) {
        c[size_t(k)] += x[size_t(i)][size_t(k)] / 3.0;
      }
    }
    auto along = [&](double t) {
      P p;
      for (int k = 0; k < 3; k++) {
        p[size_t(k)] = c[size_t(k)] + t * (x[3][size_t(k)] - c[size_t(k)]);
      }
      return p;
    };
    const P xr = along(-1.0);
    const double fr = f(xr);
    n++;
    if (fr < fx[0]) {
      const P xe = along(-2.0);
      const double fe = f(xe);
      n++;
      if (fe < fr) {
        x[3] = xe, fx[3] = fe;
      }
      else {
        x[3] = xr, fx[3] = fr;
      }
      continue;
    }
    if (fr < fx[2]) {
      x[3] = xr, fx[3] = fr;
      continue;
    }
    const bool outside = fr < fx[3];
    const P xc = along(outside ? -0.5 : 0.5);
    const double fc = f(xc);
    n++;
    if (fc < (outside ? fr : fx[3])) {
      x[3] = xc, fx[3] = fc;
      continue;
    }
    for (int i = 1; i < 4; i++) {
      for (int k = 0; k < 3; k++) {
        x[size_t(i)][size_t(k)] = x[0][size_t(k)] + 0.5 * (x[size_t(i)][size_t(k)] - x[0][size_t(k)]);
      }
      fx[size_t(i)] = f(x[size_t(i)]);
      n++;
    }
  }
  const int best = int(std::min_element(fx.begin(), fx.end()) - fx.begin());
  *evals += n;
  *fbest = fx[size_t(best)];
  return x[size_t(best)];
}

/* Parameter vector <-> proxy: widths kept within [0.2 deg, 170 deg] by construction. */
constexpr double kMinWidth = 0.2 * kDeg, kMaxWidth = 170.0 * kDeg;
double width_of(double x) { return kMinWidth + (kMaxWidth - kMinWidth) * logistic(x); }
double width_param(double w) { const double t = (w - kMinWidth) / (kMaxWidth - kMinWidth); return std::log(t / (1.0 - t)); }

}  // namespace

DirectionPairs sample_map_exits(const rdm::RdmMaps &maps, const std::vector<float> &map, int n, uint64_t seed)
{
  const rdm::MapResolution &b = maps.bins;
  const size_t bins = b.incident() * b.outgoing();
  std::vector<double> cdf(bins);
  double total = 0.0;
  for (int ti = 0; ti < b.theta_i; ti++) {
    const double dwi = maps.incident_solid_angle(ti);
    for (int pi = 0; pi < b.phi_i; pi++) {
      for (int to = 0; to < b.theta_o; to++) {
        const double dwo = maps.outgoing_solid_angle(to);
        for (int po = 0; po < b.phi_o; po++) {
          const size_t k = maps.map_index(ti, pi, to, po);
          total += double(map[k] + map[k + 1] + map[k + 2]) * dwo * dwi;
          cdf[k / 3] = total;
        }
      }
    }
  }
  DirectionPairs out;
  if (!(total > 0.0) || n < 1) {
    return out;
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const double dti = 0.5 * kPi / b.theta_i, dto = kPi / b.theta_o;
  const double dpi = 2.0 * kPi / b.phi_i, dpo = 2.0 * kPi / b.phi_o;
  for (int s = 0; s < n; s++) {
    const double u = U(rng) * total;
    const size_t k = size_t(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin());
    const size_t kk = std::min(k, bins - 1);
    const int po = int(kk % size_t(b.phi_o));
    const int to = int((kk / size_t(b.phi_o)) % size_t(b.theta_o));
    const int pi = int((kk / b.outgoing()) % size_t(b.phi_i));
    const int ti = int(kk / b.outgoing() / size_t(b.phi_i));
    out.wi.push_back(jitter(ti * dti, (ti + 1) * dti, -kPi + pi * dpi, -kPi + (pi + 1) * dpi, U(rng), U(rng)));
    out.wo.push_back(jitter(to * dto, (to + 1) * dto, -kPi + po * dpo, -kPi + (po + 1) * dpo, U(rng), U(rng)));
  }
  return out;
}

double m_proxy_nll(const DirectionPairs &pairs, double alpha, double beta_M, double gamma_M, double kappa_M)
{
  const ny::TwistRotation twist = ny::make_twist_rotation(float(alpha));
  const float kappa_vm = float(1.0 / (gamma_M * gamma_M));
  const size_t n = pairs.wi.size();
  /* Fixed-size blocks reduced in order: the same sum at any thread count. */
  constexpr size_t kBlock = 4096;
  const size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<double> sums(blocks, 0.0);
  tbb::parallel_for(size_t(0), blocks, [&](size_t blk) {
    double s = 0.0;
    for (size_t i = blk * kBlock; i < std::min(n, (blk + 1) * kBlock); i++) {
      const ny::Vec3 wi_f = ny::yarn_to_surface_fiber(twist, pairs.wi[i]);
      const ny::Vec3 wo_f = ny::yarn_to_surface_fiber(twist, pairs.wo[i]);
      const ny::TruncatedNormal tn =
          ny::make_truncated_normal(-ny::theta_of(wi_f), float(beta_M), -ny::kHalfPi, ny::kHalfPi);
      const float pdf = ny::yarn_m_proxy_pdf(tn, kappa_vm, float(kappa_M), wo_f);
      s -= std::log(std::max(double(pdf), 1e-30));
    }
    sums[blk] = s;
  });
  double total = 0.0;
  for (double s : sums) {
    total += s;
  }
  return n ? total / double(n) : 0.0;
}

double global_kappa_R(const rdm::RdmMaps &maps)
{
  const std::vector<double> ER = maps.energy(maps.r), EM = maps.energy(maps.m);
  double r = 0.0, m = 0.0;
  for (int ti = 0; ti < maps.bins.theta_i; ti++) {
    const double w = maps.incident_solid_angle(ti);
    for (int pi = 0; pi < maps.bins.phi_i; pi++) {
      const size_t k = maps.incident_index(ti, pi) * 3;
      r += w * (ER[k] + ER[k + 1] + ER[k + 2]);
      m += w * (EM[k] + EM[k + 1] + EM[k + 2]);
    }
  }
  return r + m > 0.0 ? r / (r + m) : 0.5;
}

ProxyFitResult fit_sampling_proxy(const rdm::RdmMaps &maps, const ProxyFitOptions &o)
{
  const auto t0 = std::chrono::steady_clock::now();
  ProxyFitResult r;
  r.proxy.kappa_R = global_kappa_R(maps);
  const DirectionPairs pairs = sample_map_exits(maps, maps.m, o.samples, o.seed);
  r.nll_uniform = std::log(4.0 * kPi);
  if (pairs.wi.empty()) {
    /* No multiple scattering at all: any proxy will do; keep the defaults, all uniform. */
    r.proxy.kappa_M = 0.0;
    r.nll = r.nll_uniform;
    return r;
  }
  const double alpha = maps.surface_alpha();
  auto f = [&](const std::array<double, 3> &x) {
    return m_proxy_nll(pairs, alpha, width_of(x[1]), width_of(x[2]), logistic(x[0]));
  };
  /* Two starts (narrow and wide lobes), each restarted once from its optimum; keep the best. */
  double best = 1e300;
  std::array<double, 3> xbest{};
  for (const auto &start : {std::array<double, 3>{0.0, width_param(0.3), width_param(0.6)},
                            std::array<double, 3>{1.0, width_param(0.8), width_param(1.5)}}) {
    double fb;
    std::array<double, 3> x = nelder_mead(f, start, 1.0, o.max_evaluations / 4, &r.evaluations, &fb);
    x = nelder_mead(f, x, 0.3, o.max_evaluations / 4, &r.evaluations, &fb);
    if (fb < best) {
      best = fb;
      xbest = x;
    }
  }
  r.proxy.kappa_M = logistic(xbest[0]);
  r.proxy.beta_M = width_of(xbest[1]);
  r.proxy.gamma_M = width_of(xbest[2]);
  r.nll = best;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace neuralyarn::model
