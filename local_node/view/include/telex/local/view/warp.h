// SPDX-License-Identifier: MIT
// A remote world that stays put: one eye's video reprojected from the pose it was captured at (the
// robot head's) to the operator's eye pose at display time, through a grid mesh built from the
// remote depth registered to that eye (a depth-image-based warp). Triangles across a depth
// discontinuity are dropped, so a disocclusion opens a hole (shaded neutrally) instead of a
// stretched edge; what the capture did not see at all takes the previous warped frame. OpenGL 3.3
// core, drawn on the calling thread's current context (the stereo view's renderer's) or on a
// headless EGL context of its own.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "telex/common/depth_image.h"
#include "telex/common/registration.h"

namespace telex::local {

// What the holes a warp opens are filled with, where no pixel of the capture lands (a pixel the
// capture does land on but whose triangle was dropped at an edge takes that pixel first, and
// where the remote has no depth the video is turned as if far away: it is not a hole).
enum class HoleFill {
  // Outside the capture's view (the border a turn uncovers): the previous warped frame, turned by
  // the display's rotation since. A disocclusion inside the view: neutral, as the previous frame
  // there may hold the occluder's old edge.
  Previous,
  Neutral,  // everywhere WarpOptions::neutral_bgr
};

struct WarpOptions {
  // One mesh vertex per this many pixels each way (1..64). llvmpipe pays per triangle: at
  // 1280x720 a step of 4 cost twice the time of 8 for no error the check could see.
  int grid_step_px = 8;
  // Blocks of merge_cells x merge_cells grid cells without a depth jump or a hole at any of their
  // pixels are drawn as one cell (1..8; 1: every cell on its own), while edges keep the fine grid.
  // llvmpipe pays per triangle: at 1280x720 a block of 4 cut an eye's warp from 28.7 to 21.1 ms
  // CPU with the ground-truth check's error unchanged (0.0136 deg).
  int merge_cells = 4;
  // A triangle is dropped when its corners' depths differ by more than this fraction of the
  // nearest one (a slanted plane 4 px apart changes by a few percent; an occlusion edge by more).
  double max_depth_step_ratio = 0.1;
  HoleFill hole_fill = HoleFill::Previous;
  cv::Vec3b neutral_bgr{96, 96, 96};
  // A hole pixel whose nearest landing capture pixel misses it by at most this many pixels (the
  // sliver an eye's small move off the turn's axis opens along an edge) takes that pixel's colour
  // instead of the neutral one. 0: every hole neutral.
  double sliver_px = 2.0;
  // false: WarpedEye::bgr stays empty and the picture is only in WarpedEye::texture, for a
  // renderer in the same GL context (EyeView::background_texture): no read-back and no upload.
  bool read_back_bgr = true;
};

struct WarpedEye {
  cv::Mat3b bgr;       // the video at the display pose, holes filled; empty: !read_back_bgr
  cv::Mat1w depth_mm;  // the depth at the display pose, registered to it; 0 in holes
  // bgr as a GL texture (RGBA8, rows top-down) in the warp's context, valid until the next warp.
  std::uint32_t texture = 0;
};

class DepthWarp {
 public:
  // For `width` x `height` eyes. Uses the GL context current on this thread, or creates a headless
  // EGL one when there is none. Throws std::runtime_error naming what is missing, and
  // std::invalid_argument for a size out of 1..8192 or options out of range.
  DepthWarp(int width, int height, WarpOptions options = {});
  ~DepthWarp();
  DepthWarp(const DepthWarp&) = delete;
  DepthWarp& operator=(const DepthWarp&) = delete;

  // `eye_bgr` (captured) and `depth_mm` (registered to the same eye, 0 = no data), both k's size,
  // seen from the display pose: p_Display = X_DisplayCapture * p_Capture, same intrinsics k.
  // `R_DisplayPrevious`: the display's rotation since the previous warp, for the hole fill.
  // Call from the thread that constructed the warp.
  WarpedEye warp(const cv::Mat3b& eye_bgr, const cv::Mat1w& depth_mm, const Intrinsics& k,
                 const RigidTransform& X_DisplayCapture,
                 const glm::dmat3& R_DisplayPrevious = glm::dmat3(1.0));
  // The same when the video and the depth were captured at different poses (the eye pair and the
  // depth frame at their own instants while the head turns): the mesh is the depth's, moved by
  // X_DisplayDepth, and each of its points takes the video's colour where the video's camera saw
  // it, p_Video = X_VideoDepth * p_Depth. Where the depth has none, the video is turned as if far
  // away by the rotation between the video's pose and the display's. X_VideoDepth identity is the
  // overload above.
  WarpedEye warp(const cv::Mat3b& video_bgr, const cv::Mat1w& depth_mm, const Intrinsics& k,
                 const RigidTransform& X_DisplayDepth, const RigidTransform& X_VideoDepth,
                 const glm::dmat3& R_DisplayPrevious);
  // Forgets the previous frame: the next warp's holes are neutral.
  void reset_previous();

  const WarpOptions& options() const { return options_; }

 private:
  struct Impl;
  WarpOptions options_;
  std::unique_ptr<Impl> impl_;
};

// The warp's triangles over a depth image: a grid with one vertex per `step` pixels each way
// (vertex (gx, gy) is index gy * columns + gx and samples pixel min(g * step, size - 1)), two
// triangles a cell, a triangle kept only when all its corners have depth and they differ by at
// most max_depth_step_ratio of the nearest. With `merge` > 1, each block of merge x merge cells
// whose every pixel has depth within that ratio of the block's nearest is two triangles over the
// block's corners instead. Pure; `indices` is cleared and refilled.
void mesh_triangles(const cv::Mat1w& depth_mm, int step, double max_depth_step_ratio,
                    std::vector<std::uint32_t>& indices, int merge = 1);

// The rigid transform between an eye's capture and display poses when the head turns about the
// right eye's centre by R_DisplayCapture and the eye sits at p_RightEye (the right eye: 0; a left
// eye a baseline B to its left: (-B, 0, 0)).
RigidTransform eye_display_from_capture(const glm::dmat3& R_DisplayCapture,
                                        const glm::dvec3& p_RightEye);

}  // namespace telex::local
