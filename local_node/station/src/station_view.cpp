// SPDX-License-Identifier: MIT
// The operator view: eyes' video, the stereo pair and the overview on their own thread, the window.
#include "station_view.h"

#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <span>

#include "telex/base/periodic.h"
#include "telex/common/head_kinematics.h"
#include "telex/local/view/openxr_output.h"
#include "telex/local/view/operator_view.h"

namespace telex::local {
namespace {

// What the window shows until the first pair: the same text in both eyes.
cv::Mat3b waiting_image(const std::string& remote) {
  cv::Mat3b img(480, 1280, cv::Vec3b(40, 40, 40));
  const std::string text = "waiting for the remote at " + remote;
  for (const int x0 : {0, 640})
    cv::putText(img, text, {x0 + 40, 240}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {230, 230, 230}, 1,
                cv::LINE_AA);
  return img;
}

}  // namespace

StationView::StationView(const StationConfig& cfg, StationFaults& faults)
    : cfg_(cfg),
      faults_(faults),
      spec_(ViewSpec::parse(cfg.view_spec)),
      window_(spec_.on_screen() ? std::make_unique<ViewWindow>(spec_) : nullptr),
      gate_(!openxr()) {
  // No runtime, or XR_RUNTIME_JSON naming nothing, stops the start before anything connects.
  if (openxr()) spdlog::info("openxr view: runtime {}", openxr_runtime_manifest());
  if (!spec_.stereo()) return;
  VideoReceiver::Hooks hooks;
  hooks.send_pli = [this](const proto::PictureLoss& pli) {
    if (auto* c = client_.load()) c->send_picture_loss(pli);
  };
  if (cfg.client.repair)
    hooks.send_nack = [this](const proto::VideoNack& nack) {
      if (auto* c = client_.load()) c->send_video_nack(nack);
    };
  hooks.rtt_ns = [this] {
    auto* c = client_.load();
    return c ? c->stats().rtt_ns.load() : std::int64_t{0};
  };
  hooks.now_ns = [] { return monotonic_ns(); };
  hooks.clock_offset_ns = [this] {
    auto* c = client_.load();
    return c ? c->stats().clock_offset_ns.load() : std::int64_t{0};
  };
  video_ = std::make_unique<VideoReceiver>(std::move(hooks));
}

void StationView::open() {
  if (spec_.kind == ViewSpec::Kind::Png) std::filesystem::create_directories(spec_.dir);
  if (!window_) return;
  const MonitorInfo& m = window_->monitor();
  spdlog::info("view {} on monitor '{}' ({}x{} at {},{}), {}",
               spec_.kind == ViewSpec::Kind::Hmd ? "full screen" : "in a window", m.name,
               m.rect.width, m.rect.height, m.rect.x, m.rect.y, window_->gl_renderer());
  window_->show(waiting_image(cfg_.client.host + ":" + std::to_string(cfg_.client.port)));
}

void StationView::bind(ClientEvents& events) {
  if (!video_) return;
  events.on_video = [this](const proto::Header& h, const proto::EncodedVideo& v) {
    video_->push(v.frame, (h.flags & proto::kFlagRepair) != 0);
  };
}

void StationView::summarize(StationSummary& s) const {
  if (!video_) return;
  const auto& c = video_->counters();
  s.video_pairs_received = c.received.load();
  s.video_pairs_decoded = c.decoded.load();
  s.video_pairs_with_head_pose = c.with_head_pose.load();
  s.video_pairs_damaged = c.damaged.load();
  s.video_decode_errors = c.decode_errors.load();
  s.video_plis_sent = c.plis_sent.load();
  s.video_nacks_sent = c.nacks_sent.load();
  s.video_pairs_repaired = c.repaired.load();
  s.video_pairs_given_up = c.given_up.load();
  s.video_pairs_expected = c.expected.load();
  s.video_pairs_asked_overdue = c.asked_overdue.load();
  s.video_pairs_queue_dropped = c.queue_dropped.load();
  s.video_eye_width_px = c.eye_width_px.load();
  s.video_eye_height_px = c.eye_height_px.load();
  const VideoReceiver::DeliveryAges ages = video_->delivery_ages();
  s.video_delivered_age_samples = ages.delivered_ms.size();
  s.video_delivered_age_ms_median = percentile(ages.delivered_ms, 0.5);
  s.video_delivered_age_ms_p99 = percentile(ages.delivered_ms, 0.99);
  s.video_delivered_age_ms_max = percentile(ages.delivered_ms, 1.0);
  s.video_replaced_age_ms_p99 = percentile(ages.replaced_ms, 0.99);
  s.video_replaced_age_ms_max = percentile(ages.replaced_ms, 1.0);
  s.video_replaced_over_100ms = static_cast<std::uint64_t>(std::count_if(
      ages.replaced_ms.begin(), ages.replaced_ms.end(), [](double ms) { return ms > 100.0; }));
  std::lock_guard lock(shown_mu_);
  s.video_pairs_shown = pairs_shown_;
  s.video_frames_drawn = frames_drawn_;
  s.video_late_waits = late_waits_;
  s.video_late_waits_met = late_waits_met_;
  std::vector<double> age = shown_age_ms_;
  s.shown_frame_age_ms_median = percentile(age, 0.5);
  s.shown_frame_age_ms_p99 = percentile(age, 0.99);
  s.glass_to_glass_samples = glass_ms_.size();
  s.glass_to_glass_ms_median = percentile(glass_ms_, 0.5);
  s.glass_to_glass_ms_p99 = percentile(glass_ms_, 0.99);
  s.glass_to_glass_mismatched = glass_mismatched_;
  const PhotonLatency::Figures motion = photon_.motion(), capture = photon_.capture();
  s.motion_to_photon_samples = motion.samples;
  s.motion_to_photon_ms_median = motion.median_ms;
  s.motion_to_photon_ms_p99 = motion.p99_ms;
  s.capture_to_photon_samples = capture.samples;
  s.capture_to_photon_ms_median = capture.median_ms;
  s.capture_to_photon_ms_p99 = capture.p99_ms;
}

PhotonStamps StationView::photon_stamps(const StereoViewInputs& in) const {
  return {in.hand.motion_ns, drawn_ ? drawn_->capture_ns : 0};
}

void StationView::photon_now(const PhotonStamps& stamps) {
  auto* c = client_.load();
  photon_.record(stamps, monotonic_ns(), c ? c->stats().clock_offset_ns.load() : 0);
}

void StationView::measure_glass(std::optional<std::uint32_t> counter) {
  if (!drawn_ || !counter) return;  // no pair drawn, or a source that stamps none
  auto* c = client_.load();
  const std::int64_t now_remote_ns = monotonic_ns() + (c ? c->stats().clock_offset_ns.load() : 0);
  std::lock_guard lock(shown_mu_);
  if (*counter != static_cast<std::uint32_t>(drawn_->frame_id)) {
    ++glass_mismatched_;
  } else if (glass_ms_.size() < kMaxAgeSamples) {
    glass_ms_.push_back(static_cast<double>(now_remote_ns - drawn_->capture_ns) / 1e6);
  }
  drawn_.reset();
}

void StationView::show_surface(std::shared_ptr<const Surface> surface, const cv::Mat1w& depth_mm) {
  std::lock_guard lock(surface_mu_);
  surface_ = std::move(surface);
  depth_mm_ = depth_mm;
}

void StationView::show_depth(const cv::Mat1w& depth_mm) {
  std::lock_guard lock(surface_mu_);
  depth_mm_ = depth_mm;
}

void StationView::write_files(const std::array<FingertipForce, kFingerCount>& forces,
                              const std::string& status, bool at_moment) {
  if (cfg_.view_at_s >= 0.0 && !at_moment) return;
  if (spec_.kind != ViewSpec::Kind::Png) return;
  request_stereo(forces, status);  // the view thread writes the pair and view.png
}

std::shared_ptr<const EyePair> StationView::show_pair(std::int64_t want_capture_ns, bool late) {
  if (!video_) return nullptr;
  auto pair = video_->pair(want_capture_ns);
  if (!pair) return nullptr;
  // Late, when the next pair is due within a few ms: waited for, rather than showing one about a
  // period old.
  const std::int64_t wait_ns = late
                                   ? late_pair_wait_ns(pair->delivered_ns, video_->pair_period_ns(),
                                                       monotonic_ns(), kMaxLatePairWaitNs)
                                   : 0;
  std::shared_ptr<const EyePair> newer;
  if (wait_ns > 0) newer = video_->wait_newer(pair->frame_id, std::chrono::nanoseconds(wait_ns));
  const bool came = newer != nullptr;
  if (came) pair = std::move(newer);
  auto* c = client_.load();
  // Display time on the remote's clock (the heartbeat's offset), as the capture time.
  const std::int64_t now_remote_ns = monotonic_ns() + (c ? c->stats().clock_offset_ns.load() : 0);
  std::lock_guard lock(shown_mu_);
  ++frames_drawn_;
  late_waits_ += wait_ns > 0;
  late_waits_met_ += came;
  if (pairs_shown_ == 0 || pair->frame_id != last_shown_frame_id_) ++pairs_shown_;
  last_shown_frame_id_ = pair->frame_id;
  if (shown_age_ms_.size() < kMaxAgeSamples)
    shown_age_ms_.push_back(static_cast<double>(now_remote_ns - pair->capture_ns) / 1e6);
  return pair;
}

void StationView::request_stereo(const std::array<FingertipForce, kFingerCount>& forces,
                                 const std::string& status) {
  hand_in_.take(hand_);
  {
    std::lock_guard lock(stereo_mu_);
    stereo_request_.hand = hand_;
    stereo_request_.forces = forces;
    stereo_request_.status = status;
    stereo_request_.pending = true;
    stereo_busy_.store(true, std::memory_order_release);
  }
  stereo_cv_.notify_one();
}

bool StationView::pump_window(std::atomic<bool>& stop, std::chrono::milliseconds wait) {
  if (auto sbs = sbs_for_window_.take(wait)) {
    window_->show(sbs->bgr);
    photon_now(sbs->stamps);  // swapped
  } else {
    window_->refresh();
  }
  if (!window_->should_close()) return false;
  if (!stop.exchange(true)) spdlog::info("the view window was closed: stopping");
  return true;
}

void StationView::log_window_counts() const {
  if (!window_) return;
  spdlog::info(
      "view window: {} stereo pairs shown, {} replaced by a newer one before the window drew "
      "them, {} redraws",
      window_->images_uploaded(), sbs_for_window_.dropped(), window_->frames_shown());
}

// ---- view thread: the stereo pair, off the main thread (and off the haptic one). Its headless
// EGL context is made while the station connects; a machine without EGL stops the station here,
// named. A window gets the pair through sbs_for_window_. ----
void StationView::run_stereo(std::stop_token stop, int niceness) {
  if (openxr()) {
    run_openxr(stop);
    return;
  }
  // On a machine without a GPU (llvmpipe) the view could take a core from a surface thread that
  // is not real-time: there it runs at the niceness it is given, and so do llvmpipe's rasterizer
  // threads, which its context starts and which inherit it.
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), niceness);
  try {
    const cv::Size first = cfg_.eye_size.empty() ? cv::Size(640, 480) : cfg_.eye_size;
    StereoView view(first.width, first.height, cfg_.body);
    view.set_eye_cameras(cfg_.eye_camera, cfg_.R_RightEyeLeftEye);
    for (;;) {
      StereoViewInputs in;
      {
        std::unique_lock lock(stereo_mu_);
        stereo_cv_.wait(lock, stop, [this] { return stereo_request_.pending; });
        if (!stereo_request_.pending) return;  // stopped with nothing left to draw
        stereo_request_.pending = false;
        in.hand = stereo_request_.hand;
        in.forces = stereo_request_.forces;
        in.status = stereo_request_.status;
      }
      render_stereo(view, in);  // false: no intrinsics before the first surface
      std::lock_guard lock(stereo_mu_);
      if (!stereo_request_.pending) stereo_busy_.store(false, std::memory_order_release);
    }
  } catch (...) {
    faults_.fail("view (stereo)", std::current_exception());
  }
}

