// SPDX-License-Identifier: MIT
// The operator's picture: remote camera (or colourised depth) with the virtual hand, an inset of
// the full-frame normal map with the haptic path's fingertip windows outlined on it, one force
// arrow per fingertip and a status text.
#pragma once

#include <array>
#include <span>
#include <string>
#include <vector>

#include "telex/haptics/haptic_model.h"
#include "telex/local/inputs/tracker.h"

namespace telex::local {

struct ViewInputs {
  cv::Mat3b camera_bgr;              // right-eye image; empty = draw the colourised depth instead
  const Surface* surface = nullptr;  // may be null before the first frame
  cv::Mat1w depth_mm;                // raw depth for the colourised background
  // The inset's normals, the depth's size: display_normals (fig7_view.h), computed by the view;
  // empty: the surface's own. Where they are not the surface's own, the windows the surface has
  // normals in (the haptic path's fingertip windows) are outlined on the inset.
  cv::Mat3f normals;
  HandState hand;
  // The tick re-expressed in the camera (reexpress): there the Model frame is the Camera.
  std::array<FingertipForce, kFingerCount> forces{};
  std::string status;
  double arrow_m_per_N = 0.02;  // force arrow length in the scene per newton
};

// Pure: draws into a new image the size of the camera image (or of the depth).
cv::Mat3b render_operator_view(const ViewInputs& in);

// The normal-map inset, top right of `img`, a quarter of its width at the normals' aspect, with a
// white border: `normals` colourised, `windows` (their pixels) outlined on it. Nothing when empty.
void draw_normal_inset(cv::Mat3b& img, const cv::Mat3f& normals,
                       std::span<const cv::Rect> windows = {});
// The same in two steps, for images of one width drawn later: the inset for an image
// `image_cols` wide (empty when it would not fit `image_rows`), then pasted with its border.
cv::Mat3b normal_inset(const cv::Mat3f& normals, std::span<const cv::Rect> windows, int image_cols,
                       int image_rows);
void paste_normal_inset(cv::Mat3b& img, const cv::Mat3b& inset);
// The windows the haptic path built normals in (the bounding boxes of where `surface`'s normals
// are set), to outline on the full-frame normals `shown`; none when `shown` is the surface's own.
std::vector<cv::Rect> haptic_windows(const Surface* surface, const cv::Mat3f& shown);

// Pixel of a camera-frame point, or nothing behind the camera.
std::optional<cv::Point2d> project(const Intrinsics& k, const glm::dvec3& p_CameraQ);

}  // namespace telex::local
