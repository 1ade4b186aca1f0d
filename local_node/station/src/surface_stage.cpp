// SPDX-License-Identifier: MIT
// The surface stage: depth events -> frames (network thread), frames -> snapshots (surface thread).
#include "surface_stage.h"

#include <algorithm>
#include <chrono>

#include "telex/common/head_kinematics.h"
#include "telex/local/inputs/hand_model.h"

namespace telex::local {
namespace {

// Median depth (m) of the valid pixels in the central tenth of the raw frame: where scripts aim.
// The raw frame, not the snapshot: a region-of-interest snapshot holds nothing there yet.
double centre_depth_m(const cv::Mat1w& depth_mm) {
  const int w = std::max(1, depth_mm.cols / 10), h = std::max(1, depth_mm.rows / 10);
  const cv::Mat1w c = depth_mm(cv::Rect((depth_mm.cols - w) / 2, (depth_mm.rows - h) / 2, w, h));
  std::vector<std::uint16_t> v;
  for (auto z : c)
    if (z > 0) v.push_back(z);
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2] * 1e-3;
}

cv::Rect grow_rect(const cv::Rect& r, int margin) {
  return {r.x - margin, r.y - margin, r.width + 2 * margin, r.height + 2 * margin};
}

}  // namespace

SurfaceStage::SurfaceStage(const StationConfig& cfg, StationFaults& faults, StationView& view,
                           SessionRecorder* recorder)
    : cfg_(cfg),
      faults_(faults),
      view_(view),
      recorder_(recorder),
      reach_px_(cfg.surface.bilateral_options.radius_px +
                cfg.surface.normal_options.smooth_radius_px + 1),
      assembler_(static_cast<std::int64_t>(cfg.max_tile_age_s * 1e9)),
      repair_(cfg.nack_retry_min_s, cfg.key_request_interval_s) {}

// ---- network thread ----

void SurfaceStage::bind(ClientEvents& events) {
  events.on_config = [this](const proto::StreamConfig& c) { assembler_.configure(c); };
  // The remote says which registration its depth went through after each stream configuration.
  events.on_stats = [this](const proto::Stats& s) {
    for (const auto& [key, value] : s.counters) {
      if (value == 0) continue;
      for (const char* name : {"none", "hardware", "rig"})
        if (key == std::string("registration_") + name) remote_registration_.store(name);
      if (key == "source_ended") remote_said_.fetch_or(kSourceEnded);
      if (key == "eyes_off") remote_said_.fetch_or(kEyesOff);
      if (key == "eyes_ended") remote_said_.fetch_or(kEyesEnded);
    }
  };
  events.on_tile = [this](const proto::Header& h, const proto::DepthTile& t) { on_tile(h, t); };
  events.on_manifest = [this](const proto::Header& h, const proto::FrameManifest& m) {
    on_manifest(h, m);
  };
}

void SurfaceStage::on_tile(const proto::Header& h, const proto::DepthTile& t) {
  const std::int64_t now = monotonic_ns();
  assembler_.apply_tile(h, t, now);
  // A repaired tile under a fingertip rebuilds the surface at once, not at the next frame.
  if (h.flags & proto::kFlagRepair)
    if (auto f = assembler_.take_repaired(now)) frames_.put(std::move(*f));
}

void SurfaceStage::on_manifest(const proto::Header& h, const proto::FrameManifest& m) {
  faults_.check(StationLoop::Network);
  const std::int64_t now = monotonic_ns();
  {
    std::lock_guard lock(watch_mu_);
    assembler_.set_watched(watch_rects_);
  }
  if (auto f = assembler_.finish(h, m, now)) {
    repair_.on_frame(now, f->capture_ns, client_->stats().clock_offset_ns.load());
    frames_.put(std::move(*f));
  }
  if (!cfg_.client.repair) return;
  const RepairRequest r = assembler_.repair_request(
      now, repair_.retry_ns(client_->stats().rtt_ns.load()), repair_.key_interval_ns());
  if (r.nack) client_->send_nack(*r.nack);
  if (r.key_frame) client_->request_key_frame();
}

