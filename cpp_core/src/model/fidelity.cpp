// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/fidelity.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include <tbb/parallel_for.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

using nlohmann::json;

json FidelityReport::to_json() const
{
  return {{"albedo_mae", albedo_mae},
          {"albedo_mae_rel", albedo_mae_rel},
          {"albedo_max_rel", albedo_max_rel},
          {"T_rmse", T_rmse},
          {"R_energy_mae_rel", R_energy_mae_rel},
          {"M_energy_mae_rel", M_energy_mae_rel},
          {"rel_var_importance", rel_var_importance},
          {"rel_var_uniform", rel_var_uniform},
          {"rel_var_per_wi_kappa_R", rel_var_per_wi_kappa_R},
          {"albedo_rel_by_theta_i", albedo_rel_by_theta},
          {"M_energy_rel_by_theta_i", M_rel_by_theta},
          {"R_energy_rel_by_theta_i", R_rel_by_theta},
          {"lobes", lobes.to_json()}};
}

namespace {

/* Albedo, P(T) and the R and M energies of the model against the maps, per incident bin (the bin's centre),
 * weighted by the bins' solid angles; and their relative errors per theta_i. */
void check_energies(const ny::YarnBsdfParams &p, const rdm::RdmMaps &maps, FidelityReport &r)
{
  const rdm::MapResolution &b = maps.bins;
  const std::vector<double> ER = maps.energy(maps.r), EM = maps.energy(maps.m);
  struct Row {
    double w = 0, a_abs = 0, a_rel = 0, a_max = 0, t2 = 0, r_rel = 0, m_rel = 0;
  };
  std::vector<Row> rows(b.incident());
  tbb::parallel_for(0, int(b.incident()), [&](int k) {
    const int ti = k / b.phi_i, pi = k % b.phi_i;
    Row &row = rows[size_t(k)];
    if (maps.count[size_t(k)] == 0) {
      return;
    }
    row.w = maps.incident_solid_angle(ti);
    const ny::Vec3 wi = train::entry_vec3(rdm::bin_center(ti, 0.0, 0.5 * kPi, b.theta_i),
                                          rdm::bin_center(pi, -kPi, kPi, b.phi_i));
    const ny::YarnLobes l = ny::yarn_lobes(p, wi);
    const ny::Rgb e_m = m_lobe_energy(p, l);
    const ny::Rgb e_r = ny::yarn_energy_R(l);
    const double pt = l.P_T - maps.p_t[size_t(k)];
    row.t2 = pt * pt;
    for (int c = 0; c < 3; c++) {
      const double a_model = l.P_T + channel(e_r, c) + channel(e_m, c);
      const double a_map = maps.exit_energy[size_t(k) * 3 + size_t(c)];
      const double err = std::abs(a_model - a_map);
      row.a_abs += err / 3.0;
      const double rel = a_map > 1e-6 ? err / a_map : 0.0;
      row.a_rel += rel / 3.0;
      row.a_max = std::max(row.a_max, rel);
    }
    const double er_map = (ER[size_t(k) * 3] + ER[size_t(k) * 3 + 1] + ER[size_t(k) * 3 + 2]) / 3.0;
    const double em_map = (EM[size_t(k) * 3] + EM[size_t(k) * 3 + 1] + EM[size_t(k) * 3 + 2]) / 3.0;
    row.r_rel = er_map > 1e-6 ? std::abs(ny::average(e_r) - er_map) / er_map : 0.0;
    row.m_rel = em_map > 1e-6 ? std::abs(ny::average(e_m) - em_map) / em_map : 0.0;
  });
  r.albedo_rel_by_theta.assign(size_t(b.theta_i), 0.0);
  r.M_rel_by_theta.assign(size_t(b.theta_i), 0.0);
  r.R_rel_by_theta.assign(size_t(b.theta_i), 0.0);
  for (size_t k = 0; k < rows.size(); k++) {
    const size_t ti = k / size_t(b.phi_i);
    r.albedo_rel_by_theta[ti] += rows[k].a_rel / b.phi_i;
    r.M_rel_by_theta[ti] += rows[k].m_rel / b.phi_i;
    r.R_rel_by_theta[ti] += rows[k].r_rel / b.phi_i;
  }
  double wsum = 0;
  for (const Row &row : rows) {
    wsum += row.w;
    r.albedo_mae += row.w * row.a_abs;
    r.albedo_mae_rel += row.w * row.a_rel;
    r.albedo_max_rel = std::max(r.albedo_max_rel, row.a_max);
    r.T_rmse += row.w * row.t2;
    r.R_energy_mae_rel += row.w * row.r_rel;
    r.M_energy_mae_rel += row.w * row.m_rel;
  }
  r.albedo_mae /= wsum;
  r.albedo_mae_rel /= wsum;
  r.T_rmse = std::sqrt(r.T_rmse / wsum);
  r.R_energy_mae_rel /= wsum;
  r.M_energy_mae_rel /= wsum;

}

/* Sampling efficiency: relative variance of one-sample estimates of the albedo under uniform sampling, the
 * model's importance sampling, and importance sampling with the best kappa_R for each w_i. */
void check_sampling(const ny::YarnBsdfParams &p, const FidelityOptions &o, FidelityReport &r)
{
  std::vector<double> rv_imp(size_t(o.variance_directions)), rv_uni(rv_imp.size()), rv_opt(rv_imp.size());
  tbb::parallel_for(0, o.variance_directions, [&](int d) {
    std::mt19937_64 rng(o.seed * 7919u + uint64_t(d));
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    const double theta = std::acos(1.0 - U(rng)), phi = -kPi + 2 * kPi * U(rng);
    const ny::Vec3 wi = train::entry_vec3(theta, phi);
    const ny::YarnLobes l = ny::yarn_lobes(p, wi);
    ny::YarnBsdfParams q = p;
    const double er = ny::average(l.weight_R) * 0.5, em = ny::average(m_lobe_energy(p, l));
    q.kappa_R = float(er + em > 0 ? er / (er + em) : 0.5);
    auto stats = [&](const ny::YarnBsdfParams &pp, int mode) {
      double s = 0, s2 = 0;
      for (int i = 0; i < o.variance_samples; i++) {
        double x = 0;
        if (mode == 0) {
          ny::YarnSample ys;
          if (ny::yarn_sample(pp, wi, U(rng), U(rng), U(rng), false, &ys)) {
            x = ny::average(ys.weight);
          }
        }
        else {
          const ny::Vec3 wo = ny::sample_uniform_sphere(U(rng), U(rng));
          x = ny::average(ny::yarn_eval_lobes(pp, l, wo)) * 4.0 * kPi;
        }
        s += x;
        s2 += x * x;
      }
      const double mean = s / o.variance_samples;
      const double var = s2 / o.variance_samples - mean * mean;
      return mean > 0 ? var / (mean * mean) : 0.0;
    };
    rv_imp[size_t(d)] = stats(p, 0);
    rv_uni[size_t(d)] = stats(p, 1);
    rv_opt[size_t(d)] = stats(q, 0);
  });
  for (int d = 0; d < o.variance_directions; d++) {
    r.rel_var_importance += rv_imp[size_t(d)] / o.variance_directions;
    r.rel_var_uniform += rv_uni[size_t(d)] / o.variance_directions;
    r.rel_var_per_wi_kappa_R += rv_opt[size_t(d)] / o.variance_directions;
  }
}

}  // namespace

FidelityReport check_model(const YarnModel &model, const rdm::RdmMaps &maps_a, const FidelityOptions &o,
                           const rdm::RdmMaps *maps_b)
{
  const auto t0 = std::chrono::steady_clock::now();
  const rdm::RdmMaps mean = maps_b ? rdm::mean_of_maps(maps_a, *maps_b) : rdm::RdmMaps{};
  const rdm::RdmMaps &maps = maps_b ? mean : maps_a;
  const std::vector<float> flat = model.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  FidelityReport r;
  check_energies(p, maps, r);
  check_sampling(p, o, r);
  r.lobes = check_lobes(model, maps_a, maps_b);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace neuralyarn::model
