// SPDX-License-Identifier: MIT
// `telex`: the offline tool (process, codec, stability, bench, ...). Bad flags exit 2.
#include <algorithm>
#include <exception>
#include <iostream>
#include <memory>

#include "command.h"
#include "telex/cli/cli.h"

namespace telex::tool {
std::vector<CommandEntry>& command_registry() {
  static std::vector<CommandEntry> registry;
  return registry;
}
}  // namespace telex::tool

int main(int argc, char** argv) {
  using namespace telex::tool;
  CLI::App app{"telex: offline tool for the telexistence haptics system"};
  telex::cli::prepare(app, "telex");
  app.require_subcommand(1);
  auto& reg = command_registry();
  std::sort(reg.begin(), reg.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  std::vector<std::pair<CLI::App*, std::function<int()>>> runners;
  for (auto& entry : reg) {
    CLI::App* sub = app.add_subcommand(entry.name, entry.description);
    runners.emplace_back(sub, entry.setup(*sub));
  }
  if (const auto rc = telex::cli::parse(app, argc, argv)) return *rc;
  for (auto& [sub, run] : runners) {
    if (sub->parsed()) {
      try {
        return run();
      } catch (const std::exception& e) {
        std::cerr << "telex " << sub->get_name() << ": error: " << e.what() << "\n";
        return 1;
      }
    }
  }
  return 2;
}
