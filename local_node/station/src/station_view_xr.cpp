// SPDX-License-Identifier: MIT
// --view openxr on the view thread: the headset's session and frame loop, the stereo pair drawn
// into its swapchain images, the haptic output gated on its focus, its pose for --head-source hmd.
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>

#include <glm/gtc/quaternion.hpp>

#include "station_view.h"
#include "telex/base/periodic.h"
#include "telex/local/view/openxr_output.h"

namespace telex::local {
namespace {

// Frames the session gets to reach STOPPING after the station asked it to exit.
constexpr int kExitSteps = 300;

}  // namespace

void StationView::set_gate(bool open) {
  std::lock_guard lock(xr_mu_);
  auto& windows = xr_stats_.gate_closed_ns;
  if (open) {
    if (!windows.empty() && windows.back().second == 0) windows.back().second = monotonic_ns();
    gate_.open();
  } else {
    gate_.close();
    if (windows.empty() || windows.back().second != 0) windows.emplace_back(monotonic_ns(), 0);
  }
}

std::function<bool(Pose&, std::int64_t&)> StationView::hmd_head_source() {
  return [this, have = false, last = HmdSample{}](Pose& out, std::int64_t& located_ns) mutable {
    if (hmd_head_.take(last)) have = true;
    out = last.X_NatNetHead;
    located_ns = last.located_ns;
    return have;
  };
}

StationView::XrStats StationView::xr_stats() const {
  std::lock_guard lock(xr_mu_);
  return xr_stats_;
}

void StationView::run_openxr(std::stop_token stop) {
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 5);  // as run_stereo, and for its reason
  // Destroyed in reverse: the view's GL objects and the session's swapchains while their
  // context is still there.
  struct Parts {
    std::unique_ptr<EglContext> egl;
    std::unique_ptr<GlxContext> glx;
    std::unique_ptr<OpenXrOutput> xr;
    std::unique_ptr<StereoView> view;
  } p;
  set_gate(false);  // the gate starts closed: record it as a window from the start
  try {
    p.xr = std::make_unique<OpenXrOutput>();
    if (p.xr->binding() == OpenXrOutput::Binding::Egl) {
      p.egl = std::make_unique<EglContext>();
      p.xr->start(p.egl->handles());
    } else {
      p.glx = std::make_unique<GlxContext>();
      p.xr->start(p.glx->handles());
    }
    {
      std::lock_guard lock(xr_mu_);
      xr_stats_.runtime = p.xr->runtime_name();
      xr_stats_.eye_width = p.xr->eye_size()[0];
      xr_stats_.eye_height = p.xr->eye_size()[1];
    }
    p.xr->on_phase(
        [this](OpenXrOutput::Phase phase) { set_gate(phase == OpenXrOutput::Phase::Focused); });
    p.view = std::make_unique<StereoView>(cfg_.body);
    p.view->use_current_context();
    p.view->set_eye_cameras(cfg_.eye_camera, cfg_.R_RightEyeLeftEye);
    PhotonStamps drawn_stamps;  // of the frame step() drew, if it drew one
    bool drew = false;
    const auto draw = [this, &p, &drawn_stamps, &drew](const std::array<XrEyeTarget, 2>& t) {
      StereoViewInputs in;
      {
        std::lock_guard lock(stereo_mu_);  // the newest request, drawn at the headset's rate
        in.hand = stereo_request_.hand;
        in.forces = stereo_request_.forces;
        in.status = stereo_request_.status;
      }
      if (!stereo_inputs(in, /*late_pair=*/true)) return false;
      // Each eye drawn in the headset's field of view for it at its swapchain's size and turned
      // as it is in the head (the head's axes the camera's), the video and depth placed in it at
      // their true angles.
      for (std::size_t eye = 0; eye < 2; ++eye) {
        in.display_k[eye] = pinhole_from_fov(t[eye].fov, t[eye].width, t[eye].height);
        in.R_CameraDisplay[eye] = t[eye].R_HeadEye;
      }
      // The video late-latched, as in the window: the newest pair, taken once the body is drawn
      // (without waiting for the next: the runtime paces the frames).
      p.view->render_into(in,
                          {StereoView::GlTarget{t[0].texture, t[0].width, t[0].height},
                           StereoView::GlTarget{t[1].texture, t[1].width, t[1].height}},
                          [this](StereoViewInputs& l) { take_pair(l, 0); });
      drawn_stamps = photon_stamps(in);
      drew = true;
      return true;
    };
    const RigidTransform& X_NatNetStage = cfg_.X_NatNetStage;
    const glm::dquat q_NatNetStage = glm::quat_cast(X_NatNetStage.rotation);
    const bool record_poses = !cfg_.record_hmd_poses_csv.empty();
    std::int64_t last_display_ns = 0;
    int exit_steps = 0;
    for (;;) {
      drew = false;
      const OpenXrOutput::Phase phase = p.xr->step(draw);
      // step() returns right after xrEndFrame: a frame it drew is submitted now.
      if (drew && phase != OpenXrOutput::Phase::Ended) photon_now(drawn_stamps);
      if (phase == OpenXrOutput::Phase::Ended) break;
      const XrHeadPose h = p.xr->head();
      if (h.valid && record_poses && h.display_time_ns != last_display_ns) {
        last_display_ns = h.display_time_ns;
        stage_poses_.push({h.display_time_ns, Pose{h.p_StageHead_m, h.q_StageHead}});
      }
      if (h.valid)
        hmd_head_.publish(
            {Pose{X_NatNetStage.rotation * h.p_StageHead_m + X_NatNetStage.translation_m,
                  glm::normalize(q_NatNetStage * h.q_StageHead)},
             h.located_ns});
      if (stop.stop_requested()) {
        p.xr->request_exit();
        if (++exit_steps > kExitSteps) break;  // the runtime never stopped: destroyed anyway
      }
    }
    std::lock_guard lock(xr_mu_);
    xr_stats_.frames_submitted = p.xr->frames_submitted();
    xr_stats_.end_reason = p.xr->end_reason().empty() ? "the station stopped" : p.xr->end_reason();
  } catch (...) {
    set_gate(false);
    faults_.fail("view (openxr)", std::current_exception());
    return;
  }
  set_gate(false);
  const XrStats s = xr_stats();
  spdlog::info("openxr view: {} frames submitted; the session ended: {}", s.frames_submitted,
               s.end_reason);
  if (!stop.stop_requested()) xr_ended_.store(true);
}

}  // namespace telex::local
