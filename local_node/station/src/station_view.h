// SPDX-License-Identifier: MIT
// The operator view (--view png:DIR | window | hmd | openxr): the eyes' video as received, the
// newest surface and depth, the 2D view, the stereo pair drawn on its own thread, and the window
// on the main thread. With openxr the view thread runs the headset's frame loop instead
// (station_view_xr.cpp), gates the haptic output on its focus and tracks its pose.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <stop_token>
#include <string>
#include <vector>

#include "faults.h"
#include "output_gate.h"
#include "telex/base/latest_slot.h"
#include "telex/base/spsc_ring.h"
#include "telex/base/triple_buffer.h"
#include "telex/local/link/surface_client.h"
#include "telex/local/link/video_receiver.h"
#include "telex/local/station/station_config.h"
#include "telex/local/view/photon_latency.h"
#include "telex/local/view/stereo_view.h"
#include "telex/local/view/view_window.h"

namespace telex::local {

class StationView {
 public:
  // Opens the window (--view window | hmd) now, so a missing display or an unknown monitor stops
  // the start before anything connects.
  StationView(const StationConfig& cfg, StationFaults& faults);

  // Creates the PNG folder, and shows the window's waiting picture.
  void open();
  // The eyes' video from the network thread.
  void bind(ClientEvents& events);
  // The client the eyes' Picture Loss Indications go to (and its round trip and clock offset).
  void attach(SurfaceClient& client) { client_ = &client; }
  // Before the client goes: the eyes' decode thread, which asks the client for its round trip
  // and clock offset and sends it NACKs and PLIs, is stopped and joined.
  void detach() {
    if (video_) video_->stop();
    client_ = nullptr;
  }
  bool stereo() const { return spec_.stereo(); }
  // The eyes' decode thread's fault, if it failed.
  std::optional<ThreadFaultReport> thread_fault() const {
    return video_ ? video_->thread_fault() : std::nullopt;
  }
  bool window() const { return window_ != nullptr; }
  // How often the window asks for a frame: its monitor's refresh period (display_period_ns).
  std::int64_t window_period_ns() const {
    return window_ ? display_period_ns(window_->monitor()) : 0;
  }
  // Encoded pairs received so far: the status line's eye rate.
  std::uint64_t eye_frames_received() const {
    return video_ ? video_->counters().received.load() : 0;
  }
  // The eyes in the run's summary: pairs shown, PLIs sent, shown-frame age; motion and capture
  // to photon.
  void summarize(StationSummary& s) const;
  // The status line's motion and capture to photon (the newest frames' medians).
  PhotonLatency::Recent photon_recent() const { return photon_.recent(); }
  bool openxr() const { return spec_.kind == ViewSpec::Kind::OpenXr; }
  bool writes_png() const { return spec_.kind == ViewSpec::Kind::Png; }
  // --view openxr: closed until the headset's session is FOCUSED, and whenever it is not.
  const OutputGate& output_gate() const { return gate_; }
  // --head-source hmd: the headset's newest pose in the NatNet frame (through the rig's
  // operator.hmd_stage_in_natnet) and when it was located, read by the tracker on the haptic
  // thread; false until the session located the headset.
  std::function<bool(Pose&, std::int64_t&)> hmd_head_source();
  // --record-hmd-poses, main thread: the headset's view in STAGE at each frame's display time,
  // oldest first; false when none is waiting. Poses the main thread was too slow for are counted.
  struct StagePose {
    std::int64_t display_time_ns = 0;
    Pose X_StageView;
  };
  bool take_stage_pose(StagePose& out) { return stage_poses_.pop(out); }
  std::uint64_t stage_poses_dropped() const { return stage_poses_.dropped(); }
  // The headset's session ended by itself (the user quit, the runtime went): the station stops.
  bool xr_ended() const { return xr_ended_.load(); }
  struct XrStats {
    std::string runtime, end_reason;
    std::uint64_t frames_submitted = 0;
    int eye_width = 0, eye_height = 0;
    // When the gate closed (after closing) and opened again (before opening; 0: still closed at
    // the end), CLOCK_MONOTONIC ns: a haptic tick whose time falls inside output no force.
    std::vector<std::pair<std::int64_t, std::int64_t>> gate_closed_ns;
  };
  XrStats xr_stats() const;

