// SPDX-License-Identifier: MIT
// Sub-command registry of the `telex` tool: each command_*.cpp registers itself at start-up.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "telex/cli/command_line.h"

namespace telex::tool {

// A sub-command adds its options to `app` and returns the function that runs it (exit code).
using CommandSetup = std::function<std::function<int()>(cli::CommandLine& app)>;

struct CommandEntry {
  std::string name;
  std::string description;
  CommandSetup setup;
};

std::vector<CommandEntry>& command_registry();

struct RegisterCommand {
  RegisterCommand(std::string name, std::string description, CommandSetup setup) {
    command_registry().push_back({std::move(name), std::move(description), std::move(setup)});
  }
};

}  // namespace telex::tool
