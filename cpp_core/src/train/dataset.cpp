// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/train/dataset.h"

#include <cmath>
#include <random>

#include "neuralyarn/presets.h" /* ParameterError */

namespace neuralyarn::train {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

bool is_validation_bin(const rdm::MapResolution &bins, int theta_i, int phi_i)
{
  /* A multiplicative hash of the bin index: spread over the hemisphere, the same every run. */
  const uint32_t k = uint32_t(theta_i * bins.phi_i + phi_i) * 2654435761u;
  return (k >> 16) % 10 == 0;
}

Eigen::Vector3f entry_direction(double theta, double phi)
{
  return Eigen::Vector3f(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)),
                         float(std::cos(theta)));
}

Dataset sample_transmission(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation)
{
  if (n < 1) {
    throw ParameterError("samples", "the number of training samples must be >= 1");
  }
  const rdm::MapResolution &b = maps.bins;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Dataset d;
  d.X.resize(3, n);
  d.Y.resize(1, n);
  int k = 0;
  for (int tries = 0; k < n; tries++) {
    if (tries > 1000 * n) {
      throw ParameterError("maps", "no incident bin is available for this split");
    }
    /* Uniform on the hemisphere: cos(theta) uniform in [0, 1]. */
    const double theta = std::acos(U(rng));
    const double phi = -kPi + 2.0 * kPi * U(rng);
    const int ti = rdm::bin_of(theta, 0.0, 0.5 * kPi, b.theta_i);
    const int pi = rdm::bin_of(phi, -kPi, kPi, b.phi_i);
    if (is_validation_bin(b, ti, pi) != validation || maps.count[maps.incident_index(ti, pi)] == 0) {
      continue;
    }
    const Eigen::Vector3f w = entry_direction(theta, phi);
    d.X(0, k) = w.x();
    d.X(1, k) = w.y();
    d.X(2, k) = w.z();
    d.Y(0, k) = maps.p_t[maps.incident_index(ti, pi)];
    k++;
  }
  return d;
}

}  // namespace neuralyarn::train
