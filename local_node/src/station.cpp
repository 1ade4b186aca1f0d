// SPDX-License-Identifier: MIT
// The operator station's threads: network (SurfaceClient), surface building, the haptic loop, and
// the main thread for logging, status lines and the operator view's window.
#include "telex/local/station.h"

#include <fmt/format.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <exception>
#include <fstream>
#include <latch>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <stop_token>
#include <thread>
#include <vector>

#include "telex/base/latest_slot.h"
#include "telex/base/periodic.h"
#include "telex/base/spsc_ring.h"
#include "telex/base/triple_buffer.h"
#include "telex/common/head_kinematics.h"
#include "telex/common/opencv_workers.h"
#include "telex/local/deadman.h"
#include "telex/local/frame_assembler.h"
#include "telex/local/operator_view.h"
#include "telex/local/stereo_view.h"
#include "telex/local/view_window.h"

namespace telex::local {
namespace {

using std::chrono::milliseconds;

// What the haptic thread reports per tick; trivially copyable so the ring never allocates.
struct TickSample {
  std::int64_t t_ns = 0;
  std::int64_t deadline_ns = 0;  // the timer's deadline this tick waited for
  std::int64_t period_ns = 0;
  std::uint64_t surface_frame = 0;
  std::int64_t surface_capture_ns = 0;  // remote clock; 0 = no surface yet
  std::array<FingertipForce, kFingerCount> forces{};
  std::array<bool, kFingerCount> tracked{};
  std::array<glm::dvec3, kFingerCount> p_CameraFingertip{};
  std::array<glm::dvec3, kFingerCount> axis_Camera{};
};

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

// On a screen (--view window | hmd) the stereo pair is drawn at video rate (the synthetic and V4L2
// stereo sources send 30 fps); into PNGs once a second.
constexpr std::int64_t kOnScreenViewPeriodNs = 33'333'333;

// What the window shows until the first pair: the same text in both eyes.
cv::Mat3b waiting_image(const std::string& remote) {
  cv::Mat3b img(480, 1280, cv::Vec3b(40, 40, 40));
  const std::string text = "waiting for the remote at " + remote;
  for (const int x0 : {0, 640})
    cv::putText(img, text, {x0 + 40, 240}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {230, 230, 230}, 1,
                cv::LINE_AA);
  return img;
}

const char* kFingerNames[kFingerCount] = {"thumb", "index", "middle", "ring", "little"};

cv::Rect grow_rect(const cv::Rect& r, int margin) {
  return {r.x - margin, r.y - margin, r.width + 2 * margin, r.height + 2 * margin};
}

bool all_finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

Station::Station(StationConfig config) : cfg_(std::move(config)) {
  cfg_.haptic.validate();
  if (!(cfg_.rate_hz >= 10 && cfg_.rate_hz <= 10000))
    throw std::invalid_argument("haptic rate must be within 10..10000 Hz");
  if (cfg_.log_every < 1) throw std::invalid_argument("--log-every must be >= 1");
  ViewSpec::parse(cfg_.view_spec);
  if (cfg_.head_teleop) check_head_axes(cfg_.robot_head);
  if (!(cfg_.head_rate_hz >= 1.0 && cfg_.head_rate_hz <= 1000.0))
    throw std::invalid_argument("--head-rate must be within 1..1000 Hz");
  if (!cfg_.deadman_spec.empty()) {
    (void)parse_deadman_spec(cfg_.deadman_spec);
    if (!cfg_.head_teleop)
      throw std::invalid_argument(
          "--deadman gates head teleoperation, which --no-head turns off: drop one of them");
  }
}

Station::~Station() = default;

// One run of the station. The threads are the last members: destroying a Run (on a normal return
// or while an exception unwinds) first stops and joins them, then stops the network client, then
// the zero-force guard commands zero force, then the display closes.
class Station::Run {
 public:
  Run(const StationConfig& cfg, std::atomic<bool>& stop);
  StationSummary execute();

 private:
  void surface_loop(std::stop_token stop);
  void haptic_loop(std::stop_token stop);
  void haptic_ticks(std::stop_token stop);
  bool wait_first_surface();
  void start_haptics();
  void main_loop();
  bool pump_window();
  void stop_threads();
  void drain();
  void drain_tracking();
  void print_status();
  std::string status_text(double fps);
  cv::Mat3b render_view();
  // Eye 0 (left) or 1 (right): the received frame captured nearest to `want_capture_ns` (0: the
  // newest), decoded; *offset_ns is its capture time minus the one wanted.
  cv::Mat3b eye_image(int eye, std::int64_t want_capture_ns = 0, std::int64_t* offset_ns = nullptr);
  void request_stereo_view();
  void write_view_files(bool at_moment = false);
  void stereo_loop(std::stop_token stop);
  // The fingertips of `hand` moved into the camera `frame` was captured with (head teleoperation).
  void in_frame_camera(const AssembledFrame& frame, HandState& hand) const {
    if (!cfg_.head_captured_pose || !frame.head.valid || !hand.head_valid) return;
    to_capture_camera(capture_correction(cfg_.robot_head, hand, true,
                                         {frame.head.joint_rad[0], frame.head.joint_rad[1],
                                          frame.head.joint_rad[2]}),
                      hand);
  }
  // The operator's head to the remote as joint targets, at most head_rate_hz (main thread), with
  // the tracking sample's id and true age and the dead-man's state.
  void send_head(std::int64_t now_ns);
  std::int64_t next_head_ns_ = 0;
  StationSummary summarize();
  // A thread's error: logged once, the first one kept (run() rethrows it as a
  // StationThreadError naming `thread`), and the station stops.
  void fail(const std::string& thread, std::exception_ptr error);
  // The threads the station does not run itself (network client, tracker and gloves, display
  // writer, recorder): each stops on an exception and keeps it; the main thread polls them here
  // and fails the station on the first. True when one has failed.
  bool poll_thread_faults();
  std::array<bool, 4> fault_reported_{};
  void check(StationLoop loop) const {
    if (cfg_.fault_hook) cfg_.fault_hook(loop);
  }

  const StationConfig& cfg_;
  std::atomic<bool>& stop_;
  const std::int64_t t_start_ns_ = monotonic_ns();
  const std::int64_t period_ns_;
  // The display channel each finger drives (the rig's, for the haptic hand's side).
  const std::array<int, kFingerCount> channel_ =
      cfg_.display_channel[index_of(cfg_.tracker.use_left_hand ? Side::Left : Side::Right)];

