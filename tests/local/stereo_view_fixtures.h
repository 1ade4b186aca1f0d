// SPDX-License-Identifier: MIT
// What the stereo view's tests share: a tracked right hand reaching forward, a pixel count, and a
// green dot straight ahead with the column it shows at.
#pragma once

#include <cstddef>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "telex/local/inputs/tracker.h"
#include "telex/local/view/stereo_view.h"

namespace telex::local::test {

// A right hand reaching forward, 45 cm in front of the eyes, fingers along +z.
inline HandState reaching_hand() {
  HandState h;
  h.time_ns = 1;
  h.skeleton_valid = true;
  h.wrist_camera = {0.05, 0.10, 0.40};
  for (std::size_t f = 0; f < kFingerCount; ++f) {
    const double x = 0.05 + (static_cast<double>(f) - 2.0) * 0.02;
    for (std::size_t j = 0; j < 4; ++j)
      h.joints_camera[f][j] = {x, 0.10, 0.48 + 0.025 * static_cast<double>(j)};
    h.tips[f].valid = true;
    h.tips[f].finger = static_cast<int>(f);
    h.tips[f].p_CameraFingertip = h.joints_camera[f][3];
  }
  return h;
}

inline int count(const cv::Mat3b& img, const std::function<bool(const cv::Vec3b&)>& pred) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) n += pred(img(y, x));
  return n;
}

// Both eyes see a green dot straight ahead of the camera on grey, over a wall 3 m away.
inline StereoViewInputs green_dot_ahead() {
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  cv::Mat3b eye(480, 640, cv::Vec3b(60, 60, 60));
  cv::rectangle(eye, cv::Rect(314, 234, 13, 13), cv::Vec3b(0, 220, 0), cv::FILLED);
  in.eye_bgr = {eye, eye};
  in.depth_mm = cv::Mat1w(480, 640, std::uint16_t{3000});
  return in;
}

// The green dot's mean column in an eye image, -1 when hardly any of it shows.
inline double green_x(const cv::Mat3b& img) {
  double sum = 0.0;
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (img(y, x)[1] > 150 && img(y, x)[0] < 80 && img(y, x)[2] < 80) {
        sum += x;
        ++n;
      }
  return n > 50 ? sum / n : -1.0;
}

}  // namespace telex::local::test
