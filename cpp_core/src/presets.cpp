// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/presets.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "neuralyarn/units.h"
#include "presets_data.h" /* generated: kPresetsJson, the text of cpp_core/data/presets.json */

namespace neuralyarn {

namespace {

std::string fmt(double v)
{
  std::ostringstream s;
  s << v;
  return s.str();
}

[[noreturn]] void fail(const FiberPreset &p, const std::string &param, const std::string &what, double got)
{
  throw ParameterError(param, "parameter '" + param + "' of fiber preset '" + p.name + "' " + what +
                                  ", got " + fmt(got));
}

void check_range(const FiberPreset &p, const std::string &param, double v, double lo, double hi,
                 bool lo_open, bool hi_open, const std::string &unit = "")
{
  const bool ok = std::isfinite(v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  if (!ok) {
    const std::string range = std::string(lo_open ? "(" : "[") + fmt(lo) + ", " +
                              (std::isinf(hi) ? std::string("inf") : fmt(hi)) + (hi_open ? ")" : "]");
    fail(p, param, "must be a finite number in " + range + (unit.empty() ? "" : " " + unit), v);
  }
}

const std::vector<std::string> &known_keys()
{
  static const std::vector<std::string> keys = {"name", "N", "rho", "alpha", "C_R", "C_TT", "beta_R_deg",
                                                "beta_TT_deg", "gamma_TT_deg", "description"};
  return keys;
}

double get_number(const nlohmann::json &o, const std::string &key, const std::string &name)
{
  if (!o.contains(key)) {
    throw ParameterError(key, "fiber preset '" + name + "' is missing parameter '" + key + "'");
  }
  const auto &v = o.at(key);
  if (!v.is_number()) {
    throw ParameterError(key, "parameter '" + key + "' of fiber preset '" + name + "' must be a number, got " +
                                  v.dump());
  }
  return v.get<double>();
}

std::array<double, 3> get_rgb(const nlohmann::json &o, const std::string &key, const std::string &name)
{
  if (!o.contains(key)) {
    throw ParameterError(key, "fiber preset '" + name + "' is missing parameter '" + key + "'");
  }
  const auto &v = o.at(key);
  if (!v.is_array() || v.size() != 3) {
    throw ParameterError(key, "parameter '" + key + "' of fiber preset '" + name +
                                  "' must be an array of 3 numbers (r, g, b), got " + v.dump());
  }
  std::array<double, 3> c{};
  for (size_t i = 0; i < 3; i++) {
    if (!v[i].is_number()) {
      throw ParameterError(key + "[" + std::to_string(i) + "]",
                           "parameter '" + key + "[" + std::to_string(i) + "]' of fiber preset '" + name +
                               "' must be a number, got " + v[i].dump());
    }
    c[i] = v[i].get<double>();
  }
  return c;
}

}  // namespace

ny::FiberBsdfParams FiberPreset::fiber_params() const
{
  ny::FiberBsdfParams p;
  p.C_R = ny::make_rgb(float(C_R[0]), float(C_R[1]), float(C_R[2]));
  p.C_TT = ny::make_rgb(float(C_TT[0]), float(C_TT[1]), float(C_TT[2]));
  p.beta_R = float(beta_R_deg * kDeg);
  p.beta_TT = float(beta_TT_deg * kDeg);
  p.gamma_TT = float(gamma_TT_deg * kDeg);
  return p;
}

void validate(const FiberPreset &p)
{
  if (p.N < 1 || p.N > kMaxFibers) {
    fail(p, "N", "must be an integer in [1, " + std::to_string(kMaxFibers) + "]", p.N);
  }
  check_range(p, "rho", p.rho, 0.0, 1.0, true, true);
  check_range(p, "alpha", p.alpha, 0.0, INFINITY, false, true);
  for (int i = 0; i < 3; i++) {
    check_range(p, "C_R[" + std::to_string(i) + "]", p.C_R[i], 0.0, 1.0, false, false);
    check_range(p, "C_TT[" + std::to_string(i) + "]", p.C_TT[i], 0.0, 1.0, false, false);
  }
  check_range(p, "beta_R_deg", p.beta_R_deg, kMinWidthDeg, kMaxWidthDeg, false, false, "degrees");
  check_range(p, "beta_TT_deg", p.beta_TT_deg, kMinWidthDeg, kMaxWidthDeg, false, false, "degrees");
  check_range(p, "gamma_TT_deg", p.gamma_TT_deg, kMinWidthDeg, kMaxWidthDeg, false, false, "degrees");
}

FiberPreset preset_from_json(const nlohmann::json &o, const std::string &name)
{
  if (!o.is_object()) {
    throw ParameterError("", "fiber preset '" + name + "' must be a JSON object, got " + o.dump());
  }
  FiberPreset p;
  p.name = name;
  if (o.contains("name")) {
    if (!o.at("name").is_string() || o.at("name").get<std::string>().empty()) {
      throw ParameterError("name", "parameter 'name' of fiber preset '" + name + "' must be a non-empty string");
    }
    p.name = o.at("name").get<std::string>();
  }
  for (const auto &item : o.items()) {
    bool known = false;
    for (const auto &k : known_keys()) {
      known = known || item.key() == k;
    }
    if (!known) {
      throw ParameterError(item.key(), "fiber preset '" + p.name + "' has an unknown parameter '" + item.key() +
                                           "' (known: N, rho, alpha, C_R, C_TT, beta_R_deg, beta_TT_deg, "
                                           "gamma_TT_deg, name, description)");
    }
  }
  const double n = get_number(o, "N", p.name);
  if (!(std::isfinite(n) && n == std::floor(n) && n >= 1 && n <= kMaxFibers)) {
    fail(p, "N", "must be an integer in [1, " + std::to_string(kMaxFibers) + "]", n);
  }
  p.N = int(n);
  p.rho = get_number(o, "rho", p.name);
  p.alpha = get_number(o, "alpha", p.name);
  p.C_R = get_rgb(o, "C_R", p.name);
  p.C_TT = get_rgb(o, "C_TT", p.name);
  p.beta_R_deg = get_number(o, "beta_R_deg", p.name);
  p.beta_TT_deg = get_number(o, "beta_TT_deg", p.name);
  p.gamma_TT_deg = get_number(o, "gamma_TT_deg", p.name);
  validate(p);
  return p;
}

nlohmann::json preset_to_json(const FiberPreset &p)
{
  nlohmann::json o;
  o["name"] = p.name;
  o["N"] = p.N;
  o["rho"] = p.rho;
  o["alpha"] = p.alpha;
  o["C_R"] = p.C_R;
  o["C_TT"] = p.C_TT;
  o["beta_R_deg"] = p.beta_R_deg;
  o["beta_TT_deg"] = p.beta_TT_deg;
  o["gamma_TT_deg"] = p.gamma_TT_deg;
  return o;
}

const std::vector<FiberPreset> &builtin_presets()
{
  static const std::vector<FiberPreset> presets = [] {
    /* ordered_json keeps the file's (the paper's) order. */
    const nlohmann::ordered_json doc = nlohmann::ordered_json::parse(kPresetsJson);
    if (doc.value("format", "") != "neuralyarn-fiber-presets" || doc.value("version", 0) != 1) {
      throw std::runtime_error("embedded presets.json has an unexpected format or version");
    }
    std::vector<FiberPreset> out;
    for (const auto &item : doc.at("presets").items()) {
      out.push_back(preset_from_json(nlohmann::json(item.value()), item.key()));
    }
    return out;
  }();
  return presets;
}

const FiberPreset &find_preset(std::string_view name)
{
  std::string known;
  for (const auto &p : builtin_presets()) {
    if (p.name == name) {
      return p;
    }
    known += (known.empty() ? "" : ", ") + p.name;
  }
  throw ParameterError("preset", "unknown fiber preset '" + std::string(name) + "' (known: " + known + ")");
}

FiberPreset load_preset_file(const std::string &path)
{
  std::ifstream in(path);
  if (!in) {
    throw ParameterError("", "cannot open fiber parameter file '" + path + "'");
  }
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(in);
  }
  catch (const nlohmann::json::parse_error &e) {
    throw ParameterError("", "fiber parameter file '" + path + "' is not valid JSON: " + e.what());
  }
  std::string stem = path;
  const auto slash = stem.find_last_of('/');
  if (slash != std::string::npos) {
    stem = stem.substr(slash + 1);
  }
  const auto dot = stem.find_last_of('.');
  if (dot != std::string::npos && dot > 0) {
    stem = stem.substr(0, dot);
  }
  try {
    return preset_from_json(doc, stem);
  }
  catch (const ParameterError &e) {
    throw ParameterError(e.parameter(), path + ": " + e.what());
  }
}

}  // namespace neuralyarn
