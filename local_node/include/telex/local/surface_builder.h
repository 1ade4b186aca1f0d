// SPDX-License-Identifier: MIT
// Turns an assembled depth frame into the haptic loop's surface snapshot: bilateral smoothing and
// normals, over the whole frame or only in windows around the fingertips.
#pragma once

#include <memory>
#include <span>
#include <vector>

#include "telex/common/bilateral.h"
#include "telex/common/haptic_surface.h"
#include "telex/common/normals.h"
#include "telex/local/frame_assembler.h"
#include "telex/local/tracker.h"

namespace telex::local {

struct SurfaceOptions {
  bool bilateral = true;
  BilateralOptions bilateral_options{};
  NormalOptions normal_options{};
  // Region of interest: filter and build normals only near the fingertips. Elsewhere the surface
  // keeps the raw depth and no normals (the model then fits a local plane if ever needed).
  bool roi = false;
  double roi_radius_m = 0.04;        // around each fingertip, at its depth
  double roi_lookahead_s = 0.1;      // plus the distance the fingertip may travel in this time
  int roi_min_half_px = 16;
  double roi_max_distance_m = 0.25;  // fingertips farther than this from the surface need nothing
};

// Windows (in pixels, clipped to the image) that the fingertips may touch before the next frame.
// Empty when no tracked fingertip is within roi_max_distance_m of the surface.
std::vector<cv::Rect> fingertip_windows(const HandState& hand, const cv::Mat1w& depth_mm,
                                        const Intrinsics& k, const SurfaceOptions& options);

struct SurfaceBuildStats {
  double filter_ms = 0;
  double normals_ms = 0;
  std::size_t pixels_processed = 0;  // pixels filtered (== pixels with normals computed)
};

// Builds the snapshot. With options.roi, only `windows` are filtered and get normals.
std::shared_ptr<Surface> build_surface(const AssembledFrame& frame, const SurfaceOptions& options,
                                       std::span<const cv::Rect> windows,
                                       SurfaceBuildStats* stats = nullptr);

}  // namespace telex::local
