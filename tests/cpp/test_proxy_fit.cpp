// SPDX-License-Identifier: Apache-2.0
//
// The sampling-proxy fit recovers known parameters: maps filled with the proxy density itself (in the
// sampler's parameterisation) must give back the kappa_M, beta_M, gamma_M they were made from. A fit in
// another parameterisation (the authors' rotation by pi alpha, or an azimuth about phi_i) would not.
#include <gtest/gtest.h>

#include <cmath>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/proxy_fit.h"
#include "neuralyarn/train/dataset.h"
#include "neuralyarn/units.h"

using namespace neuralyarn;

TEST(ProxyFit, RecoversTheParametersOfItsOwnDensity)
{
  struct Truth {
    double kappa, beta, gamma;
  };
  for (const Truth t : {Truth{0.8, 0.35, 1.2}, Truth{0.5, 0.6, 0.5}}) {
    rdm::RdmMaps maps;
    maps.bins = {8, 24, 72, 96};
    maps.preset = find_preset("fleece");
    maps.count.assign(maps.bins.incident(), 100);
    maps.m.assign(maps.bins.incident() * maps.bins.outgoing() * 3, 0.0f);
    maps.r.assign(maps.m.size(), 0.0f);
    const ny::TwistRotation twist = ny::make_twist_rotation(float(maps.preset.alpha));
    const float kvm = float(1.0 / (t.gamma * t.gamma));
    for (int ti = 0; ti < maps.bins.theta_i; ti++) {
      for (int pi = 0; pi < maps.bins.phi_i; pi++) {
        const Eigen::Vector3f w = train::entry_direction(rdm::bin_center(ti, 0, kPi / 2, maps.bins.theta_i),
                                                         rdm::bin_center(pi, -kPi, kPi, maps.bins.phi_i));
        const ny::Vec3 wi_f = ny::yarn_to_surface_fiber(twist, ny::make_vec3(w.x(), w.y(), w.z()));
        const ny::TruncatedNormal tn =
            ny::make_truncated_normal(-ny::theta_of(wi_f), float(t.beta), -ny::kHalfPi, ny::kHalfPi);
        for (int to = 0; to < maps.bins.theta_o; to++) {
          for (int po = 0; po < maps.bins.phi_o; po++) {
            const Eigen::Vector3f v = train::entry_direction(rdm::bin_center(to, 0, kPi, maps.bins.theta_o),
                                                             rdm::bin_center(po, -kPi, kPi, maps.bins.phi_o));
            const ny::Vec3 wo_f = ny::yarn_to_surface_fiber(twist, ny::make_vec3(v.x(), v.y(), v.z()));
            const float pdf = ny::yarn_m_proxy_pdf(tn, kvm, float(t.kappa), wo_f);
            for (int c = 0; c < 3; c++) {
              maps.m[maps.map_index(ti, pi, to, po) + size_t(c)] = 0.3f * pdf; /* albedo 0.3 */
            }
          }
        }
      }
    }
    model::ProxyFitOptions o;
    o.samples = 60000;
    const model::ProxyFitResult r = model::fit_sampling_proxy(maps, o);
    /* Tolerances: 60k samples give standard errors of ~1 % on each parameter; the bin-centre maps
     * (2.5 x 3.75 degree bins, jittered) blur widths by a few percent. */
    EXPECT_NEAR(r.proxy.kappa_M, t.kappa, 0.04);
    EXPECT_NEAR(r.proxy.beta_M, t.beta, 0.06 * t.beta);
    EXPECT_NEAR(r.proxy.gamma_M, t.gamma, 0.06 * t.gamma);
    EXPECT_LT(r.nll, r.nll_uniform);
  }
}