bool StationView::render_stereo(StereoView& view, StereoViewInputs& in) {
  if (!stereo_inputs(in, spec_.on_screen())) {
    if (spec_.kind == ViewSpec::Kind::Png) write_overview(in, {});  // waiting for the surface
    return false;
  }
  // On screen the video is late-latched: the body is drawn first, then the newest pair is taken
  // and composed under it, so a pair waits for the composition only, not for the body's march.
  // The pictures keep the pair captured nearest the depth.
  const bool late = spec_.on_screen();  // stereo_inputs only looked at the newest pair
  const StereoViewImages v =
      late ? view.render(in, [this](StereoViewInputs& l) { take_pair(l, 0, true); })
           : view.render(in);
  if (v.one_eye && !warned_one_eye_) {
    spdlog::warn("the remote sends one eye's video only: the stereo view uses it for both eyes");
    warned_one_eye_ = true;
  }
  const PhotonStamps stamps = photon_stamps(in);
  if (spec_.on_screen()) {
    sbs_for_window_.put({in.fig7 ? v.fig7 : v.sbs, stamps});  // to photon when the window swaps
  } else {
    write_stereo_files(v);
    write_overview(in, v.normals);
    photon_now(stamps);
  }
  measure_glass(v.frame_counter);
  return true;
}

