// SPDX-License-Identifier: MIT
// False-colour views of depth and normal maps for display and debugging.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

namespace telex {

// Turbo colour map over [min_mm, max_mm], near = red, far = blue (values outside are clamped);
// holes (0) are black. With min_mm == max_mm == 0 the range is the 1st to 99th percentile of the
// valid pixels. Returns BGR. Throws std::invalid_argument when min_mm > max_mm.
cv::Mat3b colorize_depth(const cv::Mat1w& depth_mm, std::uint16_t min_mm = 0,
                         std::uint16_t max_mm = 0);

// Unit normals (x, y, z) as BGR colours with R = (x + 1) / 2, G = (y + 1) / 2, B = (z + 1) / 2;
// zero (invalid) normals are black.
cv::Mat3b colorize_normals(const cv::Mat3f& normals);

}  // namespace telex
