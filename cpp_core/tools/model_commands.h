// SPDX-License-Identifier: Apache-2.0
//
// The model verbs of `neuralyarn`: train, fit, bake, check.
#pragma once

#include <memory>

#include <CLI/CLI.hpp>

namespace neuralyarn::cli {

class ModelCommands {
 public:
  virtual ~ModelCommands() = default;
  /* Runs the verb that was parsed; returns -1 if none of these was. Throws on errors. */
  virtual int run() = 0;
};

std::unique_ptr<ModelCommands> add_model_commands(CLI::App &app);

}  // namespace neuralyarn::cli