bool StationView::stereo_inputs(StereoViewInputs& in, bool late_pair) {
  std::shared_ptr<const Surface> vs;
  {
    std::lock_guard lock(surface_mu_);
    vs = surface_;
    in.depth_mm = depth_mm_;
  }
  drawn_surface_ = vs;  // held while the view draws it
  if (!vs) return false;
  in.surface = vs.get();
  in.k = vs->intrinsics;
  in.eye_size = cfg_.eye_size;
  in.fig7 = cfg_.view_layout == "fig7";
  in.overlays = cfg_.view_overlays == "on" ||
                (cfg_.view_overlays == "auto" && spec_.kind != ViewSpec::Kind::Hmd);
  in.baseline_m = cfg_.stereo_baseline_m;
  in.skin_bgr = cfg_.skin_bgr;
  drawn_.reset();
  if (late_pair && video_) {
    if (const auto pair = video_->pair(0)) in.eye_bgr = {pair->left_bgr, pair->right_bgr};
  }
  // The warp: the robot head's pose when the depth drawn was captured, as the remote measured it
  // with that frame, the pose when the eye pair was captured (its own instant: at 60 deg/s a 16 ms
  // gap is a degree), and the operator's head in the newest tracking sample, which `in.hand` is in.
  const bool warp = cfg_.view_warp && vs->head_valid && in.hand.head_valid;
  if (warp) {
    in.R_BaseDepth = head_rotation(cfg_.robot_head, vs->head_joint_rad);
    in.R_BaseDisplay = in.hand.R_BaseCamera;
  } else if (cfg_.view_warp && !warned_no_warp_) {
    spdlog::info(
        "view: no warp until both head poses are known ({}): the video is shown as "
        "captured",
        !vs->head_valid ? "the remote reports no head pose with its frames"
                        : "no head body is tracked");
    warned_no_warp_ = true;
  }
  // The pair (one instant for both eyes) captured nearest to the depth drawn over it.
  if (!late_pair) take_pair(in, vs->capture_ns);
  return true;
}

