// SPDX-License-Identifier: MIT
// The stereo renderer's body pass: the capsules as one smooth body (each capsule's signed distance
// joined to those it shares an end with by a smooth minimum, sphere-traced inside a box around
// it), lit to the eye image's brightness, and the contact shadows fingertips cast on the remote
// scene. Internal to the renderer: it needs the renderer's current GL context.
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <memory>
#include <span>
#include <vector>

#include "telex/local/stereo_renderer.h"

namespace telex::local {

// Which capsules blend with which: each capsule's neighbours are the ones that share an end
// (within 1 mm) with it, at most kMaxBlendNeighbours, in input order. The chain of a finger, the
// palm's fan from the wrist and the arm join up; neighbouring fingers do not touch ends, so they
// stay apart.
inline constexpr std::size_t kMaxBlendNeighbours = 8;
std::vector<std::array<std::int32_t, kMaxBlendNeighbours>> blend_neighbours(
    std::span<const Capsule> capsules);

// The eye image's brightness as a gain for the skin: its mean luma over 118 (a mid-grey
// picture lights the skin as designed), clamped to [0.3, 1.5]; 1 with no image.
float exposure_from_image(const cv::Mat3b& bgr);

class BodyPass {
 public:
  BodyPass();  // compiles the shaders; the GL context must be current
  ~BodyPass();
  BodyPass(const BodyPass&) = delete;
  BodyPass& operator=(const BodyPass&) = delete;

  // Darkens the framebuffer's colour where the remote surface lies near a fingertip.
  // `window_depth` is the eye's depth buffer content (window depths, rows top-down).
  void draw_contact_shadows(const Intrinsics& k, const glm::dvec3& p_RightEye,
                            std::span<const glm::dvec3> fingertips, const cv::Mat1f& window_depth);
  // The body into the bound framebuffer, depth-tested against what it holds.
  void draw_body(const glm::mat4& projection, const glm::dvec3& p_RightEye,
                 std::span<const Capsule> capsules, float exposure);

  static constexpr std::size_t kMaxCapsules = 256;  // more are not drawn

 private:
  struct Gl;
  std::unique_ptr<Gl> gl_;
};

}  // namespace telex::local