  // Surface thread: what the view draws (a frame's rest that changed nothing only its depth).
  void show_surface(std::shared_ptr<const Surface> surface, const cv::Mat1w& depth_mm);
  void show_depth(const cv::Mat1w& depth_mm);
  // Haptic thread -> view: the hand.
  TripleBuffer<HandState>& hand_in() { return hand_in_; }

  // Main thread. The stereo view is handed what the main thread knows (forces, status): once a
  // second for PNGs, at video rate for a window.
  void request_stereo(const std::array<FingertipForce, kFingerCount>& forces,
                      const std::string& status);
  // No request waits and the view thread is not drawing: a request made now is drawn at once,
  // with the hand and forces as they are now. On a screen the main thread asks only then, so a
  // slow renderer (llvmpipe: about 100 ms a frame) draws the newest sample, not one it was handed
  // a frame ago.
  bool stereo_idle() const { return !stereo_busy_.load(std::memory_order_acquire); }
  // --view png:DIR: the stereo pair and the overview (view.png), drawn and written on the view
  // thread. With --view-at only the moment it names is written (`at_moment`).
  void write_files(const std::array<FingertipForce, kFingerCount>& forces,
                   const std::string& status, bool at_moment = false);
  // The window's turn: the newest stereo pair, waited for up to `wait`, or the window's events.
  // True once the operator closed it (the station then stops as on a signal; `stop` is set).
  bool pump_window(std::atomic<bool>& stop,
                   std::chrono::milliseconds wait = std::chrono::milliseconds(0));
  // At the end: what the window showed.
  void log_window_counts() const;

  // The view thread's body (started by the station when stereo()), at `niceness` (it and the
  // renderer's threads).
  void run_stereo(std::stop_token stop, int niceness);

 private:
  // The decoded pair captured nearest to `want_capture_ns` (0: the newest), counted as shown now
  // (its age: display time minus capture time); null before the first.
  // `late`: the newest, or the next when it is due within kMaxLatePairWaitNs (waited for; 20 ms:
  // g2g p99 45-66 ms against 48-72 with 12, motion to photon alike, 3 runs each).
  std::shared_ptr<const EyePair> show_pair(std::int64_t want_capture_ns = 0, bool late = false);
  static constexpr std::int64_t kMaxLatePairWaitNs = 20'000'000;
  // The stereo pair for one request, or false when there is no surface to draw yet.
  bool render_stereo(StereoView& view, StereoViewInputs& in);
  void write_stereo_files(const StereoViewImages& v) const;
  // view.png: the overview of what the pair was drawn from, the right eye's video as captured,
  // its inset the full-frame `normals` the stereo view computed for display (empty: the
  // surface's own, or none before the first surface).
  void write_overview(const StereoViewInputs& in, const cv::Mat3f& normals) const;
  void write_png(const std::string& name, const cv::Mat3b& img) const;  // DIR/name.png, whole
  // The inputs of one pair (surface, depth, eyes' video, status); false before the first surface.
  // The pair is the one captured nearest the depth drawn; with `late_pair` only a look at the
  // newest (its pictures light the body), taken later by take_pair.
  bool stereo_inputs(StereoViewInputs& in, bool late_pair = false);
  // The pair captured nearest `want_capture_ns` (0: the newest) into `in`, shown (show_pair), with
  // its pairing to the depth in the status and its head pose for the warp.
  void take_pair(StereoViewInputs& in, std::int64_t want_capture_ns, bool late = false);
  // in.R_BaseVideo from the drawn pair's own head pose; a pair without one leaves it unset (the
  // video is turned from the depth's pose, as before the pairs carried one), said once.
  void video_pose(StereoViewInputs& in);
  // --view openxr: the view thread's body (station_view_xr.cpp).
  void run_openxr(std::stop_token stop);
  void set_gate(bool open);