void StationView::take_pair(StereoViewInputs& in, std::int64_t want_capture_ns, bool late) {
  const auto pair = show_pair(want_capture_ns, late);
  if (!pair) return;
  drawn_ = pair;
  in.eye_bgr = {pair->left_bgr, pair->right_bgr};
  if (drawn_surface_) {
    const std::int64_t gap_ns = std::abs(pair->capture_ns - drawn_surface_->capture_ns);
    char pairing[48];
    std::snprintf(pairing, sizeof pairing, " | eyes paired within %.1f ms",
                  static_cast<double>(gap_ns) / 1e6);
    in.status += pairing;
  }
  if (in.R_BaseDepth) video_pose(in);  // the warp is engaged
}

void StationView::video_pose(StereoViewInputs& in) {
  if (drawn_ && drawn_->head_joint_rad) {
    const auto& j = *drawn_->head_joint_rad;
    in.R_BaseVideo = head_rotation(cfg_.robot_head, {j[0], j[1], j[2]});
    return;
  }
  if (drawn_ && !warned_pair_pose_) {
    spdlog::info(
        "view: an eye pair came without the robot head's pose at its capture (the remote had no "
        "head reading then): such a pair's video is warped from the pose of the depth frame "
        "drawn with it");
    warned_pair_pose_ = true;
  }
}

void StationView::write_stereo_files(const StereoViewImages& v) const {
  for (const auto& [name, img] : {std::pair{"left", &v.left}, std::pair{"right", &v.right},
                                  std::pair{"sbs", &v.sbs}, std::pair{"fig7", &v.fig7}})
    write_png(name, *img);
}

void StationView::write_overview(const StereoViewInputs& in, const cv::Mat3f& normals) const {
  ViewInputs vi;
  if (drawn_) vi.camera_bgr = drawn_->right_bgr;
  vi.surface = in.surface;
  vi.depth_mm = in.depth_mm;
  vi.normals = normals;
  vi.hand = in.hand;
  vi.forces = in.forces;
  vi.status = in.status;
  vi.arrow_m_per_N = in.arrow_m_per_N;
  write_png("view", render_operator_view(vi));
}

void StationView::write_png(const std::string& name, const cv::Mat3b& img) const {
  if (img.empty()) return;
  const auto tmp = spec_.dir / (name + ".tmp.png");
  if (cv::imwrite(tmp.string(), img)) std::filesystem::rename(tmp, spec_.dir / (name + ".png"));
}

}  // namespace telex::local
