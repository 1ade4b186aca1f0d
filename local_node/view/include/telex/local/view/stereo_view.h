// SPDX-License-Identifier: MIT
// The operator's stereo view (--view png:DIR writes left.png, right.png, sbs.png, and fig7.png
// with --view-layout fig7): each eye's camera image, the remote depth registered to that eye
// hiding the virtual body where the remote scene is nearer, the arm and hand as one smooth shaded
// body with their contact shadows, fingertips in contact coloured by pressure with their force
// arrows in 3D, and the normal-map inset and status text as an overlay that fits.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>

#include "telex/common/rig.h"
#include "telex/haptics/body.h"
#include "telex/haptics/haptic_model.h"
#include "telex/local/inputs/tracker.h"
#include "telex/local/view/pinhole.h"
#include "telex/local/view/stereo_renderer.h"
#include "telex/local/view/warp.h"

namespace telex::local {

struct StereoViewInputs {
  std::array<cv::Mat3b, 2> eye_bgr;  // by Side (left 0, right 1); an empty one: the other eye's
  // The remote depth, registered to the right eye. A frame is not changed in place once drawn: the
  // view keys the work it does once per depth frame on its buffer.
  cv::Mat1w depth_mm;
  Intrinsics k;  // the depth's: the right eye's camera at the depth's size
  // Each eye's image size (--eye-size); empty: the eye video's size when video came, else the
  // depth's. The eyes see the depth's camera through eye_intrinsics(k, eye_size).
  cv::Size eye_size;
  double baseline_m = 0.065;  // the left eye sits this far to the right eye's left
  HandState hand;             // camera (right eye) frame
  // The tick re-expressed in the camera (reexpress): there the Model frame is the Camera.
  std::array<FingertipForce, kFingerCount> forces{};
  const Surface* surface = nullptr;  // for the normal-map inset; may be null
  std::string status;
  double arrow_m_per_N = 0.02;        // force arrow length in the scene per newton
  cv::Vec3b skin_bgr{150, 175, 225};  // the body's colour (the rig's operator.skin_rgb)
  bool fig7 = false;                  // also compose Fig. 7 (--view-layout fig7)
  bool overlays = true;  // the status band and the normal-map inset on each eye (--view-overlays)
  // Where the operator's shoulders sit in the camera (right eye) frame, by Side, when the tracker
  // has no shoulder body: 30 cm below and 10 cm behind the eyes, the right one 20 cm right of the
  // right eye, the left one as far left of the left eye (the eyes 64 mm apart).
  std::array<glm::dvec3, 2> default_shoulder_camera{glm::dvec3{-0.264, 0.30, -0.10},
                                                    glm::dvec3{0.20, 0.30, -0.10}};
  // The warp (--warp on, telex/local/view/warp.h): the right eye camera's orientation in the head
  // base's frame when the depth was captured (the robot head's joints the remote measured with
  // that frame), and now (the operator's head, the frame `hand` is in). Both set: each eye's video
  // and depth are reprojected to the operator's pose before the body is drawn over them.
  std::optional<glm::dmat3> R_BaseDepth, R_BaseDisplay;
  // The same when the eye pair was captured (the joints in the pair's header): the video is
  // turned from there, the depth brought into it from R_BaseDepth. Unset (a pair without a head
  // pose): the video is taken to have been captured at R_BaseDepth.
  std::optional<glm::dmat3> R_BaseVideo;
  // By Side: the pinhole each eye is drawn in instead of the eye camera's (a headset's field of
  // view for that eye at its swapchain's size, pinhole_from_fov), both of one size, the eyes'
  // axes turned by R_CameraDisplay (eye_size is then unused). The video and depth keep their true
  // angular positions in it, resampled, never stretched; outside the camera's field the eye shows
  // kOutsideCameraBgr and has no depth.
  std::array<std::optional<Intrinsics>, 2> display_k;
  // By Side: each eye's display orientation in the camera (right eye) frame, a direction d_Display
  // of that eye being R_CameraDisplay d_Display: a headset's located view in its head, the head's
  // axes the camera's (a canted display, Pimax, Index, Varjo, turns each eye outward about y). The
  // video and depth are resampled through it (a homography; the depth's z along the turned axis)
  // and the body is drawn in the turned eye, so the remote world and the body stay where they are.
  // Identity (the default): the eyes' axes are the cameras', the images exactly as without it.
  std::array<glm::dmat3, 2> R_CameraDisplay{glm::dmat3(1.0), glm::dmat3(1.0)};
};

// What an eye shows where its display sees beyond the camera's field (display_k).
inline const cv::Scalar kOutsideCameraBgr{70, 70, 70};

struct StereoViewImages {
  cv::Mat3b left, right, sbs;
  cv::Mat3b fig7;        // with StereoViewInputs::fig7: the right eye beside the normal map
  bool one_eye = false;  // only one eye's image came: it was used for both
  bool warped = false;   // the eyes were reprojected to the operator's pose
  // The frame counter stamped in the video drawn (a synthetic eye's, telex/video/frame_counter.h;
  // the right eye's, or the only eye's), read before it was painted over: the pictures never
  // show it. None for a camera's video.
  std::optional<std::uint32_t> frame_counter;
  // The full-frame normals shown (display_normals, fig7_view.h), the depth's size; empty without a
  // depth of the surface's size. May view the surface's own buffer: valid while it is held.
  cv::Mat3f normals;
};

// One eye's video brought into the view's pinhole camera: undistorted with that eye's intrinsics
// and distortion (scaled to the image's size when the video was resized) and, for the left eye,
// rotated into the right eye's orientation (rectified), resampled to `target`'s size. The maps are
// built once per (image size, target) and reused.
class EyeRectifier {
 public:
  EyeRectifier(CameraModel camera, const glm::dmat3& R_TargetEye);
  // R_DisplayTarget: `target`'s camera turned from the rectified eye's (p_Display =
  // R_DisplayTarget p_Target; a canted display eye), folded into the same map.
  cv::Mat3b apply(const cv::Mat3b& image, const Intrinsics& target, const cv::Scalar& border = {},
                  const glm::dmat3& R_DisplayTarget = glm::dmat3(1.0));

