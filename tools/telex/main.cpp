// SPDX-License-Identifier: MIT
// `telex`: the offline tool (process, codec, stability, bench, ...). Bad flags exit 2.
#include <algorithm>
#include <exception>
#include <iostream>
#include <memory>

#include "command.h"

namespace telex::tool {
std::vector<CommandEntry>& command_registry() {
  static std::vector<CommandEntry> registry;
  return registry;
}
}  // namespace telex::tool

int main(int argc, char** argv) {
  using namespace telex::tool;
  telex::cli::Program program{"telex: offline tool for the telexistence haptics system", "telex"};
  const telex::cli::CommandLine& app = program.command_line();
  app.require_subcommand(1);
  auto& reg = command_registry();
  std::sort(reg.begin(), reg.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  std::vector<std::pair<telex::cli::CommandLine, std::function<int()>>> runners;
  for (auto& entry : reg) {
    telex::cli::CommandLine sub = app.add_subcommand(entry.name, entry.description);
    runners.emplace_back(sub, entry.setup(sub));
  }
  if (const auto rc = program.parse(argc, argv)) return *rc;
  for (auto& [sub, run] : runners) {
    if (sub.parsed()) {
      try {
        return run();
      } catch (const std::exception& e) {
        std::cerr << "telex " << sub.get_name() << ": error: " << e.what() << "\n";
        return 1;
      }
    }
  }
  return 2;
}
