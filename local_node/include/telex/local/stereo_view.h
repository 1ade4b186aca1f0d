// SPDX-License-Identifier: MIT
// The operator's stereo view (--view png:DIR writes left.png, right.png, sbs.png): each eye's
// camera image, the remote depth registered to that eye hiding the virtual body where the remote
// scene is nearer, the arm and hand as shaded capsules, fingertips in contact coloured by pressure
// with their force arrows in 3D, and the normal-map inset and status text as an overlay that fits.
#pragma once

#include <array>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>

#include "telex/common/body.h"
#include "telex/common/haptic_model.h"
#include "telex/local/stereo_renderer.h"
#include "telex/local/tracker.h"

namespace telex::local {

struct StereoViewInputs {
  std::array<cv::Mat3b, 2> eye_bgr;  // by Side (left 0, right 1); an empty one: the other eye's
  cv::Mat1w depth_mm;                // the remote depth, registered to the right eye
  Intrinsics k;                      // the right eye's (and, rectified, the left eye's)
  double baseline_m = 0.065;         // the left eye sits this far to the right eye's left
  HandState hand;                    // camera (right eye) frame
  std::array<FingertipForce, kFingerCount> forces{};
  const Surface* surface = nullptr;  // for the normal-map inset; may be null
  std::string status;
  double arrow_m_per_N = 0.02;  // force arrow length in the scene per newton
  // Where the operator's right shoulder sits in the camera frame when the tracker has no shoulder
  // body (scripted hands): 20 cm right of, 30 cm below and 10 cm behind the eyes.
  glm::dvec3 default_shoulder_camera{0.20, 0.30, -0.10};
};

struct StereoViewImages {
  cv::Mat3b left, right, sbs;
  bool one_eye = false;  // only one eye's image came: it was used for both
};

// Owns the renderer (created at the first frame's size on the calling thread, which must be the
// one every later call comes from) and the body's swivel history.
class StereoView {
 public:
  StereoView();
  // Creates the renderer now, for eyes of this size (a later frame of another size makes a new
  // one): a machine without EGL fails here with the renderer's error.
  StereoView(int width, int height);
  ~StereoView();
  StereoViewImages render(const StereoViewInputs& in);

 private:
  std::unique_ptr<StereoRenderer> renderer_;
  cv::Size renderer_size_;
  Body body_;
};

// Index of the capture time in `captures` nearest to `want_ns` (the first of equals); nullopt
// for none. The view pairs each eye's video with the depth frame it draws over this way.
std::optional<std::size_t> nearest_capture(std::span<const std::int64_t> captures,
                                           std::int64_t want_ns);

// The arm and hand of `hand` (camera frame) and the fingertips' contact and force capsules.
std::vector<Capsule> view_capsules(Body& body, const StereoViewInputs& in);

}  // namespace telex::local