  const StationConfig& cfg_;
  StationFaults& faults_;
  const ViewSpec spec_;
  // GLFW's window, used on the main thread only.
  std::unique_ptr<ViewWindow> window_;

  std::atomic<SurfaceClient*> client_{nullptr};
  std::unique_ptr<VideoReceiver> video_;  // with a view: decodes the eyes on its own thread
  mutable std::mutex shown_mu_;
  std::uint32_t last_shown_frame_id_ = 0;  // guarded by shown_mu_, as the two below
  std::uint64_t pairs_shown_ = 0;
  std::uint64_t late_waits_ = 0, late_waits_met_ = 0;  // show_pair's late waits, and those met
  std::uint64_t frames_drawn_ = 0;    // frames that took a pair (pairs_shown_ of them a fresh one)
  std::vector<double> shown_age_ms_;  // at most kMaxAgeSamples
  // Glass to glass: capture to the rendered eye handed to the display, for the pairs whose frame
  // counter (telex/video/frame_counter.h), read from the video the frame drew before the view
  // painted it over, is their id.
  std::vector<double> glass_ms_;          // at most kMaxAgeSamples, guarded by shown_mu_
  std::uint64_t glass_mismatched_ = 0;    // a counter read back that is not the pair's id
  std::shared_ptr<const EyePair> drawn_;  // view thread: the pair stereo_inputs gave the view
  std::shared_ptr<const Surface> drawn_surface_;  // view thread: the surface it gave, held
  static constexpr std::size_t kMaxAgeSamples = 1 << 20;

  std::mutex surface_mu_;
  std::shared_ptr<const Surface> surface_;
  cv::Mat1w depth_mm_;

  TripleBuffer<HandState> hand_in_;
  HandState hand_{};  // main thread

  // Main thread -> view thread, and on a screen the view thread's pairs back, newest wins.
  struct WindowFrame {
    cv::Mat3b bgr;
    PhotonStamps stamps;
  };
  LatestSlot<WindowFrame> sbs_for_window_;
  std::mutex stereo_mu_;
  std::condition_variable_any stereo_cv_;
  struct StereoRequest {
    HandState hand{};
    std::array<FingertipForce, kFingerCount> forces{};
    std::string status;
    bool pending = false;
  } stereo_request_;  // guarded by stereo_mu_
  // From a request made until the view thread has drawn it.
  std::atomic<bool> stereo_busy_{false};
  bool warned_one_eye_ = false;  // view thread
  // After the rendered eyes went to the display: the glass-to-glass sample of drawn_, whose
  // video carried `counter` (StereoViewImages::frame_counter).
  void measure_glass(std::optional<std::uint32_t> counter);
  // What a frame drawn from `in` and drawn_ is stamped with, and its motion and capture to
  // photon, handed to the display now.
  PhotonStamps photon_stamps(const StereoViewInputs& in) const;
  void photon_now(const PhotonStamps& stamps);
  PhotonLatency photon_;
  bool warned_no_warp_ = false;    // view thread
  bool warned_pair_pose_ = false;  // view thread: pairs without a head pose were said once

  // --view openxr.
  OutputGate gate_;
  std::atomic<bool> xr_ended_{false};
  struct HmdSample {
    Pose X_NatNetHead;
    std::int64_t located_ns = 0;  // CLOCK_MONOTONIC
  };
  TripleBuffer<HmdSample> hmd_head_;
  SpscRing<StagePose> stage_poses_{256};  // view thread -> main thread, with --record-hmd-poses
  mutable std::mutex xr_mu_;
  XrStats xr_stats_;  // guarded by xr_mu_
};

}  // namespace telex::local
