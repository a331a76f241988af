// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/fallback.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/model/calibration.h"
#include "neuralyarn/model/cycles_lobes.h"
#include "neuralyarn/model/model.h"
#include "neuralyarn/model/nnls.h"
#include "neuralyarn/thread_limit.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

using nlohmann::json;

namespace {

/* Upper bound of a stored energy (the loader's check; physical albedos are <= 1, the networks may
 * overshoot a little). */
constexpr double kMaxEnergy = 1.5;

/* Share of the von Mises density (mean 0 on the normal, concentration kappa) with |phi| < pi/2, i.e. in
 * the upper hemisphere whatever theta (w.z = cos theta cos phi). Midpoint rule on 4096 cells: the density
 * is smooth and periodic, the rule converges geometrically. */
double von_mises_upper_share(float kappa)
{
  constexpr int n = 4096;
  double up = 0.0, all = 0.0;
  for (int k = 0; k < n; k++) {
    const double phi = -kPi + 2.0 * kPi * (k + 0.5) / n;
    const double v = ny::von_mises_pdf(float(phi), kappa);
    all += v;
    up += std::abs(phi) < 0.5 * kPi ? v : 0.0;
  }
  return all > 0.0 ? up / all : 0.5;
}

/* Upper bound of a stored lobe weight (the loader's check): a weight is at most the view's energy over a
 * lobe's albedo, and the lobes' albedos are above ~0.3. */
constexpr double kMaxWeight = 100.0;

/* The fitted weights of one view (FallbackTables::W's [lobe][rgb] block), wv in the yarn frame, E the
 * view's R + M energies (E_R + E_M_up + E_M_down). */
std::vector<float> fit_view_weights(const ny::YarnBsdfParams &p, const std::vector<FallbackLobe> &lobes,
                                    ny::Vec3 wv, const double E[3], const FallbackOptions &o)
{
  namespace cl = cycles_lobes;
  const int K = int(lobes.size());
  const ny::YarnLobes l = ny::yarn_lobes(p, wv);
  const ny::Vec3 vf = ny::yarn_to_surface_fiber(p.twist, wv); /* (w.t_f, w.(n x t_f), w.n) */
  const cl::Dir v{vf.x, vf.y, vf.z};
  std::vector<double> albedo(static_cast<size_t>(K));
  for (int k = 0; k < K; k++) {
    albedo[size_t(k)] = fallback_lobe_albedo(lobes[size_t(k)], v);
  }
  /* The normal equations per channel, lower triangle, row-major so that a row's entries are contiguous. */
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  std::vector<RowMajor> G(3, RowMajor::Zero(K, K));
  std::vector<Eigen::VectorXd> b(3, Eigen::VectorXd::Zero(K));
  double eps[3];
  for (int c = 0; c < 3; c++) {
    eps[c] = std::max(o.fit_rel_eps * E[c] / (4.0 * kPi), 1e-12);
  }
  std::vector<double> B(static_cast<size_t>(K) * kMLanes);
  const double dth = kPi / o.fit_theta, dph = 2.0 * kPi / o.fit_phi;
  std::vector<double> sin_ph(size_t(o.fit_phi)), cos_ph(size_t(o.fit_phi));
  for (int q = 0; q < o.fit_phi; q++) {
    const double ph = -kPi + (q + 0.5) * dph;
    sin_ph[size_t(q)] = std::sin(ph);
    cos_ph[size_t(q)] = std::cos(ph);
  }
  /* A row's lights kMLanes at a time: the M network runs on them together (yarn_eval_M_lanes). */
  float wx[kMLanes], wy[kMLanes], wz[kMLanes];
  ny::Rgb S_M[kMLanes];
  for (int a = 0; a < o.fit_theta; a++) {
    const double th = -0.5 * kPi + (a + 0.5) * dth;
    const double ct = std::cos(th), st = std::sin(th), dw = ct * dth * dph;
    for (int q0 = 0; q0 < o.fit_phi; q0 += kMLanes) {
      const int n = std::min(kMLanes, o.fit_phi - q0);
      cl::Dir w[kMLanes];
      for (int j = 0; j < n; j++) {
        const int q = q0 + j;
        w[j] = cl::Dir{st, ct * sin_ph[size_t(q)], ct * cos_ph[size_t(q)]}; /* the light, surface-fiber frame */
        const ny::Vec3 wo =
            ny::surface_fiber_to_yarn(p.twist, ny::make_vec3(float(w[j].x), float(w[j].y), float(w[j].z)));
        wx[j] = wo.x;
        wy[j] = wo.y;
        wz[j] = wo.z;
        for (int k = 0; k < K; k++) {
          B[size_t(j) * size_t(K) + size_t(k)] = fallback_lobe_eval(lobes[size_t(k)], v, w[j]);
        }
      }
      yarn_eval_M_lanes(p, l, n, wx, wy, wz, S_M);
      for (int j = 0; j < n; j++) {
        /* ny::yarn_eval_lobes: R + M, zero where w_i is below the surface. */
        const ny::Rgb S = l.valid ? ny::yarn_eval_R(p, l, ny::make_vec3(wx[j], wy[j], wz[j])) + S_M[j]
                                  : ny::make_rgb(0.0f);
        const double *Bj = &B[size_t(j) * size_t(K)];
        const double s[3] = {S.r, S.g, S.b};
        for (int c = 0; c < 3; c++) {
          const double wt = dw / ((s[c] + eps[c]) * (s[c] + eps[c]));
          for (int k = 0; k < K; k++) {
            const double wb = wt * Bj[k];
            b[size_t(c)][k] += wb * s[c];
            double *Gk = &G[size_t(c)](k, 0);
            for (int r = 0; r <= k; r++) {
              Gk[r] += wb * Bj[r];
            }
          }
        }
      }
    }
  }
  std::vector<float> out(size_t(K) * 3, 0.0f);
  Eigen::VectorXd A(K);
  for (int k = 0; k < K; k++) {
    A[k] = albedo[size_t(k)];
  }
  for (int c = 0; c < 3; c++) {
    if (!(E[c] > 0.0)) {
      continue;
    }
    Eigen::MatrixXd Gc = G[size_t(c)].selfadjointView<Eigen::Lower>();
    /* The energy constraint as a row weighing 10^4 times the whole fit. */
    const double lambda = 1e4 * Gc.trace() / std::max(A.squaredNorm(), 1e-300);
    Gc += lambda * A * A.transpose();
    const Eigen::VectorXd w = nnls_small(Gc, b[size_t(c)] + lambda * E[c] * A);
    for (int k = 0; k < K; k++) {
      out[size_t(k) * 3 + size_t(c)] = float(std::min(w[k], kMaxWeight));
    }
  }
  return out;
}

std::string num(double v)
{
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

/* A float as the shortest double that reads back as the same float (%.9g round-trips floats), so that
 * the file stays short and the round trip is exact. */
double short_double(float v) { return std::strtod(num(double(v)).c_str(), nullptr); }

json float_list(const std::vector<float> &v)
{
  json a = json::array();
  for (float x : v) {
    a.push_back(short_double(x));
  }
  return a;
}

std::vector<float> table_from(const json &j, const char *key, size_t size, double lo, double hi,
                              const std::string &where)
{
  if (!j.contains(key) || !j[key].is_array()) {
    throw ModelError(where + "missing array '" + key + "'");
  }
  const json &a = j[key];
  if (a.size() != size) {
    throw ModelError(where + "'" + key + "' has " + std::to_string(a.size()) + " values, expected " +
                     std::to_string(size) + " for its bins");
  }
  std::vector<float> v;
  v.reserve(size);
  for (size_t i = 0; i < size; i++) {
    if (!a[i].is_number()) {
      throw ModelError(where + "'" + key + "' entry " + std::to_string(i) +
                       " is not a number (NaN is written as null)");
    }
    const double x = a[i].get<double>();
    if (!std::isfinite(x) || !(x >= lo && x <= hi)) {
      throw ModelError(where + "'" + key + "' entry " + std::to_string(i) + " = " + num(x) + " is outside [" +
                       num(lo) + ", " + num(hi) + "]");
    }
    v.push_back(float(x));
  }
  return v;
}

double number_from(const json &j, const char *key, const std::string &where)
{
  if (!j.contains(key) || !j[key].is_number() || !std::isfinite(j[key].get<double>())) {
    throw ModelError(where + "missing or non-finite number '" + key + "'");
  }
  return j[key].get<double>();
}

void require_agrees(const char *key, double stored, double expected, const std::string &where)
{
  if (std::abs(stored - expected) > 1e-6 * std::max(1.0, std::abs(expected))) {
    throw ModelError(where + "'" + key + "' = " + num(stored) + " disagrees with the model (" + num(expected) +
                     "); re-run `neuralyarn fallback MODEL`");
  }
}

/* The scalars as compute_fallback() derives them from the model's kernel array. */
FallbackTables scalars_of(const std::vector<float> &flat)
{
  FallbackTables f;
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  f.beta_R_rad = double(p.fiber.beta_R);
  f.twist_tilt_rad = std::atan(kPi * double(flat[ny::kYarnFlatAlpha]));
  f.beta_M_rad = double(p.beta_M);
  f.gamma_M_rad = double(p.gamma_M);
  f.kappa_M = double(p.kappa_M);
  /* The proxy is kappa_M lobe + (1 - kappa_M) uniform sphere; the uniform part has half its mass up. */
  const double share = von_mises_upper_share(1.0f / (p.gamma_M * p.gamma_M));
  const double lobe_up = f.kappa_M * share, uniform_up = 0.5 * (1.0 - f.kappa_M);
  f.kappa_M_up = lobe_up + uniform_up > 0.0 ? lobe_up / (lobe_up + uniform_up) : 0.0;
  f.C_R = {double(p.fiber.C_R.r), double(p.fiber.C_R.g), double(p.fiber.C_R.b)};
  f.kernel_flat_hash = fnv1a64_hex(flat);
  return f;
}
}  // namespace

double fallback_lobe_eval(const FallbackLobe &L, const cycles_lobes::Dir &v, const cycles_lobes::Dir &o)
{
  if (L.closure == "ggx") {
    return cycles_lobes::ggx_eval(L.alpha_x, L.alpha_y, v, o);
  }
  return L.closure == "diffuse" ? cycles_lobes::diffuse_eval(o) : cycles_lobes::translucent_eval(o);
}

double fallback_lobe_albedo(const FallbackLobe &L, const cycles_lobes::Dir &v, int n)
{
  return L.closure == "ggx" ? cycles_lobes::ggx_albedo(L.alpha_x, L.alpha_y, v, n) : 1.0; /* diffuse, translucent: 1 */
}

std::vector<FallbackLobe> fallback_lobes(const FallbackTables &f)
{
  /* GGX slope half width at half maximum alpha sqrt(sqrt 2 - 1); theta_o moves twice the half vector. */
  const double per_beta = std::sqrt(2.0 * std::log(2.0)) / (2.0 * std::sqrt(std::sqrt(2.0) - 1.0));
  auto alpha = [](double a) { return std::min(std::max(a, kFallbackAlphaMin), 1.0); };
  /* The M ladder's base at least twice the floor, so that its lobes stay distinct under the floor. */
  const double aR = alpha(per_beta * f.beta_R_rad);
  const double aM = std::max(per_beta * f.beta_M_rad, 2.0 * kFallbackAlphaMin);
  return {{"ggx", aR, 1.0},
          {"ggx", alpha(0.5 * aM), 1.0},
          {"ggx", alpha(aM), 1.0},
          {"ggx", alpha(2.5 * aM), 1.0},
          {"diffuse", 0.0, 0.0},
          {"translucent", 0.0, 0.0}};
}

namespace {
/* The OSL template's ny_cell: angle x between the n cell centres -> lower cell, upper cell, upper weight. */
void cell_of(double x, int n, int *i0, int *i1, double *w)
{
  const double f = std::clamp((x + 0.5 * kPi) * n / kPi - 0.5, 0.0, n - 1.0);
  *i0 = std::min(int(std::floor(f)), n - 1);
  *i1 = std::min(*i0 + 1, n - 1);
  *w = f - *i0;
}

/* A yarn-frame direction in the surface fibers' frame (the kernel's rotation by the stored tilt). */
cycles_lobes::Dir to_surface_fiber(const FallbackTables &f, const cycles_lobes::Dir &w)
{
  const ny::TwistRotation r{float(std::cos(f.twist_tilt_rad)), float(std::sin(f.twist_tilt_rad))};
  const ny::Vec3 v = ny::yarn_to_surface_fiber(r, ny::make_vec3(float(w.x), float(w.y), float(w.z)));
  return {v.x, v.y, v.z};
}
}  // namespace

FallbackAt fallback_at(const FallbackTables &f, const cycles_lobes::Dir &view)
{
  const double theta = std::asin(std::clamp(view.x, -1.0, 1.0)), phi = std::atan2(view.y, view.z);
  int i0, i1, j0, j1;
  double a, b;
  cell_of(theta, f.theta_bins, &i0, &i1, &a);
  cell_of(phi, f.phi_bins, &j0, &j1, &b);
  const size_t cell[4] = {size_t(i0 * f.phi_bins + j0), size_t(i0 * f.phi_bins + j1), size_t(i1 * f.phi_bins + j0),
                          size_t(i1 * f.phi_bins + j1)};
  const double wgt[4] = {(1 - a) * (1 - b), (1 - a) * b, a * (1 - b), a * b};
  const size_t K = f.lobes.size();
  FallbackAt at;
  at.W.assign(K * 3, 0.0);
  for (int q = 0; q < 4; q++) {
    at.P_T += wgt[q] * f.P_T[cell[q]];
    for (size_t k = 0; k < K * 3; k++) {
      at.W[k] += wgt[q] * f.W[cell[q] * K * 3 + k];
    }
  }
  return at;
}

std::array<double, 3> fallback_eval(const FallbackTables &f, const cycles_lobes::Dir &view,
                                    const cycles_lobes::Dir &light)
{
  const FallbackAt at = fallback_at(f, view);
  const cycles_lobes::Dir v = to_surface_fiber(f, view), o = to_surface_fiber(f, light);
  std::array<double, 3> out{0.0, 0.0, 0.0};
  for (size_t k = 0; k < f.lobes.size(); k++) {
    const double e = fallback_lobe_eval(f.lobes[k], v, o);
    for (int c = 0; c < 3; c++) {
      out[size_t(c)] += at.W[k * 3 + size_t(c)] * e;
    }
  }
  return out;
}

std::array<double, 3> fallback_albedo(const FallbackTables &f, const cycles_lobes::Dir &view, int n)
{
  const FallbackAt at = fallback_at(f, view);
  const cycles_lobes::Dir v = to_surface_fiber(f, view);
  std::array<double, 3> out{at.P_T, at.P_T, at.P_T};
  for (size_t k = 0; k < f.lobes.size(); k++) {
    const double a = fallback_lobe_albedo(f.lobes[k], v, n);
    for (int c = 0; c < 3; c++) {
      out[size_t(c)] += at.W[k * 3 + size_t(c)] * a;
    }
  }
  return out;
}

double FallbackTables::theta_center(int i) const { return -0.5 * kPi + (i + 0.5) * kPi / theta_bins; }
double FallbackTables::phi_center(int j) const { return -0.5 * kPi + (j + 0.5) * kPi / phi_bins; }

std::string fnv1a64_hex(const std::vector<float> &values)
{
  uint64_t h = 0xcbf29ce484222325ull; /* FNV-1a 64 offset basis and prime */
  for (float v : values) {
    uint32_t bits;
    std::memcpy(&bits, &v, 4);
    for (int k = 0; k < 4; k++) { /* little-endian byte order, whatever the host's */
      h ^= uint64_t((bits >> (8 * k)) & 0xffu);
      h *= 0x100000001b3ull;
    }
  }
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", (unsigned long long)h);
  return buf;
}

FallbackTables compute_fallback(const YarnModel &model, const FallbackOptions &o)
{
  if (o.theta_bins < 1 || o.phi_bins < 1 || o.theta_bins > 1024 || o.phi_bins > 1024) {
    throw ModelError("fallback: bins must be in [1, 1024], got " + std::to_string(o.theta_bins) + " x " +
                     std::to_string(o.phi_bins));
  }
  if (o.fit_theta < 2 || o.fit_phi < 4 || !(o.fit_rel_eps > 0.0)) {
    throw ModelError("fallback: the weight fit needs at least 2 x 4 light directions and eps > 0");
  }
  if (o.quad_theta < 2 || o.quad_theta % 2 != 0 || o.quad_phi < 4) {
    throw ModelError("fallback: the M quadrature needs an even number of polar cells and at least 4 azimuths");
  }
  const std::vector<float> flat = model.kernel_flat();
  const ny::YarnBsdfParams p = ny::yarn_params_from_flat(flat.data());
  FallbackTables f = scalars_of(flat);
  f.theta_bins = o.theta_bins;
  f.phi_bins = o.phi_bins;
  const size_t n = f.cells();
  f.P_T.assign(n, 0.0f);
  f.E_R.assign(n * 3, 0.0f);
  f.E_M_up.assign(n * 3, 0.0f);
  f.E_M_down.assign(n * 3, 0.0f);
  f.lobes = fallback_lobes(f);
  const size_t K = f.lobes.size();
  f.W.assign(n * K * 3, 0.0f);
  const auto limit = thread_limit(o.threads);
  const ExitGrid grid(o.quad_theta, o.quad_phi);
  tbb::parallel_for(0, int(n), [&](int k) {
    const int i = k / f.phi_bins, j = k % f.phi_bins;
    const ny::Vec3 wi = ny::direction_from_angles(float(f.theta_center(i)), float(f.phi_center(j)));
    const ny::YarnLobes l = ny::yarn_lobes(p, wi);
    double up[3], down[3];
    m_lobe_energy_split(p, l, grid, true, up, down);
    f.P_T[size_t(k)] = l.P_T;
    const ny::Rgb er = ny::yarn_energy_R(l);
    const float ers[3] = {er.r, er.g, er.b};
    for (int c = 0; c < 3; c++) {
      f.E_R[size_t(k) * 3 + size_t(c)] = std::max(0.0f, ers[c]);
      f.E_M_up[size_t(k) * 3 + size_t(c)] = float(std::max(0.0, up[c]));
      f.E_M_down[size_t(k) * 3 + size_t(c)] = float(std::max(0.0, down[c]));
    }
    double E[3];
    for (int c = 0; c < 3; c++) {
      E[c] = double(f.E_R[size_t(k) * 3 + size_t(c)]) + f.E_M_up[size_t(k) * 3 + size_t(c)] +
             f.E_M_down[size_t(k) * 3 + size_t(c)];
    }
    const std::vector<float> w = fit_view_weights(p, f.lobes, wi, E, o);
    std::copy(w.begin(), w.end(), f.W.begin() + std::ptrdiff_t(size_t(k) * K * 3));
  });
  return f;
}

namespace {
json lobes_json(const std::vector<FallbackLobe> &lobes)
{
  json a = json::array();
  for (const FallbackLobe &L : lobes) {
    json o{{"closure", L.closure}};
    if (L.closure == "ggx") {
      o["alpha_x"] = L.alpha_x;
      o["alpha_y"] = L.alpha_y;
    }
    a.push_back(o);
  }
  return a;
}
}  // namespace

json fallback_to_json(const FallbackTables &f)
{
  return json{{"version", kFallbackVersion},
              {"theta_bins", f.theta_bins},
              {"phi_bins", f.phi_bins},
              {"theta_range_deg", {-90, 90}},
              {"phi_range_deg", {-90, 90}},
              {"layout", "values at cell centres, row-major [theta][phi] (P_T) and [theta][phi][rgb] (energies); "
                         "theta = asin(w.x), phi = atan2(w.y, w.z) of the view direction w in the yarn frame; "
                         "W: [theta][phi][lobe][rgb]"},
              {"P_T", float_list(f.P_T)},
              {"E_R", float_list(f.E_R)},
              {"E_M_up", float_list(f.E_M_up)},
              {"E_M_down", float_list(f.E_M_down)},
              {"lobes", lobes_json(f.lobes)},
              {"W", float_list(f.W)},
              {"beta_R_rad", f.beta_R_rad},
              {"twist_tilt_rad", f.twist_tilt_rad},
              {"beta_M_rad", f.beta_M_rad},
              {"gamma_M_rad", f.gamma_M_rad},
              {"kappa_M", f.kappa_M},
              {"kappa_M_up", f.kappa_M_up},
              {"C_R", f.C_R},
              {"kernel_flat_fnv1a64", f.kernel_flat_hash}};
}

FallbackTables fallback_from_json(const json &j, const YarnModel &model, const std::string &where_in,
                                  const std::string *written_flat_hash)
{
  const std::string where = where_in + "fallback: ";
  if (!j.is_object()) {
    throw ModelError(where + "must be an object");
  }
  if (!j.contains("version") || !j["version"].is_number_integer() || j["version"].get<int>() != kFallbackVersion) {
    throw ModelError(where + "version " + (j.contains("version") ? j["version"].dump() : "(missing)") +
                     " is not supported (this build reads version " + std::to_string(kFallbackVersion) +
                     "); re-run `neuralyarn fallback MODEL`");
  }
  FallbackTables f;
  for (const char *key : {"theta_bins", "phi_bins"}) {
    if (!j.contains(key) || !j[key].is_number_integer() || j[key].get<int>() < 1 || j[key].get<int>() > 1024) {
      throw ModelError(where + "'" + key + "' must be an integer in [1, 1024]");
    }
  }
  f.theta_bins = j["theta_bins"].get<int>();
  f.phi_bins = j["phi_bins"].get<int>();
  for (const char *key : {"theta_range_deg", "phi_range_deg"}) {
    if (j.contains(key) && j[key] != json{-90, 90}) {
      throw ModelError(where + "'" + key + "' must be [-90, 90] (the only range of version 1)");
    }
  }
  const size_t n = f.cells();
  f.P_T = table_from(j, "P_T", n, 0.0, 1.0, where);
  f.E_R = table_from(j, "E_R", n * 3, 0.0, kMaxEnergy, where);
  f.E_M_up = table_from(j, "E_M_up", n * 3, 0.0, kMaxEnergy, where);
  f.E_M_down = table_from(j, "E_M_down", n * 3, 0.0, kMaxEnergy, where);

  /* The scalars are copies of the model's; they and the hash must agree with it. */
  const std::vector<float> flat = model.kernel_flat();
  const FallbackTables expect = scalars_of(flat);
  f.beta_R_rad = number_from(j, "beta_R_rad", where);
  f.twist_tilt_rad = number_from(j, "twist_tilt_rad", where);
  f.beta_M_rad = number_from(j, "beta_M_rad", where);
  f.gamma_M_rad = number_from(j, "gamma_M_rad", where);
  f.kappa_M = number_from(j, "kappa_M", where);
  f.kappa_M_up = number_from(j, "kappa_M_up", where);
  require_agrees("beta_R_rad", f.beta_R_rad, expect.beta_R_rad, where);
  require_agrees("twist_tilt_rad", f.twist_tilt_rad, expect.twist_tilt_rad, where);
  require_agrees("beta_M_rad", f.beta_M_rad, expect.beta_M_rad, where);
  require_agrees("gamma_M_rad", f.gamma_M_rad, expect.gamma_M_rad, where);
  require_agrees("kappa_M", f.kappa_M, expect.kappa_M, where);
  require_agrees("kappa_M_up", f.kappa_M_up, expect.kappa_M_up, where);
  if (!j.contains("C_R") || !j["C_R"].is_array() || j["C_R"].size() != 3) {
    throw ModelError(where + "'C_R' must be three numbers");
  }
  for (size_t c = 0; c < 3; c++) {
    if (!j["C_R"][c].is_number()) {
      throw ModelError(where + "'C_R' must be three numbers");
    }
    f.C_R[c] = j["C_R"][c].get<double>();
    require_agrees("C_R", f.C_R[c], expect.C_R[c], where);
  }
  if (!j.contains("kernel_flat_fnv1a64") || !j["kernel_flat_fnv1a64"].is_string()) {
    throw ModelError(where + "missing string 'kernel_flat_fnv1a64'");
  }
  /* The lobes follow from the scalars; the weights refer to them. */
  f.lobes = fallback_lobes(f);
  if (!j.contains("lobes") || j["lobes"] != lobes_json(f.lobes)) {
    throw ModelError(where + "'lobes' must be " + lobes_json(f.lobes).dump() + " (from the model's widths); re-run " +
                     "`neuralyarn fallback MODEL`");
  }
  f.W = table_from(j, "W", n * f.lobes.size() * 3, 0.0, kMaxWeight, where);
  f.kernel_flat_hash = j["kernel_flat_fnv1a64"].get<std::string>();
  const std::string &hash = written_flat_hash ? *written_flat_hash : expect.kernel_flat_hash;
  if (f.kernel_flat_hash != hash) {
    throw ModelError(where + "the tables were computed for another model ('kernel_flat_fnv1a64' " + f.kernel_flat_hash +
                     ", the model's is " + hash +
                     "): the model changed after they were made; re-run `neuralyarn fallback MODEL`");
  }
  f.kernel_flat_hash = expect.kernel_flat_hash; /* the same model, its array in this layout */
  return f;
}

}  // namespace neuralyarn::model
