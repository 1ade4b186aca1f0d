// SPDX-License-Identifier: MIT
// The operator view: eyes' video, the 2D view, the stereo pair on its own thread, the window.
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

#include "../xr/openxr_output.h"
#include "telex/local/operator_view.h"

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
  events.on_video = [this](const proto::Header& h, const proto::VideoFrame& v) {
    std::lock_guard lock(video_mu_);
    auto& q = eye_frames_[v.eye == 0 ? 0 : 1];
    q.push_back({static_cast<std::int64_t>(h.capture_ns), v.jpeg});
    if (q.size() > 8) q.pop_front();
    eye_frames_received_.fetch_add(1, std::memory_order_relaxed);
  };
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
  const cv::Mat3b img = render_2d(forces, status);
  const auto path = spec_.dir / "view.png";
  const auto tmp = spec_.dir / "view.tmp.png";
  if (cv::imwrite(tmp.string(), img)) std::filesystem::rename(tmp, path);
  request_stereo(forces, status);
}

cv::Mat3b StationView::render_2d(const std::array<FingertipForce, kFingerCount>& forces,
                                 const std::string& status) {
  ViewInputs vi;
  std::shared_ptr<const Surface> vs;
  {
    std::lock_guard lock(surface_mu_);
    vs = surface_;
    vi.depth_mm = depth_mm_;
  }
  vi.surface = vs.get();
  hand_in_.take(hand_);
  vi.hand = hand_;
  vi.forces = forces;
  vi.status = status;
  vi.camera_bgr = eye_image(1);
  return render_operator_view(vi);
}

cv::Mat3b StationView::eye_image(int eye, std::int64_t want_capture_ns, std::int64_t* offset_ns) {
  std::vector<std::uint8_t> jpeg;
  {
    std::lock_guard lock(video_mu_);
    const auto& q = eye_frames_[static_cast<std::size_t>(eye)];
    if (q.empty()) return {};
    std::size_t pick = q.size() - 1;
    if (want_capture_ns != 0) {
      std::array<std::int64_t, 8> captures{};
      for (std::size_t i = 0; i < q.size(); ++i) captures[i] = q[i].capture_ns;
      pick = *nearest_capture(std::span(captures.data(), q.size()), want_capture_ns);
      if (offset_ns) *offset_ns = q[pick].capture_ns - want_capture_ns;
    }
    jpeg = q[pick].jpeg;
  }
  if (jpeg.empty()) return {};
  return cv::imdecode(jpeg, cv::IMREAD_COLOR);
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
  }
  stereo_cv_.notify_one();
}

bool StationView::pump_window(std::atomic<bool>& stop) {
  if (auto sbs = sbs_for_window_.take(std::chrono::milliseconds(0)))
    window_->show(*sbs);
  else
    window_->refresh();
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
void StationView::run_stereo(std::stop_token stop) {
  if (openxr()) {
    run_openxr(stop);
    return;
  }
  // At video rate on a machine without a GPU (llvmpipe) the view would take a core from the
  // surface thread and the remote: it runs at nice 5, and so do llvmpipe's rasterizer threads,
  // which its context starts and which inherit the niceness. The haptic thread is unaffected
  // (SCHED_FIFO, or its own thread at nice 0).
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 5);
  try {
    StereoView view(640, 480, cfg_.body);
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
      if (!render_stereo(view, in)) continue;  // no intrinsics before the first surface
    }
  } catch (...) {
    faults_.fail("view (stereo)", std::current_exception());
  }
}

bool StationView::render_stereo(StereoView& view, StereoViewInputs& in) {
  if (!stereo_inputs(in)) return false;
  const StereoViewImages v = view.render(in);
  if (v.one_eye && !warned_one_eye_) {
    spdlog::warn("the remote sends one eye's video only: the stereo view uses it for both eyes");
    warned_one_eye_ = true;
  }
  if (spec_.on_screen())
    sbs_for_window_.put(v.sbs);
  else
    write_stereo_files(v);
  return true;
}

bool StationView::stereo_inputs(StereoViewInputs& in) {
  std::shared_ptr<const Surface> vs;
  {
    std::lock_guard lock(surface_mu_);
    vs = surface_;
    in.depth_mm = depth_mm_;
  }
  if (!vs) return false;
  in.surface = vs.get();
  in.k = vs->intrinsics;
  in.baseline_m = cfg_.stereo_baseline_m;
  in.skin_bgr = cfg_.skin_bgr;
  // Each eye's frame captured nearest to the depth drawn over it; the larger gap is shown.
  std::int64_t gap_left = 0, gap_right = 0;
  in.eye_bgr = {eye_image(0, vs->capture_ns, &gap_left), eye_image(1, vs->capture_ns, &gap_right)};
  if (!in.eye_bgr[0].empty() || !in.eye_bgr[1].empty()) {
    const double gap_ms =
        static_cast<double>(std::max(std::abs(gap_left), std::abs(gap_right))) / 1e6;
    char pairing[48];
    std::snprintf(pairing, sizeof pairing, " | eyes paired within %.1f ms", gap_ms);
    in.status += pairing;
  }
  return true;
}

void StationView::write_stereo_files(const StereoViewImages& v) const {
  const std::filesystem::path& dir = spec_.dir;
  for (const auto& [name, img] :
       {std::pair{"left", &v.left}, std::pair{"right", &v.right}, std::pair{"sbs", &v.sbs}}) {
    const auto tmp = dir / (std::string(name) + ".tmp.png");
    if (cv::imwrite(tmp.string(), *img))
      std::filesystem::rename(tmp, dir / (std::string(name) + ".png"));
  }
}

}  // namespace telex::local