// ---- surface thread: frames -> snapshots for the haptic loop ----

void SurfaceStage::run(std::stop_token stop) {
  struct Ready {  // the station connects once the warm-up is done, or failed
    std::latch& latch;
    bool done = false;
    void count_down() {
      if (!std::exchange(done, true)) latch.count_down();
    }
    ~Ready() { count_down(); }
  } ready{warm_};
  try {
    warm_up();
    ready.count_down();
    while (!stop.stop_requested()) {
      auto frame = frames_.take(std::chrono::milliseconds(50));
      if (!frame) continue;
      faults_.check(StationLoop::Surface);
      hand_in_.take(hand_);
      in_frame_camera(*frame, hand_);
      std::vector<cv::Rect> windows =
          fingertip_windows(hand_, frame->depth_mm, frame->intrinsics, cfg_.surface);
      if (rest_changes_nothing(*frame, windows)) {
        view_.show_depth(frame->depth_mm);
        continue;
      }
      build(*frame, windows);
      request_roi(windows);
    }
  } catch (...) {
    faults_.fail("surface (telex-surface)", std::current_exception());
  }
}

void SurfaceStage::warm_up() {
  // The first frames must not pay for first use: the pool's pages are made resident and one
  // build runs on a plane at the stream's usual size (the pool drops them if it differs).
  // Measured: the first builds with a fingertip window took 2.5-6.8 ms instead of 0.3.
  const cv::Size usual(640, 480);
  pool_.warm(usual);
  AssembledFrame plane;
  plane.depth_mm = cv::Mat1w(usual, std::uint16_t{1000});
  plane.intrinsics = kinect_v1_intrinsics(usual.width, usual.height);
  const std::vector<cv::Rect> whole{cv::Rect(cv::Point(0, 0), usual)};
  build_surface(plane, cfg_.surface, whole);
}

void SurfaceStage::in_frame_camera(const AssembledFrame& frame, HandState& hand) const {
  if (!cfg_.head_captured_pose || !frame.head.valid || !hand.head_valid) return;
  to_capture_camera(capture_correction(cfg_.robot_head, hand, true,
                                       {frame.head.joint_rad[0], frame.head.joint_rad[1],
                                        frame.head.joint_rad[2]}),
                    hand);
}

// The rest of a frame whose ROI part is already built: rebuilt only when it changed pixels the
// surface's windows (or the filter reading around them) use.
bool SurfaceStage::rest_changes_nothing(const AssembledFrame& frame,
                                        const std::vector<cv::Rect>& windows) {
  if ((frame.part != AssembledPart::Rest && frame.part != AssembledPart::Repair) ||
      frame.capture_ns != built_capture_ns_ || !cfg_.surface.roi)
    return false;
  if (windows != last_windows_) return false;
  for (const auto& w : windows)
    for (const auto& c : frame.changed_since_roi_part)
      if ((grow_rect(w, reach_px_) & c).area() > 0) return false;
  return true;
}

