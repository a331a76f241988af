// SPDX-License-Identifier: Apache-2.0
#include "neuralyarn/model/model.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "neuralyarn/io.h"
#include "neuralyarn/kernel/exit_placement.h"
#include "neuralyarn/kernel/yarn_bsdf.h"
#include "neuralyarn/units.h"
#include "neuralyarn/version.h"

#ifndef NEURALYARN_SOURCE_DIR
#  define NEURALYARN_SOURCE_DIR "."
#endif

namespace neuralyarn::model {

using nlohmann::json;

namespace {

const char *head_name(ny::MlpHead h)
{
  switch (h) {
    case ny::kMlpHeadSigmoid:
      return "sigmoid";
    case ny::kMlpHeadExp:
      return "exp";
    default:
      return "identity";
  }
}

json network_to_json(const NetworkRecord &n)
{
  json j;
  j["widths"] = n.shape.widths;
  j["head"] = head_name(n.shape.head);
  j["activation"] = "prelu";
  j["kernel_array"] = n.flat;
  j["training"] = n.training;
  return j;
}

NetworkRecord network_from_json(const json &j, const std::string &source, const char *name)
{
  const std::string where = source + ": network " + name + ": ";
  NetworkRecord n;
  if (!j.is_object()) {
    throw ModelError(where + "must be an object");
  }
  if (j.value("activation", "prelu") != "prelu") {
    throw ModelError(where + "activation '" + j.value("activation", "") + "' is not supported (prelu only)");
  }
  std::vector<float> flat;
  try {
    for (const json &v : j.at("kernel_array")) {
      if (!v.is_number()) {
        throw ModelError(where + "kernel_array holds a non-number");
      }
      flat.push_back(v.get<float>());
    }
  }
  catch (const json::exception &e) {
    throw ModelError(where + "missing or malformed kernel_array (" + e.what() + ")");
  }
  try {
    const train::Mlp<float> net = train::Mlp<float>::from_flat(flat);
    n.shape = net.shape();
  }
  catch (const std::exception &e) {
    throw ModelError(where + e.what());
  }
  /* The descriptive keys must agree with the array's own header. */
  if (j.contains("widths") && j["widths"] != json(n.shape.widths)) {
    throw ModelError(where + "'widths' disagrees with the kernel array's header");
  }
  if (j.contains("head") && j["head"] != head_name(n.shape.head)) {
    throw ModelError(where + "'head' disagrees with the kernel array's header");
  }
  n.flat = std::move(flat);
  n.training = j.value("training", json::object());
  return n;
}

double finite_in(const json &j, const char *key, double lo, double hi, const std::string &where)
{
  if (!j.contains(key) || !j[key].is_number()) {
    throw ModelError(where + "missing number '" + key + "'");
  }
  const double v = j[key].get<double>();
  if (!std::isfinite(v) || v < lo || v > hi) {
    throw ModelError(where + "'" + key + "' = " + std::to_string(v) + " is outside [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "]");
  }
  return v;
}

/* Ratios far outside this range mean a broken table, not a calibration (bake clamps to [0.01, 100]). */
constexpr double kMaxCalibration = 1000.0;

std::vector<float> float_array(const json &j, const char *key, const std::string &where)
{
  if (!j.contains(key) || !j[key].is_array()) {
    throw ModelError(where + "missing array '" + key + "'");
  }
  std::vector<float> v;
  v.reserve(j[key].size());
  for (const json &x : j[key]) {
    if (!x.is_number()) {
      throw ModelError(where + "'" + key + "' holds a non-number (NaN is written as null)");
    }
    v.push_back(x.get<float>());
  }
  return v;
}

/* The table's shape from the "calibration" object, its values from the kernel array (already checked
 * by ny::yarn_flat_check, which guarantees the size). */
EnergyCalibration calibration_from(const json &j, const std::vector<float> &flat, size_t end, const std::string &where)
{
  EnergyCalibration c;
  if (!j.is_object()) {
    throw ModelError(where + "must be an object");
  }
  c.theta_bins = int(finite_in(j, "theta_i_bins", 1, 4096, where));
  c.phi_bins = int(finite_in(j, "phi_i_bins", 1, 4096, where));
  c.clamped = j.value("clamped_bins", 0);
  if (float(c.theta_bins) != flat[ny::kYarnFlatCalThetaBins] || float(c.phi_bins) != flat[ny::kYarnFlatCalPhiBins]) {
    throw ModelError(where + "its bins disagree with the kernel array's header");
  }
  const size_t begin = size_t(flat[ny::kYarnFlatOffset_Cal]);
  if (begin + size_t(c.theta_bins) * size_t(c.phi_bins) * ny::kYarnCalStride != end || end > flat.size()) {
    throw ModelError(where + "the kernel array holds a table of another size");
  }
  c.values.assign(flat.begin() + long(begin), flat.begin() + long(end));
  for (size_t i = 0; i < c.values.size(); i++) {
    /* dP_T in [-1, 1], the factors in [0, kMaxCalibration]. */
    const bool is_dP_T = i % ny::kYarnCalStride == 0;
    const double lo = is_dP_T ? -1.0 : 0.0, hi = is_dP_T ? 1.0 : kMaxCalibration;
    if (!(c.values[i] >= lo && c.values[i] <= hi)) {
      throw ModelError(where + "table entry " + std::to_string(i) + " = " + std::to_string(c.values[i]) +
                       " is out of range (dP_T in [-1, 1], factors in [0, " + std::to_string(int(kMaxCalibration)) +
                       "])");
    }
  }
  return c;
}

/* "r_surface_frames": the spread and kYarnRNodes frames of kYarnRFrameStride numbers; that they are rotations and
 * the kernel array's own is checked with the array. */
void r_surface_frames_from(const json &j, YarnModel *m, const std::string &where)
{
  if (!m->structure.is_yarn()) {
    throw ModelError(where + "the R nodes' surface frames are a yarn-level model's");
  }
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array() ||
      j["frames"].size() != size_t(ny::kYarnRNodes)) {
    throw ModelError(where + "'frames' must be " + std::to_string(ny::kYarnRNodes) + " frames");
  }
  m->r_surface_spread = finite_in(j, "spread", 1e-6, 1.0, where);
  m->r_frames.clear();
  for (const json &frame : j["frames"]) {
    if (!frame.is_array() || frame.size() != size_t(ny::kYarnRFrameStride)) {
      throw ModelError(where + "a frame must be " + std::to_string(ny::kYarnRFrameStride) + " numbers");
    }
    for (const json &v : frame) {
      if (!v.is_number() || !std::isfinite(v.get<double>())) {
        throw ModelError(where + "a frame holds a non-finite number or a non-number");
      }
      m->r_frames.push_back(v.get<float>());
    }
  }
}

/* The R shape table's shape from the "r_shape" object, its values from the kernel array (checked by
 * ny::yarn_flat_check: tau in [0, 1]); every row's azimuth density must integrate to 1. */
RShapeTable r_shape_from(const json &j, const std::vector<float> &flat, const std::string &where, bool layout3)
{
  if (!j.is_object()) {
    throw ModelError(where + "must be an object");
  }
  RShapeTable t;
  t.theta_bins = int(finite_in(j, "theta_i_bins", 1, 1024, where));
  t.phi_bins = int(finite_in(j, "phi_i_bins", 1, 1024, where));
  t.azimuth_bins = int(finite_in(j, "azimuth_bins", 2, 1024, where));
  if (float(t.theta_bins) != flat[ny::kYarnFlatAzThetaBins] || float(t.phi_bins) != flat[ny::kYarnFlatAzPhiBins] ||
      float(t.azimuth_bins) != flat[ny::kYarnFlatAzBins]) {
    throw ModelError(where + "its bins disagree with the kernel array's header");
  }
  t.values.assign(flat.begin() + long(flat[ny::kYarnFlatOffset_Az]), flat.end());
  if (layout3) {
    /* Layout 3 rows hold the densities only: no TT share (tau = 0), which renders as that model did. */
    if (t.values.size() != size_t(t.theta_bins) * size_t(t.phi_bins) * size_t(t.azimuth_bins)) {
      throw ModelError(where + "the kernel array holds a table of another size");
    }
    std::vector<float> rows;
    for (size_t r = 0; r < t.values.size(); r += size_t(t.azimuth_bins)) {
      rows.insert(rows.end(), t.values.begin() + long(r), t.values.begin() + long(r) + t.azimuth_bins);
      rows.insert(rows.end(), 3, 0.0f);
    }
    t.values = rows;
  }
  const double d = kPi / t.azimuth_bins;
  for (size_t r = 0; r < t.values.size() / size_t(t.stride()); r++) {
    double sum = 0;
    for (int k = 0; k < t.azimuth_bins; k++) {
      sum += t.values[r * size_t(t.stride()) + size_t(k)] * d;
    }
    if (!(std::abs(sum - 1.0) < 1e-3)) {
      throw ModelError(where + "row " + std::to_string(r) + " integrates to " + std::to_string(sum) + ", not 1");
    }
  }
  return t;
}
/* A model file's "near_field": each side's signed quantiles per band, checked (kernel/exit_placement.h, which reads
 * the file's keys for Cycles' host too); the far side's are required, the entry side's optional. A model from
 * before D72 (unsigned, pooled) is converted. */
NearField near_field_from(const json &j, const std::string &where)
{
  if (!j.is_object()) {
    throw ModelError(where + "must be an object");
  }
  NearField nf;
  for (const bool through : {true, false}) {
    std::vector<float> q(size_t(ny::kExitBands) * ny::kExitQuantiles);
    std::vector<float> e(size_t(ny::kExitBands) * ny::kEntryRows * ny::kExitQuantiles);
    const char *key = nullptr, *problem = nullptr;
    bool has_offsets = false, has_entry = false;
    if (!ny::near_field_side_from_json(j, through, q.data(), e.data(), &has_offsets, &has_entry, &key, &problem)) {
      throw ModelError(where + (key ? "'" + std::string(key) + "' " : std::string()) + problem);
    }
    (through ? nf.through : nf.reflected) = has_offsets ? q : std::vector<float>();
    (through ? nf.through_entry : nf.reflected_entry) = has_entry ? e : std::vector<float>();
  }
  return nf;
}
}  // namespace

