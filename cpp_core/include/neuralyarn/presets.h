// SPDX-License-Identifier: Apache-2.0
//
// Fiber and yarn-geometry parameters of a material: the paper's Table "Fiber parameters" and user files
// in the same schema (docs/file_formats.md, "Fiber parameter files"). Everything that enters is
// validated; a bad value raises ParameterError whose message names the parameter.
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "neuralyarn/kernel/fiber_bsdf.h"

namespace neuralyarn {

/* A parameter (or parameter file) that cannot describe a physical fiber. */
class ParameterError : public std::runtime_error {
 public:
  ParameterError(const std::string &parameter, const std::string &message)
      : std::runtime_error(message), parameter_(parameter)
  {
  }
  /* The offending parameter's name as it appears in the file ("beta_R_deg", "C_TT[2]", ...). */
  const std::string &parameter() const { return parameter_; }

 private:
  std::string parameter_;
};

struct FiberPreset {
  std::string name;
  /* Yarn geometry (paper Sec. 2, Eq. 1). */
  int N = 0;          /* fibers per ply                                      */
  double rho = 0.0;   /* fiber density N r^2 / R^2, in (0, 1)                */
  double alpha = 0.0; /* twist factor 2 R dn / dl, >= 0                       */
  /* Fiber shading (Khungurn et al. 2015). Widths are in degrees, as in the paper's table. */
  std::array<double, 3> C_R{};
  std::array<double, 3> C_TT{};
  double beta_R_deg = 0.0;
  double beta_TT_deg = 0.0;
  double gamma_TT_deg = 0.0;

  /* The kernel's view: widths converted to radians. */
  ny::FiberBsdfParams fiber_params() const;
};

/* Accepted ranges (also listed in docs/file_formats.md). */
constexpr double kMinWidthDeg = 0.01;
constexpr double kMaxWidthDeg = 180.0;
constexpr int kMaxFibers = 100000;

/* Throws ParameterError naming the first parameter that is out of range or not finite. */
void validate(const FiberPreset &preset);

/* Parses and validates one preset object. Unknown keys are errors (a misspelt key would otherwise be
 * silently ignored). `name` is used when the object has no "name" key. */
FiberPreset preset_from_json(const nlohmann::json &object, const std::string &name);

/* The inverse of preset_from_json (same keys; round-trips exactly). */
nlohmann::json preset_to_json(const FiberPreset &preset);

/* The five presets of the paper, parsed from the embedded cpp_core/data/presets.json and validated on
 * first use. */
const std::vector<FiberPreset> &builtin_presets();

/* A built-in preset by name; the error lists the known names. */
const FiberPreset &find_preset(std::string_view name);

/* A user parameter file (a single preset object, see docs/file_formats.md). Errors name the file. */
FiberPreset load_preset_file(const std::string &path);

}  // namespace neuralyarn
