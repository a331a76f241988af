// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/surface_fit.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

#include "neuralyarn/io.h"
#include "neuralyarn/model/fallback.h"
#include "neuralyarn/model/nnls.h"
#include "neuralyarn/units.h"

namespace neuralyarn::model {

using nlohmann::json;
namespace cl = cycles_lobes;

namespace {

/* Largest stored weight (the loader's check): a weight is at most the view's energy over a lobe's albedo. */
constexpr double kMaxWeight = 100.0;
constexpr int kMaxLobes = 8;

cl::Dir from_angles(double cos_t, double phi, double sign)
{
  const double s = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
  return {s * std::cos(phi), s * std::sin(phi), sign * cos_t};
}

/* The lobes' mean over each light bin (rows: hemisphere, theta, phi as in the maps) and over the view bin's
 * cosines: the same for both faces. */
Eigen::MatrixXd lobe_matrix(const rdm::SurfaceMaps &m, const std::vector<SurfaceLobe> &lobes, int view, int S)
{
  const int K = int(lobes.size());
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(2 * m.light_theta * m.light_phi, K);
  for (int sv = 0; sv < S; sv++) {
    const double cv = (view + (sv + 0.5) / S) / m.view_bins;
    const cl::Dir v = from_angles(cv, 0.0, 1.0);
    int b = 0;
    for (int h = 0; h < 2; h++) {
      for (int t = 0; t < m.light_theta; t++) {
        for (int p = 0; p < m.light_phi; p++, b++) {
          for (int a = 0; a < S; a++) {
            for (int c = 0; c < S; c++) {
              const double ct = (t + (a + 0.5) / S) / m.light_theta;
              const double ph = 2.0 * kPi * (p + (c + 0.5) / S) / m.light_phi;
              const cl::Dir l = from_angles(ct, ph, h == 0 ? 1.0 : -1.0);
              for (int k = 0; k < K; k++) {
                L(b, k) += surface_lobe_eval(lobes[size_t(k)], v, l);
              }
            }
          }
        }
      }
    }
  }
  return L / (double(S) * S * S);
}

/* One view's weights [lobe][rgb] and fit error, given the lobes' bin means L (lobe_matrix). */
void fit_view(const rdm::SurfaceMaps &m, const Eigen::MatrixXd &L, int side, int view, const SurfaceFitOptions &o,
              float *W, float *error)
{
  const int K = int(L.cols()), n_bins = int(L.rows());
  const double omega = m.bin_solid_angle();
  /* The lobes' albedos per hemisphere (0: the viewer's, 1: through the cloth), binned as the data. */
  const int half = m.light_theta * m.light_phi;
  const Eigen::VectorXd A0 = L.topRows(half).colwise().sum().transpose() * omega;
  const Eigen::VectorXd A1 = L.bottomRows(half).colwise().sum().transpose() * omega;
  const size_t base = m.index(side, view, 0, 0, 0);
  double err_num = 0.0, err_den = 0.0;
  for (int c = 0; c < 3; c++) {
    double E[2] = {0.0, 0.0}; /* the data's energy per hemisphere */
    for (int b = 0; b < n_bins; b++) {
      E[b < half ? 0 : 1] += m.D[base + size_t(b) * 3 + size_t(c)] * omega;
    }
    for (int k = 0; k < K; k++) {
      W[k * 3 + c] = 0.0f;
    }
    if (!(E[0] + E[1] > 0.0)) {
      continue;
    }
    const double eps = o.rel_eps * (E[0] + E[1]) / (4.0 * kPi);
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(K, K);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(K);
    for (int b = 0; b < n_bins; b++) {
      const double d = m.D[base + size_t(b) * 3 + size_t(c)];
      const double wt = omega / ((std::max(d, 0.0) + eps) * (std::max(d, 0.0) + eps));
      G += wt * L.row(b).transpose() * L.row(b);
      rhs += wt * d * L.row(b).transpose();
    }
    /* The energy of each hemisphere as a row weighing 10^4 times the whole fit: reflection and transmission
     * each keep theirs (one constraint on the sum let the relative fit move energy between them). */
    const double lambda = 1e4 * G.trace() / std::max(A0.squaredNorm() + A1.squaredNorm(), 1e-300);
    const Eigen::VectorXd w = nnls_small(G + lambda * (A0 * A0.transpose() + A1 * A1.transpose()),
                                         rhs + lambda * (E[0] * A0 + E[1] * A1));
    for (int k = 0; k < K; k++) {
      W[k * 3 + c] = float(std::min(w[k], kMaxWeight));
    }
    const Eigen::VectorXd fit = L * w;
    for (int b = 0; b < n_bins; b++) {
      const double d = m.D[base + size_t(b) * 3 + size_t(c)];
      err_num += std::abs(fit[b] - d) * omega;
      err_den += std::abs(d) * omega;
    }
  }
  *error = float(err_den > 0.0 ? err_num / err_den : 0.0);
}

std::vector<float> floats(const json &j, const std::string &key, size_t n, double lo, double hi, const std::string &where)
{
  if (!j.contains(key) || !j[key].is_array() || j[key].size() != n) {
    throw std::runtime_error(where + ": '" + key + "' must be a list of " + std::to_string(n) + " numbers");
  }
  std::vector<float> out;
  out.reserve(n);
  for (const json &v : j[key]) {
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo || v.get<double>() > hi) {
      throw std::runtime_error(where + ": '" + key + "' must hold finite numbers in [" + std::to_string(lo) + ", " +
                               std::to_string(hi) + "]");
    }
    out.push_back(v.get<float>());
  }
  return out;
}

}  // namespace