void check_network(const NetworkRecord &net, const char *name, int inputs, int outputs, ny::MlpHead head)
{
  const auto &w = net.shape.widths;
  if (w.empty() || w.front() != inputs || w.back() != outputs || net.shape.head != head) {
    throw ModelError(std::string("network ") + name + " must map " + std::to_string(inputs) + " inputs to " +
                     std::to_string(outputs) + " outputs with a " + head_name(head) + " head, got " +
                     train::format_widths(w) + " " + head_name(net.shape.head));
  }
}

std::vector<float> YarnModel::kernel_flat() const
{
  std::vector<float> f(ny::kYarnFlatHeader, 0.0f);
  f[ny::kYarnFlatVersion] = ny::kYarnFlatFormat;
  f[ny::kYarnFlatAlpha] = float(surface_alpha());
  const ny::FiberBsdfParams fp = preset.fiber_params();
  f[ny::kYarnFlatC_R] = fp.C_R.r;
  f[ny::kYarnFlatC_R + 1] = fp.C_R.g;
  f[ny::kYarnFlatC_R + 2] = fp.C_R.b;
  f[ny::kYarnFlatBeta_R] = fp.beta_R;
  f[ny::kYarnFlatBeta_TT] = fp.beta_TT;
  f[ny::kYarnFlatGamma_TT] = fp.gamma_TT;
  f[ny::kYarnFlatFreePath] = float(r_free_path);
  if (!r_frames.empty()) {
    f[ny::kYarnFlatOffset_RFrames] = float(f.size());
    f.insert(f.end(), r_frames.begin(), r_frames.end());
  }
  f[ny::kYarnFlatKappa_R] = float(proxy.kappa_R);
  f[ny::kYarnFlatBeta_M] = float(proxy.beta_M);
  f[ny::kYarnFlatGamma_M] = float(proxy.gamma_M);
  f[ny::kYarnFlatKappa_M] = float(proxy.kappa_M);
  for (int c = 0; c < 3; c++) {
    f[ny::kYarnFlatAlbedo_M + c] = float(albedo_M[size_t(c)]);
  }
  f[ny::kYarnFlatOffset_T] = float(f.size());
  f.insert(f.end(), T.flat.begin(), T.flat.end());
  f[ny::kYarnFlatOffset_R] = float(f.size());
  f.insert(f.end(), R.flat.begin(), R.flat.end());
  f[ny::kYarnFlatOffset_M] = float(f.size());
  f.insert(f.end(), M.flat.begin(), M.flat.end());
  f[ny::kYarnFlatOffset_Cal] = float(f.size());
  f[ny::kYarnFlatCalThetaBins] = float(calibration.theta_bins);
  f[ny::kYarnFlatCalPhiBins] = float(calibration.phi_bins);
  f.insert(f.end(), calibration.values.begin(), calibration.values.end());
  f[ny::kYarnFlatOffset_Az] = float(f.size());
  f[ny::kYarnFlatAzThetaBins] = float(r_shape.theta_bins);
  f[ny::kYarnFlatAzPhiBins] = float(r_shape.phi_bins);
  f[ny::kYarnFlatAzBins] = float(r_shape.azimuth_bins);
  f.insert(f.end(), r_shape.values.begin(), r_shape.values.end());
  f[ny::kYarnFlatSize] = float(f.size());
  return f;
}

