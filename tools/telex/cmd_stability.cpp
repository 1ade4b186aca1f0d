// SPDX-License-Identifier: MIT
// `telex stability`: runs the haptic model's stability and accuracy suite; non-zero exit on
// failure.
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "command.h"
#include "suite_report.h"
#include "telex/stability/haptic_stability.h"

namespace telex::tool {
namespace {

struct Options {
  bool json = false;
  std::uint64_t random_ticks = 1'000'000;
  std::uint64_t seed = 1;
};

int run(const Options& o) {
  StabilityOptions so;
  so.random_ticks = o.random_ticks;
  so.seed = o.seed;
  const std::vector<StabilityCaseResult> cases = run_stability_suite(so);
  char header[160];
  std::snprintf(header, sizeof header, "%-34s %-4s %10s %11s %12s %7s %9s", "case", "ok",
                "max|F| N", "max|dF| N", "energy in J", "NaN/Inf", "ticks");
  return report_suite(
      cases, o.json, header,
      [](const StabilityCaseResult& c) {
        nlohmann::json e{{"name", c.name},
                         {"group", c.group},
                         {"pass", c.pass},
                         {"max_force_N", c.max_force_N},
                         {"max_force_step_N", c.max_force_step_N},
                         {"energy_in_J", c.energy_in_J},
                         {"nonfinite", c.nonfinite},
                         {"ticks", c.ticks},
                         {"criteria", c.criteria},
                         {"note", c.note}};
        for (const auto& [k, v] : c.metrics) e["metrics"][k] = v;
        return e;
      },
      [](const StabilityCaseResult& c) {
        std::printf("%-34s %-4s %10.4g %11.4g %12.4g %7llu %9llu\n", c.name.c_str(),
                    c.pass ? "PASS" : "FAIL", c.max_force_N, c.max_force_step_N, c.energy_in_J,
                    static_cast<unsigned long long>(c.nonfinite),
                    static_cast<unsigned long long>(c.ticks));
      },
      [](const StabilityCaseResult& c) {
        for (const auto& [k, v] : c.metrics) std::printf("    %s = %.6g\n", k.c_str(), v);
      });
}

const RegisterCommand kRegister{
    "stability", "Stability and accuracy suite of the haptic force model",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto o = std::make_shared<Options>();
      app.add_flag("--json", o->json, "print one JSON object instead of the table");
      app.add_option("--random-ticks", o->random_ticks,
                     "ticks of the random fingertip/surface case (default 1e6)")
          ->check(cli::Range(std::uint64_t{1}, std::uint64_t{100'000'000}));
      app.add_option("--seed", o->seed, "seed of the random case");
      return [o] { return run(*o); };
    }};

}  // namespace
}  // namespace telex::tool
