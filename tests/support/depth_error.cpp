// SPDX-License-Identifier: MIT
// Error statistics of an estimated depth image against ground truth.
#include "depth_error.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace telex::test {

DepthError compare_depth(const cv::Mat1w& estimate, const cv::Mat1f& truth_m) {
  std::vector<double> err;
  int truth_valid = 0;
  for (int v = 0; v < truth_m.rows; ++v)
    for (int u = 0; u < truth_m.cols; ++u) {
      if (!(truth_m(v, u) > 0)) continue;
      ++truth_valid;
      if (estimate(v, u) == 0) continue;
      err.push_back(std::abs(estimate(v, u) - truth_m(v, u) * 1000.0));
    }
  DepthError s;
  if (err.empty()) return s;
  std::sort(err.begin(), err.end());
  s.median_mm = err[err.size() / 2];
  s.p90_mm = err[err.size() * 9 / 10];
  s.coverage = static_cast<double>(err.size()) / truth_valid;
  s.over_10mm =
      static_cast<double>(err.end() - std::upper_bound(err.begin(), err.end(), 10.0)) / err.size();
  return s;
}

}  // namespace telex::test