json near_field_to_json(const NearField &near_field)
{
  std::vector<double> levels; /* the kernel's float levels, as the percentages they are */
  for (int k = 1; k <= ny::kExitQuantiles; k++) {
    levels.push_back(std::round(1000.0 * double(ny::exit_knot_level(k))) / 1000.0);
  }
  auto bands = [](const std::vector<float> &q) {
    json a = json::array();
    for (int b = 0; b < ny::kExitBands; b++) {
      a.push_back(std::vector<float>(q.begin() + b * ny::kExitQuantiles, q.begin() + (b + 1) * ny::kExitQuantiles));
    }
    return a;
  };
  json j = {{"through_bands", bands(near_field.through)},
            {"levels", levels},
            {"about", "energy-weighted quantiles of how far along the ply (ply radii) scattered light leaves from "
                      "where a ray from its entry point would, positive the way the light travelled along the ply, "
                      "per band of |cos| between the light's direction and the ply's axis (0-0.2, ..., 0.8-1): "
                      "through the far side, and on the side it entered (the gather's walks; docs/decisions.md D68, "
                      "D72)"}};
  if (!near_field.reflected.empty()) {
    j["reflected_bands"] = bands(near_field.reflected);
  }
  auto rows = [](const std::vector<float> &q) {
    json a = json::array();
    for (int b = 0; b < ny::kExitBands; b++) {
      json band = json::array();
      for (int r = 0; r < ny::kEntryRows; r++) {
        const auto at = q.begin() + (b * ny::kEntryRows + r) * ny::kExitQuantiles;
        band.push_back(std::vector<float>(at, at + ny::kExitQuantiles));
      }
      a.push_back(band);
    }
    return a;
  };
  if (!near_field.through_entry.empty()) {
    j["through_entry"] = rows(near_field.through_entry);
    j["about_entry"] = "energy-weighted quantiles of where across the ply's width (h in [-1, 1], seen along the "
                       "light's direction) the light came in, per band (as above) and per row of where it leaves "
                       "(h -1 ... 1 in ten rows): through the far side, and on the side it entered "
                       "(docs/decisions.md D73)";
  }
  if (!near_field.reflected_entry.empty()) {
    j["reflected_entry"] = rows(near_field.reflected_entry);
  }
  return j;
}