  // ---- outputs, opened first so a bad device or path fails before anything connects ----
  std::unique_ptr<HapticDisplay> display_;
  ZeroForceOnExit display_zero_;
  std::ofstream forces_csv_;
  std::ofstream tracking_csv_;
  std::unique_ptr<SessionRecorder> recorder_;  // --record; finished after the threads stop
  const ViewSpec view_;
  // --view window | hmd: GLFW's window, used on this (the main) thread only; opened before
  // anything connects, so a missing display or an unknown monitor stops the start.
  std::unique_ptr<ViewWindow> window_;
  // --deadman: opened here too, so a missing device stops the start; read by the main thread.
  std::unique_ptr<DeadmanInput> deadman_;

  // ---- network thread (inside SurfaceClient): tiles -> frames ----
  FrameAssembler assembler_;
  LatestSlot<AssembledFrame> frames_;
  std::latch surface_ready_{1};  // the surface thread's warm-up is done
  std::int64_t transit_ns_ = 0;  // smoothed capture-to-manifest time (network thread)
  std::mutex watch_mu_;
  std::vector<cv::Rect> watch_rects_;  // the fingertip windows as read (surface -> network)
  std::mutex video_mu_;
  struct EyeFrame {
    std::int64_t capture_ns = 0;  // sender clock, as the depth frames'
    std::vector<std::uint8_t> jpeg;
  };
  std::array<std::deque<EyeFrame>, 2> eye_frames_;  // by eye (0 left, 1 right): the last 8

  // ---- surface thread -> haptic thread and view ----
  TripleBuffer<std::shared_ptr<const Surface>> surfaces_;
  TripleBuffer<HandState> hand_for_surface_, hand_for_view_;
  // The operator's head (haptic thread -> main thread's head sender): one per tracker frame that
  // held the head body, numbered, stamped when the tracker delivered it.
  struct HeadSample {
    std::int64_t time_ns = 0;
    std::uint32_t id = 0;
    glm::dmat3 R_BaseCamera{1.0};
  };
  TripleBuffer<HeadSample> head_for_main_;
  std::uint32_t head_samples_ = 0;  // haptic thread
  HeadSample head_sample_;          // main thread
  std::atomic<std::uint64_t> surfaces_built_{0};
  std::atomic<double> first_centre_depth_m_{0.0};
  std::atomic<double> build_ms_{0.0};
  // Where a new capture's latency goes (surface thread; read after it is joined): capture to
  // the frame's manifest on the station (remote processing + network), and from there to the
  // surface's publication (queue + build).
  Histogram arrive_ms_{0.1, 20'000}, build_wait_ms_{0.1, 20'000};
  std::mutex view_mu_;
  std::shared_ptr<const Surface> view_surface_;
  cv::Mat1w view_depth_;

  // ---- haptic thread -> main thread ----
  std::unique_ptr<HandTracker> tracker_;
  HapticModel model_;
  SpscRing<TickSample> samples_;
  SpscRing<HandState> tracking_;
  std::string scheduling_;
  std::atomic<bool> scheduling_ready_{false};
  std::atomic<std::uint64_t> missed_{0};
  std::atomic<std::int64_t> haptic_t0_ns_{0};  // the first tick: a hand script's time zero

  std::mutex error_mu_;
  std::exception_ptr error_;

