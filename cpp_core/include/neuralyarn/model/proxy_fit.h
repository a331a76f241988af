// SPDX-License-Identifier: Apache-2.0
//
// Fitting the importance-sampling proxy of kernel/yarn_bsdf.h to the gathered maps (issue 4, item 2).
//
// kappa_M, beta_M and gamma_M maximise the likelihood of the M exits under the proxy density
// yarn_m_proxy_pdf() — the very function the sampler draws from, in the surface-fiber frame (fixes the
// authors' fit in a different parameterisation, official_impl.md B12). The exits are drawn from the M map
// in proportion to their energy (w_i uniform on the hemisphere, each direction jittered uniformly in solid
// angle within its bin), which is maximum likelihood on energy-weighted exit directions. The optimiser
// is Nelder-Mead on (logit kappa_M, log beta_M, log gamma_M): three parameters, a smooth objective, no
// derivatives needed.
//
// kappa_R = E_R / (E_R + E_M), the R share of the scattered (non-T) energy averaged over w_i on the
// hemisphere (the authors' version puts T in the denominator and weighs bins, not solid angle, B13).
#pragma once

#include <cstdint>
#include <vector>

#include "neuralyarn/kernel/platform.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::model {

/* Direction pairs (yarn frame) drawn from a map in proportion to its energy (channel mean). */
struct DirectionPairs {
  std::vector<ny::Vec3> wi, wo;
};
DirectionPairs sample_map_exits(const rdm::RdmMaps &maps, const std::vector<float> &map, int n, uint64_t seed);

struct ProxyFitOptions {
  int samples = 100000;
  uint64_t seed = 11;
  int max_evaluations = 600;
};

struct ProxyFitResult {
  SamplingProxy proxy;  /* kappa_R, beta_M, gamma_M, kappa_M */
  double nll = 0.0;     /* mean negative log-likelihood of the M exits under the fitted proxy */
  double nll_uniform = 0.0; /* ... under the uniform sphere (log 4 pi): the fit must beat it */
  int evaluations = 0;
  double seconds = 0.0;
};

/* Mean negative log-likelihood of the pairs under the M proxy with these parameters. */
double m_proxy_nll(const DirectionPairs &pairs, double alpha, double beta_M, double gamma_M, double kappa_M);

/* E_R / (E_R + E_M) over w_i uniform on the hemisphere. */
double global_kappa_R(const rdm::RdmMaps &maps);

ProxyFitResult fit_sampling_proxy(const rdm::RdmMaps &maps, const ProxyFitOptions &options);

}  // namespace neuralyarn::model