json model_to_json(const YarnModel &m)
{
  json j;
  j["format"] = "neuralyarn-model";
  j["version"] = m.structure.is_yarn() ? kModelFormatVersionYarn : kModelFormatVersion;
  j["code_version"] = std::string(kVersion) + "+" + kGitRevision;
  j["preset"] = preset_to_json(m.preset);
  if (m.structure.is_yarn()) {
    j["structure"] = geometry::structure_to_json(m.structure);
  }
  j["networks"] = {{"T", network_to_json(m.T)}, {"R", network_to_json(m.R)}, {"M", network_to_json(m.M)}};
  j["sampling"] = {{"kappa_R", m.proxy.kappa_R},
                   {"beta_M_deg", m.proxy.beta_M / kDeg},
                   {"gamma_M_deg", m.proxy.gamma_M / kDeg},
                   {"kappa_M", m.proxy.kappa_M}};
  j["albedo_M"] = m.albedo_M;
  if (!m.calibration.empty()) {
    j["calibration"] = {{"theta_i_bins", m.calibration.theta_bins},
                        {"phi_i_bins", m.calibration.phi_bins},
                        {"layout", "[theta_i][phi_i][dP_T, c_R.r, c_R.g, c_R.b, c_M.r, c_M.g, c_M.b]"},
                        {"clamped_bins", m.calibration.clamped}};
  }
  if (!m.r_shape.empty()) {
    j["r_shape"] = {{"theta_i_bins", m.r_shape.theta_bins},
                      {"phi_i_bins", m.r_shape.phi_bins},
                      {"azimuth_bins", m.r_shape.azimuth_bins},
                      {"layout", "[theta_i][phi_i][nu over phi~_o in (-90, 90) deg, tau r, g, b]: the R lobe's azimuth density and TT share"}};
  }
  j["r_free_path"] = m.r_free_path;
  if (!m.r_frames.empty()) {
    json frames = json::array();
    for (size_t q = 0; q < m.r_frames.size(); q += ny::kYarnRFrameStride) {
      const auto first = m.r_frames.begin() + long(q);
      frames.push_back(std::vector<float>(first, first + ny::kYarnRFrameStride));
    }
    j["r_surface_frames"] = {{"spread", m.r_surface_spread},
                             {"layout", "per R node: cos, sin of P, of a, of M (w -> M R_x(a) P w, kernel/yarn_bsdf.h)"},
                             {"frames", frames}};
  }
  if (!m.near_field.through.empty()) {
    j["near_field"] = near_field_to_json(m.near_field);
  }
  /* What a renderer uploads, ready to use (kernel/yarn_bsdf.h): the calibration table's values are only
   * here; the loader checks that the rest agrees with the parts above. */
  j["kernel_flat"] = m.kernel_flat();
  j["provenance"] = m.provenance;
  j["fidelity"] = m.fidelity;
  if (m.fallback) {
    j["fallback"] = fallback_to_json(*m.fallback);
  }
  return j;
}

