// SPDX-License-Identifier: MIT
// What one eye is drawn from (EyeView: its camera, its picture and depth, the fingertips) and the
// body's capsules: the types the renderer and its passes (the body pass, the warp) share.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <opencv2/core.hpp>
#include <vector>

#include "telex/common/depth_image.h"

namespace telex::local {

// The view's depth range (near and far planes), metres: every pass draws within it.
inline constexpr double kViewNear_m = 0.05, kViewFar_m = 20.0;

// A segment with round ends (two spheres joined by a cylinder, or a cone tangent to both when the
// radii differ), in the right eye's camera frame (x right, y down, z forward, metres). a == b
// draws a sphere. Lit capsules that share an end (within 1 mm) blend into one smooth surface.
struct Capsule {
  glm::dvec3 a{0.0}, b{0.0};
  double radius_m = 0.01;  // at a
  cv::Vec3b bgr{180, 200, 230};
  // Skin, lit as the scene (the eye image's brightness); false: a marker in its own colour.
  bool lit = true;
  double radius_b_m = -1.0;  // at b; negative: radius_m
};

struct EyeView {
  Intrinsics k;
  // This eye's centre in the right eye's camera frame (the right eye: 0; a left eye a baseline B
  // to its left: (-B, 0, 0)).
  glm::dvec3 p_RightEye{0.0};
  // This eye's orientation: a point p_Right of the right eye's frame is p_Eye = R_EyeRight
  // (p_Right - p_RightEye) in the frame `k`, `background` and `depth_mm` are in. Identity: the
  // eyes' axes are the cameras' (a rectified pair); a headset's canted display eye turns them.
  // The skin's key light stays fixed in the eye's frame.
  glm::dmat3 R_EyeRight{1.0};
  cv::Mat3b background;  // BGR, k's size; empty: dark grey
  // Non-zero: the eye image is this GL_TEXTURE_2D of the renderer's context instead (RGBA8 with
  // rgb as uploaded from BGR, rows top-down, k's size; e.g. DepthWarp's WarpedEye::texture),
  // copied on the GPU; `background` then only sets the skin's exposure (empty: 1).
  std::uint32_t background_texture = 0;
  cv::Mat1w depth_mm;  // the remote depth registered to this eye, k's size; 0 or empty: no data
  // Fingertips in the right eye's frame: each darkens the remote surface near it (a soft contact
  // shadow, 5 cm reach).
  std::vector<glm::dvec3> fingertips;
  // false: the picture stays in the renderer's framebuffer (for blit_to) and render() returns an
  // empty image.
  bool read_back = true;
};

}  // namespace telex::local
