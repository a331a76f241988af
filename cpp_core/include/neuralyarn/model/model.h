// SPDX-License-Identifier: Apache-2.0
//
// A trained neural yarn model: the three networks (T, R, M), the fitted sampling proxy, the preset it
// was trained for, and where it came from. Stored as versioned JSON (docs/file_formats.md, "Model
// file"); kernel_flat() produces the float array of kernel/yarn_bsdf.h that renderers upload.
#pragma once

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "neuralyarn/geometry/yarn_structure.h"
#include "neuralyarn/model/fallback.h"
#include "neuralyarn/presets.h"
#include "neuralyarn/train/mlp.h"

namespace neuralyarn::model {

/* 2: energy calibration table; 3: R azimuth table (kernel array layout 3); 4 and 5 hold kernel arrays of
 * layout 4, 5 or 6 (6: the R nodes' frames), which load as layout 6. Versions 1 and 2 still load
 * (without the tables they lack; their kernel array is rebuilt in the current layout). */
constexpr int kModelFormatVersion = 4;
/* A yarn-level model (docs/decisions.md D27): layout 4 plus the "structure" it was baked for. A build that
 * reads only up to version 4 refuses it rather than rendering a yarn's model on a ply. */
constexpr int kModelFormatVersionYarn = 5;

class ModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/* One trained network and how it was trained. */
struct NetworkRecord {
  train::MlpShape shape;
  std::vector<float> flat; /* kernel/mlp.h layout */
  nlohmann::json training; /* loss, steps, batch, learning rate, samples, losses, seconds, ... */
};

/* Importance-sampling proxy of kernel/yarn_bsdf.h (angles in radians). */
struct SamplingProxy {
  double kappa_R = 0.5; /* P(R | not T)                         */
  double beta_M = 0.5;  /* longitudinal width of the M lobe      */
  double gamma_M = 1.0; /* azimuthal width (vM concentration 1/gamma^2) */
  double kappa_M = 0.5; /* weight of the lobe against uniform    */
};

/* Per-incident-bin energy calibration (kernel/yarn_bsdf.h yarn_calibration, model/calibration.h): dP_T
 * is added to P_T, c_R (RGB) scales rho_R F, c_M (RGB) the M network, all bilinear over bin centres. Empty: no
 * table (dP_T = 0, c = 1). */
struct EnergyCalibration {
  int theta_bins = 0, phi_bins = 0;
  std::vector<float> values; /* [theta_i][phi_i][dP_T, c_R.rgb, c_M.rgb] */
  int clamped = 0;           /* bins whose ratio hit the clamp range (no energy in map or network) */
  bool empty() const { return theta_bins == 0; }
};

/* The R lobe's shape over w_i (kernel/yarn_bsdf.h, model/r_shape.h): the azimuthal density nu(phi~_o | w_i)
 * of its reflection part and its TT share tau. Empty: uniform azimuth, no TT. */
struct RShapeTable {
  int theta_bins = 0, phi_bins = 0, azimuth_bins = 0;
  /* [theta_i][phi_i][nu over phi~_o (sum * pi / azimuth_bins = 1), tau r, g, b (in [0, 1])] */
  std::vector<float> values;
  bool empty() const { return theta_bins == 0; }
  int stride() const { return azimuth_bins + 3; }
};

/* How far along the ply scattered light travels before it leaves (decisions D68, D72, kernel/exit_placement.h): the
 * gather's signed quantiles of the exit's axial offset per band of the light's direction (rdm::GatherStats::
 * axial_exit_through, axial_exit_reflected: ny::kExitBands x ny::kExitQuantiles), ply radii, for the light that
 * leaves through the far side and for the light that leaves on the side it entered. A
 * renderer moves the origin of such a path by an offset drawn from them. Not in the kernel array (the fallback
 * tables name that array): the model file's "near_field". Empty: those paths leave from the hit point, as models
 * before it rendered. */
struct NearField {
  std::vector<float> through, reflected;
  /* Where around the ply the light came in, per side (decisions D73; rdm::GatherStats::entry_h_through,
   * entry_h_reflected: ny::kExitBands x ny::kEntryRows x ny::kExitQuantiles of h in [-1, 1]). Empty: on the line
   * through the hit point, as models before D73 rendered. */
  std::vector<float> through_entry, reflected_entry;
  bool empty() const { return through.empty() && reflected.empty(); }
  bool operator==(const NearField &o) const
  {
    return through == o.through && reflected == o.reflected && through_entry == o.through_entry &&
           reflected_entry == o.reflected_entry;
  }
};

struct YarnModel {
  FiberPreset preset;
  geometry::YarnStructure structure; /* the level: one ply of the preset, or a K-ply yarn of it */
  NetworkRecord T, R, M;
  SamplingProxy proxy;
  EnergyCalibration calibration;
  RShapeTable r_shape;
  /* The R lobe's mean free path to its fiber, in ply radii (kernel/yarn_bsdf.h; 0: the surface fiber alone,
   * as models before it rendered). */
  double r_free_path = 0.0;
  /* A yarn-level model's R nodes as fibers of the plies' visible surface (docs/decisions.md D51): the central
   * `r_surface_spread` share of it, kYarnRNodes frames of kYarnRFrameStride floats (kernel/yarn_bsdf.h,
   * r_surface_frames() in model/r_shape.h). Empty: no frames, as models before them rendered. */
  double r_surface_spread = 0.0;
  std::vector<float> r_frames;
  std::array<double, 3> albedo_M{}; /* M albedo averaged over w_i on the hemisphere */
  NearField near_field;
  nlohmann::json provenance = nlohmann::json::object(); /* maps, seeds, code version, dates */
  nlohmann::json fidelity = nlohmann::json::object();   /* the numbers of `neuralyarn check`, if run */
  /* View-dependent tables for the stock-Blender fallbacks (model/fallback.h); optional. They describe
   * the model at the time they were computed: recompute them (compute_fallback) after changing it. */
  std::optional<FallbackTables> fallback;