YarnModel model_from_json(const json &j, const std::string &source)
{
  const std::string where = source + ": ";
  if (!j.is_object() || j.value("format", "") != "neuralyarn-model") {
    throw ModelError(where + "not a neuralyarn model (the key \"format\" must be \"neuralyarn-model\")");
  }
  if (!j.contains("version") || !j["version"].is_number_integer() || j["version"].get<int>() < 1 ||
      j["version"].get<int>() > kModelFormatVersionYarn) {
    throw ModelError(where + "model format version " + (j.contains("version") ? j["version"].dump() : "(missing)") +
                     " is not supported (this build reads versions 1 to " + std::to_string(kModelFormatVersionYarn) + ")");
  }
  YarnModel m;
  try {
    m.preset = preset_from_json(j.at("preset"), "model");
  }
  catch (const json::exception &) {
    throw ModelError(where + "missing 'preset'");
  }
  catch (const std::exception &e) {
    throw ModelError(where + "preset: " + e.what());
  }
  if (j["version"].get<int>() == kModelFormatVersionYarn) {
    try {
      m.structure = geometry::structure_from_json(j.value("structure", json()));
    }
    catch (const ParameterError &e) {
      throw ModelError(where + "a version 5 (yarn-level) model: " + e.what());
    }
  }
  else if (j.contains("structure")) {
    throw ModelError(where + "'structure' (a yarn-level model) needs format version 5");
  }
  if (!j.contains("networks") || !j["networks"].is_object()) {
    throw ModelError(where + "missing 'networks'");
  }
  const json &nets = j["networks"];
  for (const char *name : {"T", "R", "M"}) {
    if (!nets.contains(name)) {
      throw ModelError(where + "missing network '" + name + "'");
    }
  }
  m.T = network_from_json(nets["T"], source, "T");
  m.R = network_from_json(nets["R"], source, "R");
  m.M = network_from_json(nets["M"], source, "M");
  try {
    check_network(m.T, "T", 3, 1, ny::kMlpHeadSigmoid);
    const std::vector<int> &wR = m.R.shape.widths;
    check_network(m.R, "R", 3, !wR.empty() && is_r_output_width(wR.back()) ? wR.back() : 1, ny::kMlpHeadExp);
    const std::vector<int> &wM = m.M.shape.widths;
    check_network(m.M, "M", 6, !wM.empty() && is_m_output_width(wM.back()) ? wM.back() : 3, ny::kMlpHeadExp);
  }
  catch (const ModelError &e) {
    throw ModelError(where + e.what());
  }
  if (!j.contains("sampling") || !j["sampling"].is_object()) {
    throw ModelError(where + "missing 'sampling'");
  }
  const json &s = j["sampling"];
  const std::string ws = where + "sampling: ";
  m.proxy.kappa_R = finite_in(s, "kappa_R", 0.0, 1.0, ws);
  m.proxy.beta_M = finite_in(s, "beta_M_deg", 0.01, 360.0, ws) * kDeg;
  m.proxy.gamma_M = finite_in(s, "gamma_M_deg", 0.01, 1e4, ws) * kDeg;
  m.proxy.kappa_M = finite_in(s, "kappa_M", 0.0, 1.0, ws);
  if (!j.contains("albedo_M") || !j["albedo_M"].is_array() || j["albedo_M"].size() != 3) {
    throw ModelError(where + "'albedo_M' must be three numbers");
  }
  for (size_t c = 0; c < 3; c++) {
    const json &v = j["albedo_M"][c];
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0.0 || v.get<double>() > 1.5) {
      throw ModelError(where + "'albedo_M' values must be finite, in [0, 1.5]");
    }
    m.albedo_M[c] = v.get<double>();
  }
  const int version = j["version"].get<int>();
  std::optional<std::string> written_flat_hash; /* of a layout 4 or 5 array, which its fallback tables name */
  if (version >= 2) {
    /* The kernel array: layout 2 (no R table; the calibration table runs to the end), 3 (the R azimuth table
     * without the TT share, under "r_azimuth"), 4 (no R free path), 5 (no R node frames) and 6 (this code's).
     * Layouts 2 and 3 are only checked for their version and numbers and rebuilt with the tables taken over (a
     * TT share of 0 renders as they did); a layout 4 or 5 array is moved to layout 6 with zeros in the fields
     * it lacks (the same rendering) and then checked as one. */
    std::vector<float> flat = float_array(j, "kernel_flat", where);
    int layout = std::min(version, 4); /* 2, 3 or 4 (versions 4 and 5 hold layout 4, 5 or 6) */
    const int written_layout = layout == 4 && !flat.empty() ? int(flat[0]) : layout;
    const int missing = layout == 4 ? ny::yarn_flat_missing_fields(flat.data(), int(flat.size())) : 0;
    if (missing > 0) {
      std::vector<float> upgraded(flat.size() + size_t(missing));
      if (!ny::yarn_flat_upgrade(flat.data(), int(flat.size()), upgraded.data())) {
        throw ModelError(where + "'kernel_flat' is not a layout " + std::to_string(written_layout) + " array");
      }
      written_flat_hash = fnv1a64_hex(flat); /* what its fallback tables name */
      flat = std::move(upgraded);
    }
    if (j.contains("r_free_path") && (layout < 4 || written_layout == 4)) {
      throw ModelError(where + "'r_free_path' needs a layout 5 or 6 'kernel_flat'");
    }
    if (j.contains("r_surface_frames") && (layout < 4 || written_flat_hash)) {
      throw ModelError(where + "'r_surface_frames' needs a layout 6 'kernel_flat'");
    }
    if (layout == 4) {
      layout = 6;
      if (j.contains("r_free_path")) {
        m.r_free_path = finite_in(j, "r_free_path", 0.0, ny::kYarnMaxFreePath, where);
      }
      if (j.contains("r_surface_frames")) {
        r_surface_frames_from(j["r_surface_frames"], &m, where + "r_surface_frames: ");
      }
      if (const char *problem = ny::yarn_flat_check(flat.data(), int(flat.size()))) {
        throw ModelError(where + "'kernel_flat' " + problem);
      }
    }
    else {
      const size_t header = layout == 2 ? 20 : 24;
      if (flat.size() < header || flat[0] != float(layout) ||
          (layout == 3 && !(flat[ny::kYarnFlatOffset_Az] >= float(header) &&
                            flat[ny::kYarnFlatOffset_Az] <= float(flat.size())))) {
        throw ModelError(where + "'kernel_flat' is not a layout " + std::to_string(layout) + " array");
      }
      for (float v : flat) {
        if (!std::isfinite(v)) {
          throw ModelError(where + "'kernel_flat' holds a non-finite number");
        }
      }
    }
    if (j.contains("calibration")) {
      const size_t end = layout == 2 ? flat.size() : size_t(flat[ny::kYarnFlatOffset_Az]);
      m.calibration = calibration_from(j["calibration"], flat, end, where + "calibration: ");
    }
    const std::string r_key = layout == 3 ? "r_azimuth" : "r_shape";
    if (layout >= 3 && j.contains(r_key)) {
      m.r_shape = r_shape_from(j[r_key], flat, where + r_key + ": ", layout == 3);
    }
    if (layout == 6 && m.kernel_flat() != flat) {
      throw ModelError(where + "'kernel_flat' disagrees with the networks, preset and sampling parameters");
    }
  }
  if (j.contains("near_field")) {
    m.near_field = near_field_from(j["near_field"], where + "near_field: ");
  }
  m.provenance = j.value("provenance", json::object());
  m.fidelity = j.value("fidelity", json::object());
  /* A version 2 or 3 file's fallback tables refer to its older kernel array by hash; they are left out (the
   * maths is the same: `neuralyarn fallback` recomputes them in the current layout). */
  if (j.contains("fallback") && version >= 4) {
    m.fallback = fallback_from_json(j["fallback"], m, where, written_flat_hash ? &*written_flat_hash : nullptr);
  }
  return m;
}