 private:
  CameraModel camera_;
  glm::dmat3 R_TargetEye_;
  cv::Size for_size_;
  Intrinsics for_target_;
  glm::dmat3 for_R_DisplayTarget_{1.0};
  cv::Mat map1_, map2_;
};

// Owns the renderer (created at the first frame's size on the calling thread, which must be the
// one every later call comes from) and the body's swivel history.
class StereoView {
 public:
  // The body's segment lengths and wrist-axis rule from `dims` (the rig's operator.body).
  explicit StereoView(const BodyDims& dims = {});
  // Creates the renderer now, for eyes of this size (a later frame of another size makes a new
  // one): a machine without EGL fails here with the renderer's error.
  StereoView(int width, int height, const BodyDims& dims = {});
  ~StereoView();
  // Both eyes, composed with the overlay. With `late_video` the video is late-latched: the body
  // is drawn first (lit by in.eye_bgr), then `late_video` may replace the inputs' video (eye_bgr,
  // R_BaseVideo, status) with a newer pair, and the eyes are composed from that: the video shown
  // waits for no body. The same images as without it when it changes nothing.
  using LateVideo = std::function<void(StereoViewInputs&)>;
  StereoViewImages render(const StereoViewInputs& in, const LateVideo& late_video = {});
  // Renderers are made in the OpenGL context current on this thread from now on (an OpenXR
  // session's), not in one of their own.
  void use_current_context() { current_context_ = true; }
  // The pair drawn straight into two GL textures of that context (the headset's swapchain
  // images, by Side), each scaled to its size: no read-back, and no overlay (the text and inset
  // belong to the monitor's picture, not in front of the operator's eyes).
  struct GlTarget {
    unsigned texture = 0;
    int width = 0, height = 0;
  };
  void render_into(const StereoViewInputs& in, const std::array<GlTarget, 2>& targets,
                   const LateVideo& late_video = {});
  // The eyes' calibration (the rig's eyes.*; absent = drawn as they come) and the left eye's
  // rotation into the right's (p_right = R p_left).
  void set_eye_cameras(const std::array<std::optional<CameraModel>, 2>& eyes,
                       const glm::dmat3& R_RightEyeLeftEye);