  // ---- main thread's statistics, in fixed memory so a long run's resident size stays flat ----
  StationSummary summary_;
  Histogram period_us_{1.0, 20'000}, jitter_us_{1.0, 20'000}, latency_ms_{0.1, 20'000},
      contact_latency_ms_{0.1, 20'000};
  std::vector<std::int64_t> window_periods_;
  std::vector<double> window_latency_;
  TickSample last_{};
  std::uint64_t tick_index_ = 0;
  std::int64_t first_deadline_ns_ = 0;
  std::uint64_t last_latency_frame_ = 0;
  std::int64_t last_latency_capture_ = 0;
  std::int64_t next_print_ns_ = 0;
  std::uint64_t surfaces_at_last_status_ = 0;
  std::string last_status_ = "starting";
  int statuses_since_insecure_warning_ = 0;  // print_status runs once a second
  HandState view_hand_{};

  // ---- last: stopped and joined first on destruction ----
  std::unique_ptr<SurfaceClient> client_;
  std::jthread surface_thread_;
  std::jthread haptic_thread_;
  // The view thread (--view png:DIR | window | hmd), last: it reads the members above until it is
  // joined. On a screen it hands each side-by-side pair to the main thread's window, newest wins.
  LatestSlot<cv::Mat3b> sbs_for_window_;
  std::mutex stereo_mu_;
  std::condition_variable_any stereo_cv_;
  struct StereoRequest {
    HandState hand{};
    std::array<FingertipForce, kFingerCount> forces{};
    std::string status;
    bool pending = false;
  } stereo_request_;             // guarded by stereo_mu_
  bool warned_one_eye_ = false;  // view thread
  std::jthread stereo_thread_;
};

namespace {

std::ofstream open_csv(const std::filesystem::path& path, const char* flag, const char* header) {
  std::ofstream out;
  if (path.empty()) return out;
  out.open(path);
  if (!out)
    throw std::runtime_error(std::string("cannot write ") + flag + " file " + path.string());
  out << header;
  return out;
}

std::unique_ptr<SessionRecorder> open_recorder(const StationConfig& cfg) {
  if (cfg.record_bag.empty()) return nullptr;
  RecorderConfig rc;
  rc.path = cfg.record_bag.string();
  rc.force_rate_hz = cfg.record_rate_hz;
  rc.tick_rate_hz = cfg.rate_hz;
  rc.monotonic_to_bag_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count() -
                           monotonic_ns();
  auto j = session_config_json(cfg.haptic, cfg.surface, cfg.rate_hz);
  j["station"] = {{"hand", cfg.hand_spec},
                  {"haptics", cfg.haptics_spec},
                  {"remote", cfg.client.host + ":" + std::to_string(cfg.client.port)},
                  {"max_tile_age_s", cfg.max_tile_age_s}};
  rc.config_json = j.dump();
  return std::make_unique<SessionRecorder>(std::move(rc));
}

}  // namespace

Station::Run::Run(const StationConfig& cfg, std::atomic<bool>& stop)
    : cfg_(cfg),
      stop_(stop),
      period_ns_(static_cast<std::int64_t>(std::llround(1e9 / cfg.rate_hz))),
      display_(make_display(cfg.haptics_spec, cfg.display)),
      display_zero_(*display_),
      forces_csv_(open_csv(cfg.log_forces_csv, "--log-forces",
                           "time_s,finger,pressure_N,shear_N,contact,fx_N,fy_N,fz_N,penetration_m,"
                           "status,x_m,y_m,z_m,surface_frame,surface_capture_ns\n")),
      tracking_csv_(open_csv(cfg.log_tracking_csv, "--log-tracking",
                             "time_s,body_id,x_m,y_m,z_m,qx,qy,qz,qw,valid\n")),
      recorder_(open_recorder(cfg)),
      view_(ViewSpec::parse(cfg.view_spec)),
      window_(view_.on_screen() ? std::make_unique<ViewWindow>(view_) : nullptr),
      deadman_(cfg.deadman_spec.empty() || !cfg.head_teleop
                   ? nullptr
                   : open_deadman(parse_deadman_spec(cfg.deadman_spec))),
      assembler_(static_cast<std::int64_t>(cfg.max_tile_age_s * 1e9)),
      model_(cfg.haptic, kFingerCount),
      samples_(1 << 14),
      tracking_(tracking_csv_.is_open() || recorder_ ? 1024 : 1) {
  if (view_.kind == ViewSpec::Kind::Png) std::filesystem::create_directories(view_.dir);
  if (deadman_)
    std::fprintf(stderr, "telex-local: dead-man %s: the robot head moves only while it is held\n",
                 deadman_->name().c_str());
  if (window_) {
    const MonitorInfo& m = window_->monitor();
    std::fprintf(stderr, "telex-local: view %s on monitor '%s' (%dx%d at %d,%d), %s\n",
                 view_.kind == ViewSpec::Kind::Hmd ? "full screen" : "in a window", m.name.c_str(),
                 m.rect.width, m.rect.height, m.rect.x, m.rect.y, window_->gl_renderer().c_str());
    window_->show(waiting_image(cfg.client.host + ":" + std::to_string(cfg.client.port)));
  }
}

StationSummary Station::Run::execute() {
  ClientEvents events;
  events.on_config = [this](const proto::StreamConfig& c) { assembler_.configure(c); };
  events.on_tile = [this](const proto::Header& h, const proto::DepthTile& t) {
    const std::int64_t now = monotonic_ns();
    assembler_.apply_tile(h, t, now);
    // A repaired tile under a fingertip rebuilds the surface at once, not at the next frame.
    if (h.flags & proto::kFlagRepair)
      if (auto f = assembler_.take_repaired(now)) frames_.put(std::move(*f));
  };
  events.on_manifest = [this](const proto::Header& h, const proto::FrameManifest& m) {
    check(StationLoop::Network);
    const std::int64_t now = monotonic_ns();
    {
      std::lock_guard lock(watch_mu_);
      assembler_.set_watched(watch_rects_);
    }
    if (auto f = assembler_.finish(h, m, now)) {
      const std::int64_t transit = now - (f->capture_ns - client_->stats().clock_offset_ns.load());
      transit_ns_ = transit_ns_ == 0 ? transit : (7 * transit_ns_ + transit) / 8;
      frames_.put(std::move(*f));
    }
    if (!cfg_.client.repair) return;
    // Ask again only once the answer had time to come: the stream's transit and a round trip.
    const std::int64_t retry_ns =
        std::max(static_cast<std::int64_t>(cfg_.nack_retry_min_s * 1e9),
                 std::max<std::int64_t>(transit_ns_, 0) + 2 * client_->stats().rtt_ns.load());
    const RepairRequest r = assembler_.repair_request(
        now, retry_ns, static_cast<std::int64_t>(cfg_.key_request_interval_s * 1e9));
    if (r.nack) client_->send_nack(*r.nack);
    if (r.key_frame) client_->request_key_frame();
  };
  events.on_video = [this](const proto::Header& h, const proto::VideoFrame& v) {
    std::lock_guard lock(video_mu_);
    auto& q = eye_frames_[v.eye == 0 ? 0 : 1];
    q.push_back({static_cast<std::int64_t>(h.capture_ns), v.jpeg});
    if (q.size() > 8) q.pop_front();
  };
  events.on_state = [](ClientState s, const std::string& why) {
    std::fprintf(stderr, "telex-local: remote %s: %s\n", std::string(to_string(s)).c_str(),
                 why.c_str());
  };
  events.on_warning = [](const std::string& what) {
    std::fprintf(stderr, "telex-local: %s\n", what.c_str());
  };
  start_opencv_workers();  // from this thread, so they never inherit the depth path's priority
  ClientConfig client_cfg = cfg_.client;
  client_cfg.want_video = client_cfg.want_video || view_.stereo();
  // The path from a depth capture to the force runs above everything else on this machine
  // (periodic.h has the priorities and what they bought).
  const int path_priority = cfg_.realtime ? kStationPathPriority : 0;
  client_cfg.realtime_priority = path_priority;
  client_ = std::make_unique<SurfaceClient>(client_cfg, std::move(events));
  if (view_.stereo())
    stereo_thread_ = std::jthread([this](std::stop_token st) { stereo_loop(st); });
  // The surface thread warms its buffers before the first frame can arrive.
  surface_thread_ = std::jthread([this](std::stop_token st) { surface_loop(st); });
  name_thread(surface_thread_.native_handle(), "telex-surface");
  summary_.thread_scheduling.emplace_back(
      "surface", try_realtime(surface_thread_.native_handle(), path_priority));
  surface_ready_.wait();
  client_->start();
  summary_.thread_scheduling.emplace_back("network", client_->scheduling());

  if (wait_first_surface()) {
    start_haptics();  // a bad tracker spec or device is a start-up error, thrown as it is
    try {
      main_loop();
    } catch (...) {
      fail("main", std::current_exception());
    }
  }
  stop_threads();
  poll_thread_faults();  // one that failed while the others stopped
  if (window_)
    std::fprintf(stderr,
                 "telex-local: view window: %llu stereo pairs shown, %llu replaced by a newer one "
                 "before the window drew them, %llu redraws\n",
                 static_cast<unsigned long long>(window_->images_uploaded()),
                 static_cast<unsigned long long>(sbs_for_window_.dropped()),
                 static_cast<unsigned long long>(window_->frames_shown()));
  if (error_) std::rethrow_exception(error_);
  return summarize();
}

void Station::Run::fail(const std::string& thread, std::exception_ptr error) {
  const std::string what = ThreadFaultReport{thread, error}.what();
  std::fprintf(stderr,
               "telex-local: the %s thread failed: %s; stopping the station with zero force\n",
               thread.c_str(), what.c_str());
  {
    std::lock_guard lock(error_mu_);
    if (!error_) error_ = std::make_exception_ptr(StationThreadError(thread, what));
  }
  stop_.store(true);
}

bool Station::Run::poll_thread_faults() {
  const auto poll = [&](std::size_t i, std::optional<ThreadFaultReport> f) {
    if (!f || fault_reported_[i]) return;
    fault_reported_[i] = true;
    fail(f->thread, f->error);
  };
  if (client_) poll(0, client_->thread_fault());
  if (tracker_) poll(1, tracker_->thread_fault());
  poll(2, display_->thread_fault());
  if (recorder_) poll(3, recorder_->thread_fault());
  return std::find(fault_reported_.begin(), fault_reported_.end(), true) != fault_reported_.end();
}

// ---- surface thread: frames -> snapshots for the haptic loop ----
void Station::Run::surface_loop(std::stop_token stop) {
  struct Ready {  // execute() connects once the warm-up is done, or failed
    std::latch& latch;
    bool done = false;
    void count_down() {
      if (!std::exchange(done, true)) latch.count_down();
    }
    ~Ready() { count_down(); }
  } ready{surface_ready_};
  try {
    // Snapshots the haptic loop may still hold are released here, never on the 1 kHz thread.
    std::deque<std::shared_ptr<const Surface>> retired;
    // Snapshot buffers are recycled once nobody holds them (more than the retired ones + the
    // triple buffer's + the view's), so a frame neither allocates nor zeroes ~5 MB.
    SurfacePool pool(16);
    {
      // The first frames must not pay for first use: the pool's pages are made resident and one
      // build runs on a plane at the stream's usual size (the pool drops them if it differs).
      // Measured: the first builds with a fingertip window took 2.5-6.8 ms instead of 0.3.
      const cv::Size usual(640, 480);
      pool.warm(usual);
      AssembledFrame plane;
      plane.depth_mm = cv::Mat1w(usual, std::uint16_t{1000});
      plane.intrinsics = kinect_v1_intrinsics(usual.width, usual.height);
      const std::vector<cv::Rect> whole{cv::Rect(cv::Point(0, 0), usual)};
      build_surface(plane, cfg_.surface, whole);
    }
    ready.count_down();
    HandState hand{};
    std::vector<cv::Rect> last_windows;
    std::uint64_t surface_seq = 0;
    std::int64_t built_capture_ns = -1;
    // How far outside a window the filter and the normals read.
    const int reach_px =
        cfg_.surface.bilateral_options.radius_px + cfg_.surface.normal_options.smooth_radius_px + 1;
    while (!stop.stop_requested()) {
      auto frame = frames_.take(milliseconds(50));
      if (!frame) continue;
      check(StationLoop::Surface);
      // The rest of a frame whose ROI part is already built: rebuild only when it changed pixels
      // the surface's windows (or the filter reading around them) use.
      if ((frame->part == AssembledPart::Rest || frame->part == AssembledPart::Repair) &&
          frame->capture_ns == built_capture_ns && cfg_.surface.roi) {
        hand_for_surface_.take(hand);
        in_frame_camera(*frame, hand);
        const auto windows =
            fingertip_windows(hand, frame->depth_mm, frame->intrinsics, cfg_.surface);
        bool touches = windows != last_windows;
        for (const auto& w : windows)
          for (const auto& c : frame->changed_since_roi_part)
            touches = touches || (grow_rect(w, reach_px) & c).area() > 0;
        if (!touches) {
          std::lock_guard lock(view_mu_);
          view_depth_ = frame->depth_mm;
          continue;
        }
      }
      built_capture_ns = frame->capture_ns;
      // Snapshot ids are the station's own sequence: a restarted remote numbers its frames from
      // the start again, and the haptic model ignores snapshots that go backwards.
      frame->frame_id = static_cast<std::uint32_t>(++surface_seq);
      hand_for_surface_.take(hand);
      in_frame_camera(*frame, hand);
      std::vector<cv::Rect> windows =
          fingertip_windows(hand, frame->depth_mm, frame->intrinsics, cfg_.surface);
      {
        // The tiles the network thread repairs first: what these windows' surface reads.
        std::lock_guard lock(watch_mu_);
        watch_rects_.clear();
        for (const auto& w : windows) watch_rects_.push_back(grow_rect(w, reach_px));
      }
      if (!cfg_.surface.roi) windows.clear();
      SurfaceBuildStats st;
      const std::int64_t built_ns = monotonic_ns();
      std::shared_ptr<Surface> built = build_surface(*frame, cfg_.surface, windows, &st, &pool);
      // With the head's pose at capture, the haptic model works in the head base's frame, where
      // the room stays put while the head turns (its god-points and its crossfade between two
      // surfaces then agree).
      built->R_ModelCamera = cfg_.head_captured_pose && built->head_valid
                                 ? head_rotation(cfg_.robot_head, built->head_joint_rad)
                                 : glm::dmat3(1.0);
      std::shared_ptr<const Surface> s = std::move(built);
      build_ms_.store(st.snapshot_ms + st.filter_ms + st.normals_ms);
      if (surfaces_built_.load() == 0) first_centre_depth_m_.store(centre_depth_m(frame->depth_mm));
      surfaces_.publish(s);
      if (recorder_)
        recorder_->add_surface(
            {surface_seq, built_ns, frame->capture_ns, frame->depth_mm.clone(), frame->intrinsics});
      retired.push_back(s);
      if (retired.size() > 8) retired.pop_front();
      surfaces_built_.fetch_add(1);
      if (frame->part != AssembledPart::Repair) {
        const std::int64_t offset = client_->stats().clock_offset_ns.load();
        arrive_ms_.add(static_cast<double>(frame->received_ns - (frame->capture_ns - offset)) /
                       1e6);
        build_wait_ms_.add(static_cast<double>(monotonic_ns() - frame->received_ns) / 1e6);
      }
      {
        std::lock_guard lock(view_mu_);
        view_surface_ = s;
        view_depth_ = frame->depth_mm;
      }
      if (cfg_.roi_requests && cfg_.surface.roi && windows != last_windows) {
        proto::RoiRequest roi;
        for (const auto& r : windows) {
          if (roi.rects.size() >= proto::kMaxRoiRects) break;
          roi.rects.push_back({static_cast<std::uint16_t>(r.x), static_cast<std::uint16_t>(r.y),
                               static_cast<std::uint16_t>(r.width),
                               static_cast<std::uint16_t>(r.height), 1});
        }
        client_->request_roi(roi);
        last_windows = windows;
      }
    }
  } catch (...) {
    fail("surface (telex-surface)", std::current_exception());
  }
}

// Waits for the first surface (scripted hands aim at it). False when the station was stopped
// first; throws when none arrives in time.
bool Station::Run::wait_first_surface() {
  // --duration bounds the whole run, connected or not.
  const bool duration_first = cfg_.duration_s > 0 && cfg_.duration_s < cfg_.first_surface_timeout_s;
  const double wait_s = duration_first ? cfg_.duration_s : cfg_.first_surface_timeout_s;
  const std::int64_t deadline =
      (duration_first ? t_start_ns_ : monotonic_ns()) + static_cast<std::int64_t>(wait_s * 1e9);
  while (surfaces_built_.load() == 0 && !stop_.load()) {
    if (poll_thread_faults()) break;
    if (window_ && pump_window()) break;
    if (monotonic_ns() > deadline) {
      const auto& cs = client_->stats();
      if (cs.auth_failed.load() > 0)
        throw std::runtime_error(
            "no depth surface from the remote at " + cfg_.client.host + ":" +
            std::to_string(cfg_.client.port) + ": authentication failed (" +
            std::to_string(cs.auth_failed.load()) +
            " TLS handshake(s) or datagram(s) refused; see the lines above): start both daemons "
            "with the same --psk FILE (or certificates from one CA), or neither");
      throw std::runtime_error(
          "no depth surface from the remote at " + cfg_.client.host + ":" +
          std::to_string(cfg_.client.port) + " within " + fmt::format("{:g}", wait_s) + " s" +
          (duration_first ? " (--duration)" : "") +
          ": is telex-remote running and listening there (telex-remote --listen HOST:PORT)?");
    }
    std::this_thread::sleep_for(milliseconds(10));
  }
  return !stop_.load();
}

void Station::Run::start_haptics() {
  TrackerConfig tracker_cfg = cfg_.tracker;
  tracker_cfg.realtime_priority = cfg_.realtime ? kStationPathPriority : 0;
  if (first_centre_depth_m_.load() > 0) tracker_cfg.surface_depth_m = first_centre_depth_m_.load();
  if (cfg_.fault_hook) tracker_cfg.natnet_receive_hook = [this] { check(StationLoop::Tracking); };
  tracker_ = make_tracker(cfg_.hand_spec, tracker_cfg);
  std::fprintf(stderr, "telex-local: surface at %.3f m ahead; hand %s; haptics %s\n",
               tracker_cfg.surface_depth_m, tracker_->name().c_str(), display_->name().c_str());
  haptic_thread_ = std::jthread([this](std::stop_token st) { haptic_loop(st); });
  name_thread(haptic_thread_.native_handle(), "telex-haptic");
  while (!scheduling_ready_.load()) std::this_thread::sleep_for(milliseconds(1));
  summary_.scheduling = scheduling_;
  summary_.thread_scheduling.emplace_back("haptic", scheduling_);
  if (const std::string t = tracker_->scheduling(); !t.empty())
    summary_.thread_scheduling.emplace_back("tracking", t);
  std::string path;
  for (const auto& [name, how] : summary_.thread_scheduling)
    if (name != "haptic") path += (path.empty() ? "" : ", ") + name + " " + how;
  std::fprintf(stderr, "telex-local: depth-to-force path: %s\n", path.c_str());
  std::fprintf(stderr, "telex-local: haptic loop at %.0f Hz, %s\n", cfg_.rate_hz,
               scheduling_.c_str());
}

// ---- haptic thread: no lock, allocation or log call per tick ----
void Station::Run::haptic_loop(std::stop_token stop) {
  scheduling_ = try_realtime(cfg_.realtime ? kHapticPriority : 0);
  scheduling_ready_.store(true);
  try {
    haptic_ticks(stop);
  } catch (...) {
    fail("haptic (telex-haptic)", std::current_exception());
  }
  // Release the device: zero force on every finger (the guard does it again after the join).
  display_zero_.release();
}

void Station::Run::haptic_ticks(std::stop_token stop) {
  PeriodicTimer timer(period_ns_);
  std::shared_ptr<const Surface> newest;
  HandState hand{};
  std::array<FingertipInput, kFingerCount> in{};
  std::array<FingertipForce, kFingerCount> out{};
  std::array<FingerForce, kFingerCount> shown{};
  TickSample sample{};
  std::int64_t prev = 0;
  const std::int64_t tracking_stale_ns = static_cast<std::int64_t>(cfg_.haptic.stale_limit_s * 1e9);
  while (!stop.stop_requested()) {
    const std::int64_t now = timer.wait_next();
    check(StationLoop::Haptic);
    if (prev == 0) haptic_t0_ns_.store(now, std::memory_order_release);
    if (tracker_->poll(now, hand)) {
      hand_for_surface_.publish(hand);
      hand_for_view_.publish(hand);
      // A new sample only from a new tracker frame that held the head: a glove's update or a
      // frame without the head body repeats the last one, which then ages (PROTOCOL.md 2.6).
      if (hand.head_valid && hand.bodies_fresh)
        head_for_main_.publish({hand.time_ns, ++head_samples_, hand.R_BaseCamera});
      if (hand.bodies_fresh && hand.body_count > 0) tracking_.push(hand);
    }
    surfaces_.take(newest);
    const bool fresh = now - hand.time_ns <= tracking_stale_ns;
    // The model's frame: the head base's when the surface carries the head's pose at capture
    // (the robot head lags the operator's; each surface is placed by its own pose), else the
    // camera's. The fingertips go there from the camera of the operator's head; a hand without a
    // head (scripted) is taken to be in the newest surface's camera.
    const bool in_base = cfg_.head_captured_pose && hand.head_valid && newest && newest->head_valid;
    const glm::dmat3 to_model =
        in_base ? hand.R_BaseCamera : (newest ? newest->R_ModelCamera : glm::dmat3(1.0));
    for (int i = 0; i < kFingerCount; ++i) {
      const auto& tip = hand.tips[static_cast<std::size_t>(i)];
      // The tracker's poses are checked; a fingertip that still is not finite is not touched,
      // and its value never reaches the model's state.
      if (!all_finite(tip.p_CameraFingertip) || !all_finite(tip.axis_Camera)) {
        in[static_cast<std::size_t>(i)] = {glm::dvec3(0.0), glm::dvec3(0.0, 0.0, 1.0), false};
        continue;
      }
      in[static_cast<std::size_t>(i)] = {to_model * tip.p_CameraFingertip,
                                         to_model * tip.axis_Camera, tip.valid && fresh};
    }
    model_.tick(now, newest, in, out);
    // Logs, recording and view take the tick re-expressed in the newest surface's camera.
    const glm::dmat3 from_model = newest ? glm::transpose(newest->R_ModelCamera) : glm::dmat3(1.0);
    if (newest && newest->R_ModelCamera != glm::dmat3(1.0)) reexpress(from_model, out);
    for (int i = 0; i < kFingerCount; ++i) {
      const auto& f = out[static_cast<std::size_t>(i)];
      shown[static_cast<std::size_t>(i)] = {channel_[static_cast<std::size_t>(i)], f.normal_force_N,
                                            f.shear_along_axis_N, f.contact};
    }
    display_->write(now, shown);
    sample.t_ns = now;
    sample.deadline_ns = timer.deadline_ns();
    sample.period_ns = prev ? now - prev : period_ns_;
    prev = now;
    sample.surface_frame = newest ? newest->frame_id : 0;
    sample.surface_capture_ns = newest ? newest->capture_ns : 0;
    sample.forces = out;
    for (int i = 0; i < kFingerCount; ++i) {
      sample.tracked[static_cast<std::size_t>(i)] = in[static_cast<std::size_t>(i)].tracked;
      sample.p_CameraFingertip[static_cast<std::size_t>(i)] =
          from_model * in[static_cast<std::size_t>(i)].p_ModelFingertip;
      sample.axis_Camera[static_cast<std::size_t>(i)] =
          from_model * in[static_cast<std::size_t>(i)].axis_Model;
    }
    samples_.push(sample);
    missed_.store(timer.missed(), std::memory_order_relaxed);
  }
}

// ---- main thread: drain samples, log, print, view ----
void Station::Run::main_loop() {
  const std::int64_t end_ns =
      cfg_.duration_s > 0 ? t_start_ns_ + static_cast<std::int64_t>(cfg_.duration_s * 1e9) : 0;
  std::int64_t next_status = monotonic_ns() + 1'000'000'000;
  std::int64_t next_view = 0;
  next_print_ns_ = monotonic_ns();
  bool view_at_written = false;
  while (!stop_.load()) {
    std::this_thread::sleep_for(milliseconds(5));
    check(StationLoop::Main);
    if (poll_thread_faults()) break;
    if (window_) {
      if (monotonic_ns() >= next_view) {
        next_view = monotonic_ns() + kOnScreenViewPeriodNs;
        request_stereo_view();
      }
      if (pump_window()) break;
    }
    drain();
    drain_tracking();
    const std::int64_t now = monotonic_ns();
    send_head(now);
    if (cfg_.view_at_s >= 0.0 && !view_at_written) {
      const std::int64_t t0 = haptic_t0_ns_.load(std::memory_order_acquire);
      if (t0 != 0 && now >= t0 + static_cast<std::int64_t>(cfg_.view_at_s * 1e9)) {
        view_at_written = true;
        write_view_files(true);
      }
    }
    if (end_ns && now >= end_ns) break;
    if (now >= next_status) {
      next_status += 1'000'000'000;
      print_status();
    }
  }
  // The last picture shows how the run ended, not how it stood at the last whole second.
  drain();
  write_view_files();
  if (cfg_.view_at_s >= 0.0 && !view_at_written)
    std::fprintf(stderr,
                 "telex-local: warning: --view-at %g s: the run ended before that moment; no "
                 "view written\n",
                 cfg_.view_at_s);
}

// The window's turn on the main thread: the newest stereo pair when one came, else the window's
// events (and a redraw when it was uncovered or resized). True once the operator closed it (Esc
// or the window's close button): the station then stops as on a signal.
bool Station::Run::pump_window() {
  if (auto sbs = sbs_for_window_.take(milliseconds(0)))
    window_->show(*sbs);
  else
    window_->refresh();
  if (!window_->should_close()) return false;
  if (!stop_.exchange(true))
    std::fprintf(stderr, "telex-local: the view window was closed: stopping\n");
  return true;
}

void Station::Run::send_head(std::int64_t now_ns) {
  if (!cfg_.head_teleop || now_ns < next_head_ns_) return;
  next_head_ns_ = now_ns + static_cast<std::int64_t>(1e9 / cfg_.head_rate_hz);
  head_for_main_.take(head_sample_);
  if (head_sample_.time_ns == 0) return;  // no head tracked yet
  const auto q = head_joints(cfg_.robot_head, head_sample_.R_BaseCamera);
  // Never a non-finite target (the tracker's poses are checked; this is the last line): the
  // command is not built, and the remote holds the head as it does for a silent station.
  if (!std::all_of(q.begin(), q.end(),
                   [](double v) { return std::isfinite(static_cast<float>(v)); })) {
    ++summary_.head_commands_invalid;
    return;
  }
  proto::HeadCommand c;
  c.operator_ns = static_cast<std::uint64_t>(head_sample_.time_ns);
  for (std::size_t j = 0; j < 3; ++j) c.joint_rad[j] = static_cast<float>(q[j]);
  // The sample as it is: when tracking stops, the same id with a growing age, never restamped.
  c.sample_id = head_sample_.id;
  const std::int64_t age_us = std::max<std::int64_t>(0, now_ns - head_sample_.time_ns) / 1000;
  c.sample_age_us = static_cast<std::uint32_t>(std::min<std::int64_t>(age_us, 0xFFFFFFFF));
  c.deadman = deadman_ ? deadman_->poll() : proto::DeadmanState::NotUsed;
  client_->send_head(c);
  ++summary_.head_commands;
  if (age_us > 100'000) ++summary_.head_samples_stale;
  if (c.deadman == proto::DeadmanState::Released) ++summary_.head_deadman_released;
}

// Orderly end: the haptic thread first (it zeroes the display), then what it logged, then the
// surface thread and the network.
void Station::Run::stop_threads() {
  if (haptic_thread_.joinable()) {
    haptic_thread_.request_stop();
    haptic_thread_.join();
  }
  drain();
  drain_tracking();
  surface_thread_.request_stop();
  frames_.close();
  if (surface_thread_.joinable()) surface_thread_.join();
  client_->stop();
  if (stereo_thread_.joinable()) {
    stereo_thread_.request_stop();  // after drawing what is pending
    stereo_thread_.join();
  }
  if (forces_csv_.is_open()) forces_csv_.flush();
  if (recorder_) recorder_->finish();  // everything queued is written and the bag closed
}

void Station::Run::drain() {
  const std::int64_t print_period =
      cfg_.print_forces_hz > 0 ? static_cast<std::int64_t>(1e9 / cfg_.print_forces_hz) : 0;
  TickSample s{};
  while (samples_.pop(s)) {
    if (++tick_index_ == 1) first_deadline_ns_ = s.deadline_ns;
    last_ = s;
    if (recorder_) {
      RecordedTick t;
      t.t_ns = s.t_ns;
      t.surface_seq = s.surface_frame;
      for (std::size_t i = 0; i < kFingerCount; ++i)
        t.in[i] = {s.p_CameraFingertip[i], s.axis_Camera[i], s.tracked[i]};
      t.out = s.forces;
      recorder_->add_tick(t);
    }
    if (tick_index_ > 1) {
      period_us_.add(static_cast<double>(s.period_ns) / 1e3);
      jitter_us_.add(std::abs(static_cast<double>(s.period_ns - period_ns_)) / 1e3);
      window_periods_.push_back(s.period_ns);
    }
    // Capture-to-force latency: measured at the first tick that renders a newly arrived surface
    // of a new capture (a frame's rest rebuilding its surface is not a new capture).
    if (s.surface_capture_ns != 0 && s.surface_frame != last_latency_frame_ &&
        s.surface_capture_ns != last_latency_capture_) {
      last_latency_frame_ = s.surface_frame;
      last_latency_capture_ = s.surface_capture_ns;
      const std::int64_t offset = client_->stats().clock_offset_ns.load();
      const double lat = static_cast<double>(s.t_ns - (s.surface_capture_ns - offset)) / 1e6;
      latency_ms_.add(lat);
      window_latency_.push_back(lat);
      // The same, for surfaces first rendered while a finger touches them: the samples whose
      // force depends on the surface's age (a surface no fingertip is near renders 0 N at any
      // age; with --roi the remote then processes whole frames, not ROI parts).
      if (std::any_of(s.forces.begin(), s.forces.end(), [](const auto& f) { return f.contact; }))
        contact_latency_ms_.add(lat);
    }
    for (const auto& f : s.forces) {
      summary_.peak_pressure_N = std::max(summary_.peak_pressure_N, f.normal_force_N);
      summary_.peak_shear_N = std::max(summary_.peak_shear_N, std::abs(f.shear_along_axis_N));
    }
    if (forces_csv_.is_open() &&
        (tick_index_ - 1) % static_cast<std::uint64_t>(cfg_.log_every) == 0) {
      const double t = static_cast<double>(s.t_ns - t_start_ns_) / 1e9;
      for (int i = 0; i < kFingerCount; ++i) {
        if (!s.tracked[static_cast<std::size_t>(i)] &&
            !s.forces[static_cast<std::size_t>(i)].contact)
          continue;
        const auto& f = s.forces[static_cast<std::size_t>(i)];
        const auto& p = s.p_CameraFingertip[static_cast<std::size_t>(i)];
        char row[400];
        std::snprintf(row, sizeof row,
                      "%.6f,%s,%.6f,%.6f,%d,%.6f,%.6f,%.6f,%.6f,%s,%.6f,%.6f,%.6f,%llu,%lld\n", t,
                      kFingerNames[i], f.normal_force_N, f.shear_along_axis_N, f.contact ? 1 : 0,
                      f.force_N.x, f.force_N.y, f.force_N.z, f.penetration_m,
                      std::string(to_string(f.status)).c_str(), p.x, p.y, p.z,
                      static_cast<unsigned long long>(s.surface_frame),
                      static_cast<long long>(s.surface_capture_ns));
        forces_csv_ << row;
      }
    }
    if (print_period && s.t_ns >= next_print_ns_) {
      next_print_ns_ = s.t_ns + print_period;
      std::string line =
          "t=" + std::to_string(static_cast<double>(s.t_ns - t_start_ns_) / 1e9).substr(0, 6) + "s";
      for (int i = 0; i < kFingerCount; ++i) {
        const auto& f = s.forces[static_cast<std::size_t>(i)];
        if (!s.tracked[static_cast<std::size_t>(i)]) continue;
        char b[96];
        std::snprintf(b, sizeof b, "  %s P=%5.2fN S=%+5.2fN%s", kFingerNames[i], f.normal_force_N,
                      f.shear_along_axis_N, f.contact ? " contact" : "");
        line += b;
      }
      std::printf("%s\n", line.c_str());
      std::fflush(stdout);
    }
  }
}

void Station::Run::drain_tracking() {
  HandState state{};
  while (tracking_.pop(state)) {
    if (recorder_) recorder_->add_bodies(state);
    if (!tracking_csv_.is_open()) continue;
    const double t = static_cast<double>(state.time_ns - t_start_ns_) / 1e9;
    for (int b = 0; b < state.body_count; ++b) {
      const auto& body = state.bodies[static_cast<std::size_t>(b)];
      char row[256];
      std::snprintf(row, sizeof row, "%.6f,%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d\n", t, body.id,
                    body.p_m.x, body.p_m.y, body.p_m.z, body.q.x, body.q.y, body.q.z, body.q.w,
                    body.valid ? 1 : 0);
      tracking_csv_ << row;
    }
  }
}

// Once a second: the status line on stderr and the view PNG.
void Station::Run::print_status() {
  const std::uint64_t built = surfaces_built_.load();
  const double fps = static_cast<double>(built - surfaces_at_last_status_);
  surfaces_at_last_status_ = built;
  const std::string text = status_text(fps);
  if (cfg_.status_line) {
    std::string forces;
    for (int i = 0; i < kFingerCount; ++i) {
      if (!last_.tracked[static_cast<std::size_t>(i)]) continue;
      char b[48];
      std::snprintf(b, sizeof b, " %s %.2f/%+.2fN", kFingerNames[i],
                    last_.forces[static_cast<std::size_t>(i)].normal_force_N,
                    last_.forces[static_cast<std::size_t>(i)].shear_along_axis_N);
      forces += b;
    }
    std::fprintf(stderr, "telex-local: %s |%s%s\n", text.c_str(), forces.c_str(),
                 cfg_.insecure ? " | INSECURE link (--insecure)" : "");
  }
  if (cfg_.insecure && ++statuses_since_insecure_warning_ >= 60) {
    statuses_since_insecure_warning_ = 0;
    std::fprintf(stderr, "telex-local: warning: %s\n", proto::insecure_warning().c_str());
  }
  last_status_ = text;
  write_view_files();
  window_periods_.clear();
  window_latency_.clear();
}

// --view png:DIR: the 2D view now, the stereo pair on the view thread. With --view-at only the
// moment it names is written (`at_moment`), so the pictures show that moment of a scripted run.
void Station::Run::write_view_files(bool at_moment) {
  if (cfg_.view_at_s >= 0.0 && !at_moment) return;
  if (view_.kind == ViewSpec::Kind::Png) {
    const cv::Mat3b img = render_view();
    const auto path = view_.dir / "view.png";
    const auto tmp = view_.dir / "view.tmp.png";
    if (cv::imwrite(tmp.string(), img)) std::filesystem::rename(tmp, path);
    request_stereo_view();
  }
}

std::string Station::Run::status_text(double fps) {
  const auto ps = summarize_periods(window_periods_, period_ns_);
  char b[256];
  std::snprintf(b, sizeof b,
                "surface %.1f fps | latency %.1f ms | haptic %.1f Hz jitter p99 %.0f us | "
                "build %.1f ms | %s",
                fps, percentile(window_latency_, 0.5), ps.mean_rate_hz, ps.p99_jitter_us,
                build_ms_.load(), std::string(to_string(client_->state())).c_str());
  std::string text(b);
  if (tracker_) {
    // What the tracker's checks dropped, when they dropped anything (docs/HARDWARE.md).
    const TrackerStats t = tracker_->stats();
    const std::uint64_t rejected =
        t.rejected_nonfinite + t.rejected_quaternion + t.rejected_too_fast;
    if (t.foreign_datagrams + rejected > 0)
      text += " | tracking dropped " + std::to_string(t.foreign_datagrams) +
              " foreign datagrams, " + std::to_string(rejected) + " bad poses";
  }
  return text;
}

cv::Mat3b Station::Run::render_view() {
  ViewInputs vi;
  std::shared_ptr<const Surface> vs;
  {
    std::lock_guard lock(view_mu_);
    vs = view_surface_;
    vi.depth_mm = view_depth_;
  }
  vi.surface = vs.get();
  hand_for_view_.take(view_hand_);
  vi.hand = view_hand_;
  vi.forces = last_.forces;
  vi.status = last_status_;
  vi.camera_bgr = eye_image(1);
  return render_operator_view(vi);
}

cv::Mat3b Station::Run::eye_image(int eye, std::int64_t want_capture_ns, std::int64_t* offset_ns) {
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

// The main thread hands the stereo view what it knows (hand, forces, status): once a second for
// PNGs, at video rate for a window.
void Station::Run::request_stereo_view() {
  hand_for_view_.take(view_hand_);
  {
    std::lock_guard lock(stereo_mu_);
    stereo_request_.hand = view_hand_;
    stereo_request_.forces = last_.forces;
    stereo_request_.status = last_status_;
    stereo_request_.pending = true;
  }
  stereo_cv_.notify_one();
}

// ---- view thread (--view png:DIR | window | hmd): the stereo pair, off the main thread (and off
// the haptic one). Its headless EGL context is made while the station connects; a machine without
// EGL stops the station here, named. A window gets the pair through sbs_for_window_. ----
void Station::Run::stereo_loop(std::stop_token stop) {
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
      std::shared_ptr<const Surface> vs;
      {
        std::lock_guard lock(view_mu_);
        vs = view_surface_;
        in.depth_mm = view_depth_;
      }
      if (!vs) continue;  // no intrinsics before the first surface
      in.surface = vs.get();
      in.k = vs->intrinsics;
      in.baseline_m = cfg_.stereo_baseline_m;
      in.skin_bgr = cfg_.skin_bgr;
      // Each eye's frame captured nearest to the depth drawn over it; the larger gap is shown.
      std::int64_t gap_left = 0, gap_right = 0;
      in.eye_bgr = {eye_image(0, vs->capture_ns, &gap_left),
                    eye_image(1, vs->capture_ns, &gap_right)};
      if (!in.eye_bgr[0].empty() || !in.eye_bgr[1].empty()) {
        const double gap_ms =
            static_cast<double>(std::max(std::abs(gap_left), std::abs(gap_right))) / 1e6;
        char pairing[48];
        std::snprintf(pairing, sizeof pairing, " | eyes paired within %.1f ms", gap_ms);
        in.status += pairing;
      }
      const StereoViewImages v = view.render(in);
      if (v.one_eye && !warned_one_eye_) {
        std::fprintf(stderr,
                     "telex-local: the remote sends one eye's video only: the stereo view uses "
                     "it for both eyes\n");
        warned_one_eye_ = true;
      }
      if (view_.on_screen()) {
        sbs_for_window_.put(v.sbs);
        continue;
      }
      const std::filesystem::path& dir = view_.dir;
      for (const auto& [name, img] :
           {std::pair{"left", &v.left}, std::pair{"right", &v.right}, std::pair{"sbs", &v.sbs}}) {
        const auto tmp = dir / (std::string(name) + ".tmp.png");
        if (cv::imwrite(tmp.string(), *img))
          std::filesystem::rename(tmp, dir / (std::string(name) + ".png"));
      }
    }
  } catch (...) {
    fail("view (stereo)", std::current_exception());
  }
}

StationSummary Station::Run::summarize() {
  StationSummary s = summary_;
  s.ticks = tick_index_;
  s.haptic_rate_hz =
      period_us_.count() ? 1e6 * static_cast<double>(period_us_.count()) / period_us_.sum() : 0.0;
  s.period_p99_jitter_us = jitter_us_.quantile(0.99);
  s.period_median_us = period_us_.quantile(0.5);
  s.missed_ticks = missed_.load();
  s.nominal_rate_hz = cfg_.rate_hz;
  s.haptic_span_s =
      tick_index_ ? static_cast<double>(last_.deadline_ns - first_deadline_ns_) / 1e9 : 0.0;
  s.log_origin_monotonic_ns = t_start_ns_;
  if (tracker_) s.tracker = tracker_->stats();
  if (recorder_) {
    const RecorderStats r = recorder_->finish();
    s.record_ticks = r.ticks;
    s.record_surfaces = r.surfaces;
    s.record_body_frames = r.body_frames;
    s.record_dropped_ticks = r.dropped_ticks;
    s.record_dropped_surfaces = r.dropped_surfaces;
    s.record_dropped_bodies = r.dropped_bodies;
    s.record_error = r.error;
  }
  s.surfaces = surfaces_built_.load();
  s.frames = assembler_.counters().frames;  // the network thread has stopped
  s.roi_parts = assembler_.counters().roi_parts;
  s.latency_median_ms = latency_ms_.quantile(0.5);
  s.latency_p99_ms = latency_ms_.quantile(0.99);
  s.contact_latency_samples = contact_latency_ms_.count();
  s.contact_latency_median_ms = contact_latency_ms_.quantile(0.5);
  s.contact_latency_p99_ms = contact_latency_ms_.quantile(0.99);
  s.arrive_median_ms = arrive_ms_.quantile(0.5);
  s.arrive_p99_ms = arrive_ms_.quantile(0.99);
  s.build_wait_median_ms = build_wait_ms_.quantile(0.5);
  s.build_wait_p99_ms = build_wait_ms_.quantile(0.99);
  s.auth_failed = client_->stats().auth_failed.load();
  s.unsealed = client_->stats().unsealed.load();
  s.replayed = client_->stats().replayed.load();
  s.dropped_malformed = client_->stats().dropped_malformed.load();
  s.upstream_dropped = client_->stats().upstream_dropped.load();
  s.udp_datagrams = client_->stats().datagrams.load();
  s.udp_lost = client_->stats().udp_lost.load();
  s.bytes_in = client_->stats().bytes_in.load();
  const AssemblerCounters& ac = assembler_.counters();
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
  for (std::size_t n = 0; n < s.udp_messages_by_fragments.size(); ++n)
    s.udp_messages_by_fragments[n] = client_->stats().udp_messages_by_fragments[n].load();
  return s;
}

StationSummary Station::run() {
  Run run(cfg_, stop_);
  return run.execute();
}

}  // namespace telex::local
