// SPDX-License-Identifier: MIT
// A depth image as the remote's sources deliver it, for pipeline tests without a source.
#pragma once

#include "telex/remote/sources.h"

namespace telex::test {

// Frame `id` of a 30 Hz stream, with Kinect v1 optics scaled to the image.
inline remote::DepthFrame frame_of(const cv::Mat1w& depth, std::uint64_t id) {
  remote::DepthFrame f;
  f.image.depth_mm = depth;
  f.image.intrinsics = kinect_v1_intrinsics(depth.cols, depth.rows);
  f.frame_id = id;
  f.capture_ns = static_cast<std::int64_t>(id) * 33'333'333;
  return f;
}

}  // namespace telex::test
