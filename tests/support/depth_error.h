// SPDX-License-Identifier: MIT
// Error statistics of an estimated depth image against ground truth (registration, pipeline).
#pragma once

#include <opencv2/core.hpp>

namespace telex::test {

struct DepthError {
  double median_mm = 0;
  double p90_mm = 0;
  double coverage = 0;   // fraction of pixels valid in the truth that are valid in the estimate
  double over_10mm = 0;  // fraction of compared pixels off by more than 10 mm (misplaced edges)
};

// Over the pixels valid in both; `truth_m` in metres (0 = none), `estimate` in millimetres.
DepthError compare_depth(const cv::Mat1w& estimate, const cv::Mat1f& truth_m);

}  // namespace telex::test
