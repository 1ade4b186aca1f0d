// SPDX-License-Identifier: MIT
// How `telex body --check` and `telex stability` report a suite of pass/fail cases: one JSON object
// ({"cases": [...], "passed": N, "failed": M}) or a table with each case's criteria and result,
// and the exit code (0 when every case passed, 1 otherwise).
#pragma once

#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <vector>

namespace telex::tool {

// `to_json(case)` gives a case's JSON object; `print_row(case)` prints its table row, and
// `print_after(case)` any lines of its own after the criteria and result. Each case has `pass`,
// `criteria` and `note`.
template <class Case, class ToJson, class PrintRow, class PrintAfter>
int report_suite(const std::vector<Case>& cases, bool json, const char* header, ToJson to_json,
                 PrintRow print_row, PrintAfter print_after) {
  int passed = 0, failed = 0;
  for (const auto& c : cases) (c.pass ? passed : failed)++;
  if (json) {
    nlohmann::json j;
    j["cases"] = nlohmann::json::array();
    for (const auto& c : cases) j["cases"].push_back(to_json(c));
    j["passed"] = passed;
    j["failed"] = failed;
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("%s\n", header);
    for (const auto& c : cases) {
      print_row(c);
      std::printf("    criteria: %s\n    result:   %s\n", c.criteria.c_str(), c.note.c_str());
      print_after(c);
    }
    std::printf("passed %d, failed %d\n", passed, failed);
  }
  return failed == 0 ? 0 : 1;
}

}  // namespace telex::tool