double surface_lobe_eval(const SurfaceLobe &lobe, const cl::Dir &v, const cl::Dir &l)
{
  return fallback_lobe_eval({lobe.closure, lobe.alpha, lobe.alpha}, v, l); /* the one dispatch over the closures */
}

SurfaceBsdf fit_surface(const rdm::SurfaceMaps &m, const SurfaceFitOptions &o)
{
  if (o.subsamples < 1 || !(o.rel_eps > 0.0) || o.ggx_alphas.size() + 2 > size_t(kMaxLobes)) {
    throw std::invalid_argument("fit_surface: bad options");
  }
  SurfaceBsdf s;
  s.view_bins = m.view_bins;
  s.lobes = {{"diffuse", 0.0}, {"translucent", 0.0}};
  for (const double a : o.ggx_alphas) {
    if (!(a >= 0.001 && a <= 1.0)) {
      throw std::invalid_argument("fit_surface: GGX alpha must be in [0.001, 1]");
    }
    s.lobes.push_back({"ggx", a});
  }
  const size_t cells = 2 * size_t(m.view_bins), K = s.lobes.size();
  s.transparent.assign(m.tau.begin(), m.tau.end());
  s.albedo.assign(m.scattered.begin(), m.scattered.end());
  s.W.assign(cells * K * 3, 0.0f);
  s.fit_error.assign(cells, 0.0f);
  for (int view = 0; view < m.view_bins; view++) {
    const Eigen::MatrixXd L = lobe_matrix(m, s.lobes, view, o.subsamples);
    for (int side = 0; side < 2; side++) {
      const size_t cell = size_t(side * m.view_bins + view);
      fit_view(m, L, side, view, o, &s.W[cell * K * 3], &s.fit_error[cell]);
    }
  }
  return s;
}

SurfaceAt surface_at(const SurfaceBsdf &s, int side, double cos_v)
{
  /* Linear between the bins' centres and beyond the end centres (the straight-through share rises steeply
   * toward the normal: clamping it at the last centre lost 5 % of a white background seen through a knit),
   * then clamped to the stored ranges. */
  const int V = s.view_bins, K = int(s.lobes.size());
  const double x = cos_v * V - 0.5;
  const int i0 = V == 1 ? 0 : std::clamp(int(std::floor(x)), 0, V - 2), i1 = V == 1 ? 0 : i0 + 1;
  const double f = V == 1 ? 0.0 : std::clamp(x - i0, -0.5, 1.5);
  SurfaceAt at;
  const size_t c0 = size_t(side) * size_t(V) + size_t(i0), c1 = size_t(side) * size_t(V) + size_t(i1);
  at.transparent = std::clamp((1.0 - f) * s.transparent[c0] + f * s.transparent[c1], 0.0, 1.0);
  at.W.resize(size_t(K));
  for (int k = 0; k < K; k++) {
    for (int c = 0; c < 3; c++) {
      at.W[size_t(k)][size_t(c)] = std::max(0.0, (1.0 - f) * s.W[(c0 * size_t(K) + size_t(k)) * 3 + size_t(c)] +
                                                     f * s.W[(c1 * size_t(K) + size_t(k)) * 3 + size_t(c)]);
    }
  }
  return at;
}

