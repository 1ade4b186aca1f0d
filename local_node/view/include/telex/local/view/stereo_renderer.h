// SPDX-License-Identifier: MIT
// The operator's stereo view, one eye at a time: that eye's camera image as the background,
// fingertips' contact shadows on the remote depth registered to that eye, and the virtual body
// drawn as triangles (each capsule an instance of one mesh) into a target of its own and
// composited where it is nearer than the remote depth, so the real scene hides it. OpenGL 3.3 core
// through libepoxy, on a headless EGL context (Mesa's llvmpipe runs it with no display and no GPU).
#pragma once

#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "telex/common/depth_image.h"
#include "telex/haptics/body.h"
#include "telex/local/view/body_shape.h"
#include "telex/local/view/eye_view.h"

namespace telex::local {

class StereoRenderer {
 public:
  // Creates the headless EGL context and the GL objects for `width` x `height` eyes. Throws
  // std::runtime_error naming what is missing (no EGL display, no OpenGL 3.3 core context).
  StereoRenderer(int width, int height);
  // Draws in the OpenGL context current on the calling thread (an OpenXR session's, which the
  // caller owns) instead of making one; the destructor deletes only the renderer's objects.
  struct UseCurrentContext {};
  StereoRenderer(int width, int height, UseCurrentContext);
  ~StereoRenderer();
  StereoRenderer(const StereoRenderer&) = delete;
  StereoRenderer& operator=(const StereoRenderer&) = delete;

  // One eye: background, depth, contact shadows, then the body with depth test; the skin's light
  // follows the background's brightness. BGR, top row first. The
  // calling thread must be the one that constructed the renderer (the context is current there).
  cv::Mat3b render(const EyeView& eye, std::span<const Capsule> capsules);

  // render() in two steps, so that an eye's picture can be taken after the body is drawn (the
  // video late-latched, StereoView::render's `late_video`): draw_body_layer marches the body for
  // `eye`'s pinhole and centre (its k and p_RightEye; the images are not read) into `slot`'s own
  // target (0 or 1, one per eye), lit with `exposure` (exposure_from_image of the eye's picture);
  // compose then draws `eye` as render() does, with that slot's body. The same eye's k and
  // p_RightEye in both.
  void draw_body_layer(int slot, const EyeView& eye, std::span<const Capsule> capsules,
                       float exposure);
  cv::Mat3b compose(int slot, const EyeView& eye);
  // Waits until the GL work asked for so far is done (llvmpipe draws only when something is
  // read or waited for): the body layers are drawn before the video is taken.
  void finish();

  // The last eye drawn, copied on the GPU into `texture` (a GL_TEXTURE_2D of this context, e.g.
  // an OpenXR swapchain image), scaled to width x height and flipped to GL's bottom-up rows.
  void blit_to(unsigned texture, int width, int height);

  // The body is drawn at 1/divisor of the eye's resolution and composited over the eye with the
  // remote depth tested at every eye pixel. 0 (the default): the mesh at the eye's own size; the
  // march at the eye's width over 640, rounded down (a 1280x720 eye marches the body at 640x360).
  // Throws std::invalid_argument outside 0..8.
  void set_body_divisor(int divisor);
  void set_body_shape(BodyShape shape);  // BodyShape::Mesh unless set
  // While on, each body layer counts its fragments (GL queries read at once, a stall: for the
  // benchmark); body_fragments() is the last layer's count.
  void set_count_body_fragments(bool on);
  BodyFragments body_fragments() const;

  std::string gl_renderer() const;  // e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The visible arms and hands of `body` as capsules in the right eye's frame: upper arm and
// forearm tapering to the wrist, the palm as a fan of capsules from the wrist to the knuckles,
// three tapering phalanges per finger and a slightly fuller ball at each finger joint (the
// knuckles). `to_right_eye` maps a world point into the right eye's camera frame.
std::vector<Capsule> body_capsules(const BodyState& body,
                                   const std::function<glm::dvec3(const glm::dvec3&)>& to_right_eye,
                                   cv::Vec3b skin_bgr = {150, 175, 225});

// The eye image's brightness as a gain for the skin: its mean luma over 118 (a mid-grey
// picture lights the skin as designed), clamped to [0.3, 1.5]; 1 with no image.
float exposure_from_image(const cv::Mat3b& bgr);

// Clip-space projection of a pinhole camera (x right, y down, z forward) so that a point lands
// on the pixel centre OpenCV's convention gives it, u = fx x/z + cx, v = fy y/z + cy, with GL's
// window row v (rows run top-down in the renderer's buffers, as in an image). Column-major.
glm::mat4 projection_from_intrinsics(const Intrinsics& k, double near_m, double far_m);

}  // namespace telex::local
