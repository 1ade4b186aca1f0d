// SPDX-License-Identifier: MIT
// The operator's picture: remote camera (or colourised depth) with the virtual hand, an inset of
// the normal map, one force arrow per fingertip and a status text.
#pragma once

#include <array>
#include <string>

#include "telex/haptics/haptic_model.h"
#include "telex/local/tracker.h"

namespace telex::local {

struct ViewInputs {
  cv::Mat3b camera_bgr;              // right-eye image; empty = draw the colourised depth instead
  const Surface* surface = nullptr;  // may be null before the first frame
  cv::Mat1w depth_mm;                // raw depth for the colourised background
  HandState hand;
  // The tick re-expressed in the camera (reexpress): there the Model frame is the Camera.
  std::array<FingertipForce, kFingerCount> forces{};
  std::string status;
  double arrow_m_per_N = 0.02;  // force arrow length in the scene per newton
};

// Pure: draws into a new image the size of the camera image (or of the depth).
cv::Mat3b render_operator_view(const ViewInputs& in);

// Pixel of a camera-frame point, or nothing behind the camera.
std::optional<cv::Point2d> project(const Intrinsics& k, const glm::dvec3& p_CameraQ);

}  // namespace telex::local
