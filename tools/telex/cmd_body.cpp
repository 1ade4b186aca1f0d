// SPDX-License-Identifier: MIT
// `telex body --check`: the virtual body's arm solve against generated arms with known elbows and
// against singular and hostile inputs; non-zero exit on any failure.
#include <fmt/format.h>

#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "command.h"
#include "suite_report.h"
#include "telex/stability/body_check.h"

namespace telex::tool {
namespace {

struct Options {
  bool check = false;
  bool json = false;
  std::uint64_t seed = 1;
};

int run(const Options& o) {
  if (!o.check) {
    std::fprintf(stderr, "telex body: nothing to do: give --check (see telex body --help)\n");
    return 2;
  }
  const std::vector<BodyCaseResult> cases = run_body_check(o.seed);
  const std::string header = fmt::format("{:<52} {:<4} {:<9} {:>14} {:>7}", "case", "ok",
                                         "reachable", "elbow err mm", "NaN/Inf");
  return report_suite(
      cases, o.json, header.c_str(),
      [](const BodyCaseResult& c) {
        nlohmann::json e{{"name", c.name},           {"pass", c.pass},
                         {"reachable", c.reachable}, {"elbow_error_m", nullptr},
                         {"nonfinite", c.nonfinite}, {"updates", c.updates},
                         {"criteria", c.criteria},   {"note", c.note}};
        if (c.elbow_error_m) e["elbow_error_m"] = *c.elbow_error_m;
        return e;
      },
      [](const BodyCaseResult& c) {
        const std::string err =
            c.elbow_error_m ? fmt::format("{:.4g}", *c.elbow_error_m * 1e3) : std::string("-");
        std::printf("%-52s %-4s %-9s %14s %7llu\n", c.name.c_str(), c.pass ? "PASS" : "FAIL",
                    c.reachable ? "yes" : "no", err.c_str(),
                    static_cast<unsigned long long>(c.nonfinite));
      },
      [](const BodyCaseResult&) {});
}

const RegisterCommand kRegister{
    "body", "The virtual body's arm solve: --check runs its ground-truth and hostile cases",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto o = std::make_shared<Options>();
      app.add_flag("--check", o->check,
                   "run the check suite (generated arms with known elbows, singular and hostile "
                   "inputs); exit 1 on any failure");
      app.add_flag("--json", o->json, "print one JSON object instead of the table");
      app.add_option("--seed", o->seed, "seed of the generated arms");
      return [o] { return run(*o); };
    }};

}  // namespace
}  // namespace telex::tool
