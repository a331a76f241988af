// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/train/dataset.h"

#include <cmath>
#include <limits>
#include <random>

#include "neuralyarn/kernel/fiber_bsdf.h"
#include "neuralyarn/kernel/frames.h"
#include "neuralyarn/presets.h" /* ParameterError */
#include "neuralyarn/units.h"

namespace neuralyarn::train {

namespace {

void check_count(int n)
{
  if (n < 1) {
    throw ParameterError("samples", "the number of training samples must be >= 1");
  }
}

/* Draws w_i uniformly on the hemisphere until it lands in a bin of the requested split that has paths. */
struct IncidentSampler {
  const rdm::RdmMaps &maps;
  bool validation;
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> U{0.0, 1.0};
  long tries = 0;

  void draw(double *theta, double *phi, int *ti, int *pi)
  {
    const rdm::MapResolution &b = maps.bins;
    for (;;) {
      if (++tries > 100000000L) {
        throw ParameterError("maps", "no incident bin with paths is available for this split");
      }
      *theta = std::acos(1.0 - U(rng)); /* cos(theta) uniform in (0, 1] */
      *phi = -kPi + 2.0 * kPi * U(rng);
      *ti = rdm::bin_of(*theta, 0.0, 0.5 * kPi, b.theta_i);
      *pi = rdm::bin_of(*phi, -kPi, kPi, b.phi_i);
      if (is_validation_bin(b, *ti, *pi) == validation && maps.count[maps.incident_index(*ti, *pi)] > 0) {
        return;
      }
    }
  }
};

/* Bilinear interpolation of a per-incident-bin table between bin centres. */
float interpolate_incident(const rdm::RdmMaps &maps, const std::vector<float> &table, int channels, int c,
                           double theta, double phi)
{
  const rdm::MapResolution &b = maps.bins;
  const rdm::BinTaps t = rdm::bin_taps(theta, 0.0, 0.5 * kPi, b.theta_i, false),
                     p = rdm::bin_taps(phi, -kPi, kPi, b.phi_i, true);
  auto at = [&](int i, int j) {
    return double(table[maps.incident_index(t.bin[i], p.bin[j]) * size_t(channels) + size_t(c)]);
  };
  return float(t.weight[0] * (p.weight[0] * at(0, 0) + p.weight[1] * at(0, 1)) +
               t.weight[1] * (p.weight[0] * at(1, 0) + p.weight[1] * at(1, 1)));
}
}  // namespace

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

ny::Vec3 entry_vec3(double theta, double phi)
{
  const Eigen::Vector3f v = entry_direction(theta, phi);
  return ny::make_vec3(v.x(), v.y(), v.z());
}

Dataset sample_incident_table(const rdm::RdmMaps &maps, const std::vector<float> &table, int channels, int n,
                              uint64_t seed, bool validation, bool interpolate)
{
  check_count(n);
  if (channels < 1 || table.size() != maps.bins.incident() * size_t(channels)) {
    throw ParameterError("table", "an incident table needs one entry per incident bin and channel");
  }
  IncidentSampler s{maps, validation, std::mt19937_64(seed)};
  Dataset d;
  d.X.resize(3, n);
  d.Y.resize(channels, n);
  for (int k = 0; k < n; k++) {
    double theta, phi;
    int ti, pi;
    s.draw(&theta, &phi, &ti, &pi);
    const Eigen::Vector3f w = entry_direction(theta, phi);
    d.X(0, k) = w.x();
    d.X(1, k) = w.y();
    d.X(2, k) = w.z();
    for (int c = 0; c < channels; c++) {
      d.Y(c, k) = interpolate ? interpolate_incident(maps, table, channels, c, theta, phi)
                              : table[maps.incident_index(ti, pi) * size_t(channels) + size_t(c)];
    }
  }
  return d;
}

Dataset sample_transmission(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation)
{
  return sample_incident_table(maps, maps.p_t, 1, n, seed, validation, true);
}

std::vector<float> reflection_scale_table(const rdm::RdmMaps &maps, int channels)
{
  if (channels != 1 && channels != 3) {
    throw ParameterError("r_widths", "the R network has one output (its colour the fiber's C_R) or three (RGB)");
  }
  const rdm::MapResolution &b = maps.bins;
  const std::vector<double> E = maps.energy(maps.r);
  const ny::TwistRotation twist = ny::make_twist_rotation(float(maps.surface_alpha()));
  const ny::FiberBsdfParams fiber = maps.preset.fiber_params();
  std::vector<float> rho(b.incident() * size_t(channels), 0.0f);
  for (int ti = 0; ti < b.theta_i; ti++) {
    for (int pi = 0; pi < b.phi_i; pi++) {
      const Eigen::Vector3f w = entry_direction(rdm::bin_center(ti, 0.0, 0.5 * kPi, b.theta_i),
                                                rdm::bin_center(pi, -kPi, kPi, b.phi_i));
      const ny::Vec3 wf = ny::yarn_to_surface_fiber(twist, ny::make_vec3(w.x(), w.y(), w.z()));
      const ny::Rgb F = ny::schlick_fresnel(fiber.C_R, ny::cos_theta(wf));
      const size_t i = maps.incident_index(ti, pi);
      const double *e = &E[i * 3];
      const double lobe = 0.5 * double(ny::average(F));
      if (!(lobe > 0.0)) {
        continue;
      }
      if (channels == 1) {
        rho[i] = float((e[0] + e[1] + e[2]) / 3.0 / lobe);
      }
      else {
        for (int c = 0; c < 3; c++) {
          rho[i * 3 + size_t(c)] = float(e[c] / lobe);
        }
      }
    }
  }
  return rho;
}

Dataset sample_reflection_scale(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation, int channels)
{
  return sample_incident_table(maps, reflection_scale_table(maps, channels), channels, n, seed, validation, true);
}

Dataset sample_multiple_scattering(const rdm::RdmMaps &maps, int n, uint64_t seed, bool validation, bool two_sided)
{
  check_count(n);
  const rdm::MapResolution &b = maps.bins;
  IncidentSampler s{maps, validation, std::mt19937_64(seed)};
  Dataset d;
  d.X.resize(6, n);
  d.Y.resize(two_sided ? 6 : 3, n);
  if (two_sided) {
    d.Y.setConstant(std::numeric_limits<float>::quiet_NaN());
  }
  for (int k = 0; k < n; k++) {
    double theta_i, phi_i;
    int ti, pi;
    s.draw(&theta_i, &phi_i, &ti, &pi);
    const double theta_o = std::acos(1.0 - 2.0 * s.U(s.rng)); /* uniform on the sphere */
    const double phi_o = -kPi + 2.0 * kPi * s.U(s.rng);
    const int to = rdm::bin_of(theta_o, 0.0, kPi, b.theta_o);
    const int po = rdm::bin_of(phi_o, -kPi, kPi, b.phi_o);
    const Eigen::Vector3f wi = entry_direction(theta_i, phi_i), wo = entry_direction(theta_o, phi_o);
    for (int c = 0; c < 3; c++) {
      d.X(c, k) = wi(c);
      d.X(3 + c, k) = wo(c);
    }
    const float *v = &maps.m[maps.map_index(ti, pi, to, po)];
    const int row = two_sided && wo.z() < 0.0f ? 3 : 0; /* the kernel's choice of outputs, yarn_eval_M */
    d.Y(row, k) = v[0];
    d.Y(row + 1, k) = v[1];
    d.Y(row + 2, k) = v[2];
  }
  return d;
}

}  // namespace neuralyarn::train