  /* The kernel's array: header (kernel/yarn_bsdf.h YarnFlatField), the T, R and M networks, then the
   * calibration table and the R azimuth table. */
  std::vector<float> kernel_flat() const;
  /* The R lobe's surface-fiber twist (the kernel array's alpha). */
  double surface_alpha() const { return structure.is_yarn() ? structure.surface_alpha : preset.alpha; }
};

/* The architectures the kernel expects: inputs, outputs and head of each network. */
void check_network(const NetworkRecord &net, const char *name, int inputs, int outputs, ny::MlpHead head);

/* The M network's output widths the kernel takes (yarn_flat_check): 3, or 6 when it is two-sided (D45). */
inline bool is_m_output_width(int outputs) { return outputs == 3 || outputs == 6; }
/* The R-energy network's output widths: one (its colour the fiber's C_R) or three (RGB, docs/decisions.md D65). */
inline bool is_r_output_width(int outputs) { return outputs == 1 || outputs == 3; }

nlohmann::json model_to_json(const YarnModel &model);
/* A model file's "near_field" object (YarnModel::near_field, with its levels). */
nlohmann::json near_field_to_json(const NearField &near_field);
/* Validates everything (format, version, preset, network shapes, sizes, finiteness, proxy ranges);
 * throws ModelError whose message starts with `source` and names the problem. */
YarnModel model_from_json(const nlohmann::json &j, const std::string &source);

void save_model(const YarnModel &model, const std::string &path);
YarnModel load_model(const std::string &path);
/* What load_model reads and how its messages name the file: the file's JSON, unchecked (ModelError if it cannot be
 * read or parsed), for a verb that rewrites parts of a file as written; and "model file 'PATH'". */
nlohmann::json read_model_json(const std::string &path);
std::string model_source(const std::string &path);

/* Shipped models: models/<name>.json under the source tree (NEURALYARN_MODELS_DIR overrides). Returns
 * the path; throws ModelError listing the search location if there is none. */
std::string builtin_model_path(const std::string &preset_name);

}  // namespace neuralyarn::model