void save_model(const YarnModel &model, const std::string &path)
{
  try {
    write_file_atomically(path, model_to_json(model).dump(1) + "\n", "");
  }
  catch (const std::runtime_error &e) {
    throw ModelError("model file '" + path + "': " + e.what());
  }
}

std::string model_source(const std::string &path) { return "model file '" + path + "'"; }

json read_model_json(const std::string &path)
{
  const std::string source = model_source(path);
  std::string text;
  try {
    text = read_file(path);
  }
  catch (const std::runtime_error &e) {
    throw ModelError(source + ": " + e.what());
  }
  try {
    return json::parse(text);
  }
  catch (const json::exception &e) {
    throw ModelError(source + ": not valid JSON (" + std::string(e.what()) + ")");
  }
}

YarnModel load_model(const std::string &path) { return model_from_json(read_model_json(path), model_source(path)); }

std::string builtin_model_path(const std::string &preset_name)
{
  namespace fs = std::filesystem;
  const char *env = std::getenv("NEURALYARN_MODELS_DIR");
  const fs::path dir = env && *env ? fs::path(env) : fs::path(NEURALYARN_SOURCE_DIR) / "models";
  const fs::path p = dir / (preset_name + ".json");
  if (!fs::exists(p)) {
    throw ModelError("no shipped model '" + p.string() + "' (bake one with `neuralyarn bake --preset " + preset_name +
                     "` or set NEURALYARN_MODELS_DIR)");
  }
  return p.string();
}

}  // namespace neuralyarn::model