void SurfaceStage::build(AssembledFrame& frame, std::vector<cv::Rect> windows) {
  // A frame's ROI part, rest and repairs are several builds of one capture: the status line's
  // rate counts captures, as a source's fps does.
  if (frame.capture_ns != built_capture_ns_) frames_built_.fetch_add(1);
  built_capture_ns_ = frame.capture_ns;
  // Snapshot ids are the station's own sequence: a restarted remote numbers its frames from the
  // start again, and the haptic model ignores snapshots that go backwards.
  frame.frame_id = static_cast<std::uint32_t>(++surface_seq_);
  {
    // The tiles the network thread repairs first: what these windows' surface reads.
    std::lock_guard lock(watch_mu_);
    watch_rects_.clear();
    for (const auto& w : windows) watch_rects_.push_back(grow_rect(w, reach_px_));
  }
  if (!cfg_.surface.roi) windows.clear();
  SurfaceBuildStats st;
  const std::int64_t built_ns = monotonic_ns();
  std::shared_ptr<Surface> built = build_surface(frame, cfg_.surface, windows, &st, &pool_);
  // With the head's pose at capture, the haptic model works in the head base's frame, where the
  // room stays put while the head turns (its god-points and its crossfade between two surfaces
  // then agree).
  built->R_ModelCamera = cfg_.head_captured_pose && built->head_valid
                             ? head_rotation(cfg_.robot_head, built->head_joint_rad)
                             : glm::dmat3(1.0);
  std::shared_ptr<const Surface> s = std::move(built);
  build_ms_.store(st.snapshot_ms + st.filter_ms + st.normals_ms);
  if (surfaces_built_.load() == 0) first_centre_depth_m_.store(centre_depth_m(frame.depth_mm));
  surfaces_.publish(s);
  if (recorder_)
    recorder_->add_surface({surface_seq_, built_ns, frame.capture_ns, frame.depth_mm.clone(),
                            frame.intrinsics, remote_registration_.load()});
  retired_.push_back(s);
  if (retired_.size() > 8) retired_.pop_front();
  surfaces_built_.fetch_add(1);
  if (frame.part != AssembledPart::Repair) {
    const std::int64_t offset = client_->stats().clock_offset_ns.load();
    arrive_ms_.add(static_cast<double>(frame.received_ns - (frame.capture_ns - offset)) / 1e6);
    build_wait_ms_.add(static_cast<double>(monotonic_ns() - frame.received_ns) / 1e6);
  }
  view_.show_surface(s, frame.depth_mm);
}

// Full-rate tiles near the hands, asked for when the windows moved.
void SurfaceStage::request_roi(const std::vector<cv::Rect>& windows) {
  if (!cfg_.roi_requests || !cfg_.surface.roi || windows == last_windows_) return;
  proto::RoiRequest roi;
  for (const auto& r : windows) {
    if (roi.rects.size() >= proto::kMaxRoiRects) break;
    roi.rects.push_back({static_cast<std::uint16_t>(r.x), static_cast<std::uint16_t>(r.y),
                         static_cast<std::uint16_t>(r.width), static_cast<std::uint16_t>(r.height),
                         1});
  }
  client_->request_roi(roi);
  last_windows_ = windows;
}

void SurfaceStage::summarize(StationSummary& s) const {
  s.surfaces = surfaces_built_.load();
  const AssemblerCounters& ac = assembler_.counters();  // the network thread has stopped
  s.frames = ac.frames;
  s.roi_parts = ac.roi_parts;
  s.arrive_median_ms = arrive_ms_.quantile(0.5);
  s.arrive_p99_ms = arrive_ms_.quantile(0.99);
  s.build_wait_median_ms = build_wait_ms_.quantile(0.5);
  s.build_wait_p99_ms = build_wait_ms_.quantile(0.99);
  s.tiles_missing = ac.tiles_missing;
  s.frames_incomplete = ac.frames_incomplete;
  s.frames_unclosed = ac.frames_unclosed;
  s.tiles_expired = ac.tiles_expired;
  s.nacks = ac.nacks;
  s.tiles_nacked = ac.tiles_nacked;
  s.watched_tiles_nacked = ac.watched_tiles_nacked;
  s.tiles_repaired = ac.tiles_repaired;
  s.repairs_useless = ac.repairs_useless;
  s.key_frame_requests = ac.key_frame_requests;
  const TileAges& ages = assembler_.ages();
  s.tile_age_samples = ages.all.count();
  s.tile_age_watched_samples = ages.watched.count();
  s.tile_age_watched_median = ages.watched.quantile(0.5);
  s.tile_age_watched_p99 = ages.watched.quantile(0.99);
  s.tile_age_watched_max = ages.watched.max();
  s.tile_age_all_median = ages.all.quantile(0.5);
  s.tile_age_all_p99 = ages.all.quantile(0.99);
  s.tile_age_all_max = ages.all.max();
}

}  // namespace telex::local