std::vector<std::array<double, 3>> surface_curve(const SurfaceBsdf &s, int k, int samples)
{
  std::vector<std::array<double, 3>> out(static_cast<size_t>(samples));
  const auto value = [&](int side, double cos_v) -> std::array<double, 3> {
    const SurfaceAt at = surface_at(s, side, cos_v);
    return k < 0 ? std::array<double, 3>{at.transparent, at.transparent, at.transparent} : at.W[size_t(k)];
  };
  for (int i = 0; i < samples; i++) {
    const double x = samples > 1 ? double(i) / (samples - 1) : 0.0;
    if (x <= kSurfaceFront) {
      out[size_t(i)] = value(0, x / kSurfaceFront);
    }
    else if (x >= kSurfaceBackStart) {
      out[size_t(i)] = value(1, std::min(1.0, (x - kSurfaceBackStart) / kSurfaceFront));
    }
    else { /* between the faces: never looked up but by interpolation */
      const auto a = value(0, 1.0), b = value(1, 0.0);
      const double f = (x - kSurfaceFront) / (kSurfaceBackStart - kSurfaceFront);
      for (int c = 0; c < 3; c++) {
        out[size_t(i)][size_t(c)] = (1.0 - f) * a[size_t(c)] + f * b[size_t(c)];
      }
    }
  }
  return out;
}

json surface_to_json(const SurfaceBsdf &s)
{
  json lobes = json::array();
  for (const SurfaceLobe &l : s.lobes) {
    json j = {{"closure", l.closure}};
    if (l.closure == "ggx") {
      j["alpha"] = l.alpha;
    }
    lobes.push_back(j);
  }
  return {{"format", kSurfaceFormat}, {"view_bins", s.view_bins}, {"lobes", lobes},
          {"transparent", s.transparent}, {"W", s.W}, {"albedo", s.albedo}, {"fit_error", s.fit_error},
          {"source", s.source}};
}

SurfaceBsdf surface_from_json(const json &j, const std::string &where)
{
  if (!j.is_object() || j.value("format", "") != kSurfaceFormat) {
    throw std::runtime_error(where + ": not a surface BSDF (\"format\": \"" + kSurfaceFormat + "\")");
  }
  SurfaceBsdf s;
  if (!j.contains("view_bins") || !j["view_bins"].is_number_integer() || j["view_bins"].get<int>() < 1 ||
      j["view_bins"].get<int>() > 256) {
    throw std::runtime_error(where + ": 'view_bins' must be an integer in [1, 256]");
  }
  s.view_bins = j["view_bins"].get<int>();
  if (!j.contains("lobes") || !j["lobes"].is_array() || j["lobes"].empty() || j["lobes"].size() > size_t(kMaxLobes)) {
    throw std::runtime_error(where + ": 'lobes' must be a list of 1 to " + std::to_string(kMaxLobes) + " lobes");
  }
  for (const json &l : j["lobes"]) {
    const std::string c = l.is_object() ? l.value("closure", "") : "";
    SurfaceLobe lobe{c, 0.0};
    if (c == "ggx") {
      if (!l.contains("alpha") || !l["alpha"].is_number() || !(l["alpha"].get<double>() >= 0.001) ||
          !(l["alpha"].get<double>() <= 1.0)) {
        throw std::runtime_error(where + ": 'lobes': a ggx lobe's 'alpha' must be a number in [0.001, 1]");
      }
      lobe.alpha = l["alpha"].get<double>();
    }
    else if (c != "diffuse" && c != "translucent") {
      throw std::runtime_error(where + ": 'lobes': a lobe's 'closure' must be diffuse, translucent or ggx");
    }
    s.lobes.push_back(lobe);
  }
  const size_t cells = 2 * size_t(s.view_bins);
  s.transparent = floats(j, "transparent", cells, 0.0, 1.0, where);
  s.W = floats(j, "W", cells * s.lobes.size() * 3, 0.0, kMaxWeight, where);
  s.albedo = floats(j, "albedo", cells * 3, 0.0, 1.5, where);
  s.fit_error = floats(j, "fit_error", cells, 0.0, 1e6, where);
  s.source = j.value("source", json::object());
  return s;
}

void save_surface(const SurfaceBsdf &s, const std::string &path)
{
  write_file_atomically(path, surface_to_json(s).dump(1) + "\n", "");
}

SurfaceBsdf load_surface(const std::string &path)
{
  const std::string where = "surface file '" + path + "'";
  json j;
  try {
    j = json::parse(read_file(path));
  }
  catch (const json::exception &e) {
    throw std::runtime_error(where + ": not valid JSON (" + std::string(e.what()) + ")");
  }
  catch (const std::runtime_error &e) {
    throw std::runtime_error(where + ": " + e.what());
  }
  return surface_from_json(j, where);
}

}  // namespace neuralyarn::model