 private:
  // Each eye's video and depth at the display pose, by Side, when the inputs carry both poses.
  void warp_eyes(const StereoViewInputs& in, std::array<EyeView*, 2> eyes);
  // Both eyes' views (left, right) prepared and their body layers drawn, the video late-latched
  // with `late_video` (see render); `late`: the inputs the eyes are then composed from. Returns
  // whether only one eye's video came. The steps below: the eyes' pinholes, centres, fingertips
  // and the capsules (and the renderer made for in.k's size); the remote depth in each eye; the
  // video in each eye (and the warp).
  bool draw_bodies(const StereoViewInputs& early, const LateVideo& late_video,
                   StereoViewInputs& late, std::array<EyeView, 2>& views);
  void prepare_geometry(const StereoViewInputs& in, std::array<EyeView, 2>& eyes,
                        std::vector<Capsule>& capsules);
  void prepare_depth(const StereoViewInputs& in, std::array<EyeView, 2>& eyes);
  bool prepare_video(const StereoViewInputs& in, std::array<EyeView, 2>& eyes);
  // The eyes' video with any frame counter painted over (copies where one was), the counter kept
  // in frame_counter_.
  std::array<cv::Mat3b, 2> without_frame_counters(const std::array<cv::Mat3b, 2>& eyes);
  // The normal-map inset for eyes of `size` and the full-frame normals it shows (`normals`), made
  // once per depth frame and surface.
  const cv::Mat3b& normal_inset_for(const StereoViewInputs& in, cv::Mat3f& normals, cv::Size size);

  std::array<std::optional<EyeRectifier>, 2> rectifier_;
  bool current_context_ = false;
  std::unique_ptr<StereoRenderer> renderer_;
  // On the renderer's context, made at the first warped frame; they go before the renderer does.
  std::array<std::unique_ptr<DepthWarp>, 2> warp_;
  std::optional<glm::dmat3> R_BasePreviousDisplay_;
  // What the last frame's prepare_geometry and prepare_video chose: the eyes' pinhole camera,
  // and whether it warped.
  Intrinsics k_eye_;
  std::array<Intrinsics, 2> k_drawn_;  // each eye's pinhole, by Side
  cv::Scalar outside_;                 // what an eye shows beyond the camera's field
  bool warped_ = false;
  std::optional<std::uint32_t> frame_counter_;  // the last prepare_video's, see StereoViewImages
  // What prepare_depth made of the last depth frame, and from what: the depth (held, so its
  // buffer stays its own) and the cameras.
  struct EyeDepths {
    cv::Mat1w source;
    Intrinsics k;
    double baseline_m = 0.0;
    std::array<glm::dmat3, 2> R_CameraDisplay{};
    std::array<Intrinsics, 2> eye_k;  // right, left
    cv::Mat1w right, left;
  } eye_depths_;
  // The same for the normal-map inset.
  struct InsetWork {
    cv::Mat1w depth;
    const Surface* surface = nullptr;
    Intrinsics k;
    cv::Size size;
    cv::Mat3f normals;
    cv::Mat3b inset;
  } inset_;
  cv::Size renderer_size_;
  Body body_;
};

// Index of the capture time in `captures` nearest to `want_ns` (the first of equals); nullopt
// for none. The view pairs each eye's video with the depth frame it draws over this way.
std::optional<std::size_t> nearest_capture(std::span<const std::int64_t> captures,
                                           std::int64_t want_ns);

// The arm and hand of `hand` (camera frame) and the fingertips' contact and force capsules.
std::vector<Capsule> view_capsules(Body& body, const StereoViewInputs& in);

// The tracked fingertips of both hands in the camera (right eye) frame: the contact shadows'
// casters.
std::vector<glm::dvec3> view_fingertips(const HandState& hand);

}  // namespace telex::local
