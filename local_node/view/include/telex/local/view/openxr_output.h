// SPDX-License-Identifier: MIT
// --view openxr: the stereo pair to a headset through the OpenXR loader (Debian's libopenxr-dev;
// the runtime is the active one, or the manifest XR_RUNTIME_JSON names). One swapchain per eye
// at the runtime's recommended size, frames paced by xrWaitFrame and submitted with its predicted
// display time, each eye's pose from xrLocateViews, the session's state followed.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <string>
#include <vector>

#include "telex/common/depth_image.h"
#include "telex/local/view/gl_contexts.h"

namespace telex::local {

// An eye image's edges' angles from the eye's axis (OpenXR's XrFovf: left and down negative).
struct XrEyeFov {
  double angle_left_rad = 0, angle_right_rad = 0, angle_up_rad = 0, angle_down_rad = 0;
};

// One eye's swapchain image, a GL texture of the session's context (rows bottom-up, as GL's), and
// the field of view and pose xrLocateViews gave that eye for the frame's display time: the image
// is drawn with them (pinhole_from_fov, R_HeadEye) and submitted with them.
struct XrEyeTarget {
  unsigned texture = 0;
  int width = 0, height = 0;
  XrEyeFov fov;
  // The eye's orientation in the head (XR's VIEW space), in the camera convention (x right, y
  // down, z forward) for both: a direction d_Eye of the eye is R_HeadEye d_Eye in the head.
  // Identity for parallel eyes; a canted display (Pimax, Index, Varjo) turns each eye outward.
  glm::dmat3 R_HeadEye{1.0};
};

// The headset (XR's VIEW space) in the STAGE space (or LOCAL where there is no stage): OpenXR's
// axes, x right, y up, z backwards, metres.
struct XrHeadPose {
  bool valid = false;
  std::int64_t display_time_ns = 0;  // XrTime (CLOCK_MONOTONIC on Linux runtimes)
  // When the runtime was asked for it (CLOCK_MONOTONIC): its sample, predicted to display time.
  std::int64_t located_ns = 0;
  glm::dquat q_StageHead{1.0, 0.0, 0.0, 0.0};
  glm::dvec3 p_StageHead_m{0.0};
};

class OpenXrOutput {
 public:
  enum class Binding { Egl, Xlib };
  // What the session is doing, as the station needs it.
  enum class Phase { Starting, Running, Focused, Ended };

  // Loads the runtime, creates the instance (XR_KHR_opengl_enable, and XR_MNDX_egl_enable when
  // offered) and finds the headset. Throws std::runtime_error naming the runtime manifest (or
  // its absence) and what failed.
  OpenXrOutput();
  ~OpenXrOutput();
  OpenXrOutput(const OpenXrOutput&) = delete;
  OpenXrOutput& operator=(const OpenXrOutput&) = delete;

  Binding binding() const { return binding_; }
  const std::string& runtime_name() const { return runtime_name_; }
  // The session bound to the context current on this thread, its spaces and swapchains.
  void start(const EglHandles& egl);
  void start(const GlxHandles& glx);

  // One pass: the runtime's events, then, while the session runs, one frame. `draw` fills both
  // eyes' targets, each with its target's field of view (submitted with it); returning false
  // submits no layer. Never throws: a failing call ends the session (end_reason says which).
  using Draw = std::function<bool(const std::array<XrEyeTarget, 2>&)>;
  Phase step(const Draw& draw);
  // Asks the runtime to end the session (the station stops); step() until Phase::Ended.
  void request_exit();
  // Called from step() at each change of phase, as soon as the event is taken (the station gates
  // the haptic output on it).
  void on_phase(std::function<void(Phase)> f) { on_phase_ = std::move(f); }
  const std::string& end_reason() const { return end_reason_; }
  XrHeadPose head() const { return head_; }
  std::uint64_t frames_submitted() const { return frames_submitted_; }
  std::array<int, 2> eye_size() const { return {recommended_w_, recommended_h_}; }

 private:
  struct Xr;
  void create_session(const void* binding);
  void handle_events();
  void frame(const Draw& draw);
  void end(const std::string& why);
  void set_phase(Phase p);

  std::unique_ptr<Xr> xr_;
  Binding binding_ = Binding::Egl;
  bool egl_under_validation_ = false;  // the EGL binding with the core validation layer on
  std::string runtime_name_;
  std::string end_reason_;
  Phase phase_ = Phase::Starting;
  int recommended_w_ = 0, recommended_h_ = 0;
  XrHeadPose head_;
  std::uint64_t frames_submitted_ = 0;
  bool exit_requested_ = false;
  std::function<void(Phase)> on_phase_;
};

// With Khronos' core validation layer enabled (XR_ENABLE_API_LAYERS) and no file named for it,
// its text goes to stderr (XR_CORE_VALIDATION_FILE_NAME=/dev/stderr), so stdout keeps
// --json-summary alone. Call before any thread starts: it sets the environment.
void prepare_openxr_environment();

// Which runtime the loader will load, for messages: "XR_RUNTIME_JSON=PATH", else the active
// runtime's manifest where the loader looks for it (the XDG config directories). Throws
// std::runtime_error, saying what to do, when XR_RUNTIME_JSON names no file or none is installed.
std::string openxr_runtime_manifest();

// The pinhole camera (OpenCV's convention: y down, pixel centres at integers) of a `width` x
// `height` image spanning `fov`, as OpenXR's projection maps it: the eye's axis through the image
// where the angles put it, off centre for a canted fov. The image's edges are half a pixel beyond
// the outer pixels' centres.
Intrinsics pinhole_from_fov(const XrEyeFov& fov, int width, int height);

// The rotation q_AB between two frames of OpenXR's axes (x right, y up, z backwards) as the same
// rotation between the frames of the camera convention (x right, y down, z forward) on each:
// C R(q_AB) C with C = diag(1, -1, -1).
glm::dmat3 camera_rotation_from_openxr(const glm::dquat& q_AB);

}  // namespace telex::local
