// SPDX-License-Identifier: MIT
// The operator station: its parts wired together (station/), their threads and their lifetime.
// The surface stage (network events -> surfaces), the haptic loop, the view, the head sender, the
// run's log and statistics; the main thread polls faults, drains the haptic loop's samples and
// prints the status.
#include "telex/local/station/station.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <stop_token>
#include <thread>

#include "faults.h"
#include "haptic_loop.h"
#include "head_sender.h"
#include "input_watch.h"
#include "run_stats.h"
#include "session_log.h"
#include "station_view.h"
#include "surface_stage.h"
#include "telex/base/periodic.h"
#include "telex/base/realtime.h"
#include "telex/common/head_kinematics.h"
#include "telex/common/opencv_workers.h"
#include "telex/local/displays/display_registry.h"
#include "telex/local/displays/display_supervisor.h"
#include "telex/local/inputs/deadman.h"
#include "telex/local/inputs/tracker_registry.h"
#include "telex/local/view/openxr_output.h"

namespace telex::local {
namespace {

using std::chrono::milliseconds;

// On a screen (--view window | hmd) the stereo pair is asked for at the monitor's refresh rate
// (StationView::window_period_ns), whenever the last one is drawn; into PNGs once a second. An
// OpenXR view takes the newest body this often (the headset draws at its own rate).
constexpr std::int64_t kOnScreenViewPeriodNs = 33'333'333;
// The stereo view's niceness where the depth-to-force path runs without SCHED_FIFO.
constexpr int kViewNicenessBelowPath = 5;
// Authentication failures before the first surface that end the wait (they do not heal).
constexpr std::uint64_t kAuthFailuresToStop = 3;

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

// One run of the station: its parts, the network client and the threads. The threads are the last
// members: destroying a Run (on a normal return or while an exception unwinds) first stops and
// joins them, then stops the network client, then the zero-force guard commands zero force, then
// the display closes.
class Station::Run {
 public:
  Run(const StationConfig& cfg, std::atomic<bool>& stop);
  StationSummary execute();

 private:
  void connect();
  bool wait_first_surface();
  void make_tracker_now();
  // The tracker's inputs into tracker_inputs_, ten times a second.
  void watch_tracker_inputs();
  void start_haptics();
  void main_loop();
  void stop_threads();
  void drain();
  void drain_bodies();
  void drain_stage_poses();
  void print_status();
  void report_supervisor_zeroings();
  // The threads the station does not run itself (network client, tracker and gloves, display
  // writer, recorder): each stops on an exception and keeps it; the main thread polls them here
  // and fails the station on the first. True when one has failed.
  bool poll_thread_faults();
  // The headset's session ended by itself: the station stops as on a signal (`stop_` set).
  bool xr_ended();
  StationSummary summarize();

  const StationConfig& cfg_;
  std::atomic<bool>& stop_;
  const std::int64_t t_start_ns_ = monotonic_ns();
  StationFaults faults_;
  std::array<bool, 5> fault_reported_{};

  // ---- outputs, opened first so a bad device or path fails before anything connects ----
  std::unique_ptr<HapticDisplay> display_;
  ZeroForceOnExit display_zero_;
  SessionLog log_;
  StationView view_;
  HeadSender head_;

  // ---- the depth-to-force path ----
  SurfaceStage surface_;
  HapticLoop haptic_;

  // ---- main thread ----
  RunStats stats_;
  std::vector<std::pair<std::string, std::string>> thread_scheduling_;
  std::string haptic_scheduling_;
  std::uint64_t surfaces_at_last_status_ = 0;
  std::int64_t last_status_ns_ = 0;
  std::uint64_t eyes_at_last_status_ = 0;
  std::string last_status_ = "starting";
  InputWatch tracker_inputs_;
  std::int64_t next_input_watch_ns_ = 0;
  int statuses_since_insecure_warning_ = 0;  // print_status runs once a second
  std::uint64_t supervisor_zeroings_ = 0;

  // ---- last: stopped and joined first on destruction ----
  std::unique_ptr<SurfaceClient> client_;
  // Destroyed before client_: the view's eye decoder (a thread of view_, which outlives client_)
  // stops using the client before it goes.
  struct DetachView {
    StationView& view;
    ~DetachView() { view.detach(); }
  } detach_view_{view_};
  std::jthread surface_thread_;
  std::jthread haptic_thread_;
  // The view thread (--view png:DIR | window | hmd), last: it reads the parts above until it is
  // joined.
  std::jthread stereo_thread_;
};

Station::Run::Run(const StationConfig& cfg, std::atomic<bool>& stop)
    : cfg_(cfg),
      stop_(stop),
      faults_(stop, cfg.fault_hook),
      display_(make_display(cfg.haptics_spec, cfg.display)),
      display_zero_(*display_),
      log_(cfg, t_start_ns_),
      view_(cfg, faults_),
      head_(cfg),
      surface_(cfg, faults_, view_, log_.recorder()),
      haptic_(cfg, faults_, *display_, display_zero_, surface_.surfaces(), surface_.hand_in(),
              view_.hand_in(), log_.wants_bodies()),
      stats_(cfg, t_start_ns_) {
  view_.open();
}

StationSummary Station::Run::execute() {
  // A tracking device (NatNet's sockets, a glove) opens before anything connects, so a missing
  // one is named first; a script aims at the first surface, so it is made once that is here.
  if (cfg_.hand_spec.rfind("script:", 0) != 0) make_tracker_now();
  connect();
  if (wait_first_surface()) {
    start_haptics();  // a bad tracker spec or device is a start-up error, thrown as it is
    try {
      main_loop();
    } catch (...) {
      faults_.fail("main", std::current_exception());
    }
  }
  stop_threads();
  poll_thread_faults();  // one that failed while the others stopped
  view_.log_window_counts();
  if (auto error = faults_.first_error()) std::rethrow_exception(error);
  return summarize();
}

// The network client with the parts' event handlers, the view and surface threads, then the link.
void Station::Run::connect() {
  ClientEvents events;
  surface_.bind(events);
  view_.bind(events);
  events.on_state = [this](ClientState s, const std::string& why) {
    if (s == ClientState::Handshaking) surface_.forget_remote_said();
    spdlog::info("remote {}: {}", to_string(s), why);
  };
  events.on_warning = [](const std::string& what) { spdlog::warn("{}", what); };
  events.on_auth_failed = [](const std::string& why) {
    spdlog::error("authentication failed: {}", why);
  };
  start_opencv_workers();  // from this thread, so they never inherit the depth path's priority
  ClientConfig client_cfg = cfg_.client;
  client_cfg.want_video = client_cfg.want_video || view_.stereo();
  // The path from a depth capture to the force runs above everything else on this machine
  // (periodic.h has the priorities and what they bought).
  const int path_priority = cfg_.realtime ? kStationPathPriority : 0;
  client_cfg.realtime_priority = path_priority;
  client_ = std::make_unique<SurfaceClient>(client_cfg, std::move(events));
  surface_.attach(*client_);
  view_.attach(*client_);
  // The surface thread warms its buffers before the first frame can arrive.
  surface_thread_ = std::jthread([this](std::stop_token st) { surface_.run(st); });
  name_thread(surface_thread_.native_handle(), "telex-surface");
  const std::string surface_scheduling =
      try_realtime(surface_thread_.native_handle(), path_priority);
  thread_scheduling_.emplace_back("surface", surface_scheduling);
  if (view_.stereo()) {
    // The view gives way (nice 5) only where the depth path is not SCHED_FIFO: a real-time path
    // preempts it at any niceness, and on loopback a view at nice 5 lost most of its core to the
    // remote's busy threads (12.8 frames a second against 16.4 at nice 0, the surface and eye
    // rates the same).
    const int niceness = surface_scheduling.starts_with("SCHED_FIFO") ? 0 : kViewNicenessBelowPath;
    spdlog::info("view thread at nice {}{}", niceness,
                 niceness > 0 ? " (the depth path is not real-time)" : "");
    stereo_thread_ =
        std::jthread([this, niceness](std::stop_token st) { view_.run_stereo(st, niceness); });
    name_thread(stereo_thread_.native_handle(), "telex-view");
  }
  surface_.wait_warm();
  client_->start();
  thread_scheduling_.emplace_back("network", client_->scheduling());
}

bool Station::Run::poll_thread_faults() {
  const auto poll = [&](std::size_t i, std::optional<ThreadFaultReport> f) {
    if (!f || fault_reported_[i]) return;
    fault_reported_[i] = true;
    faults_.fail(f->thread, f->error);
  };
  if (client_) poll(0, client_->thread_fault());
  if (haptic_.tracker()) poll(1, haptic_.tracker()->thread_fault());
  poll(2, display_->thread_fault());
  if (log_.recorder()) poll(3, log_.recorder()->thread_fault());
  poll(4, view_.thread_fault());
  return std::find(fault_reported_.begin(), fault_reported_.end(), true) != fault_reported_.end();
}

bool Station::Run::xr_ended() {
  if (!view_.xr_ended()) return false;
  if (!stop_.exchange(true)) spdlog::info("the headset's session ended: stopping");
  return true;
}

// Waits for the first surface (scripted hands aim at it). False when the station was stopped
// first; throws when none arrives in time.
bool Station::Run::wait_first_surface() {
  // --duration bounds the whole run, connected or not.
  const bool duration_first = cfg_.duration_s > 0 && cfg_.duration_s < cfg_.first_surface_timeout_s;
  const double wait_s = duration_first ? cfg_.duration_s : cfg_.first_surface_timeout_s;
  const std::int64_t deadline =
      (duration_first ? t_start_ns_ : monotonic_ns()) + static_cast<std::int64_t>(wait_s * 1e9);
  while (surface_.surfaces_built() == 0 && !stop_.load()) {
    if (poll_thread_faults()) break;
    watch_tracker_inputs();
    if (view_.window() && view_.pump_window(stop_)) break;
    if (xr_ended()) break;
    // Keys or certificates that do not match do not heal by retrying: three refusals end it.
    if (monotonic_ns() > deadline || client_->stats().auth_failed.load() >= kAuthFailuresToStop) {
      const auto& cs = client_->stats();
      const std::string remote = cfg_.client.host + ":" + std::to_string(cfg_.client.port);
      if (cs.auth_failed.load() > 0)
        throw std::runtime_error(
            "no depth surface from the remote at " + remote + ": authentication failed (" +
            std::to_string(cs.auth_failed.load()) +
            " TLS handshake(s) or datagram(s) refused; see the lines above): start both daemons "
            "with the same --psk FILE (or certificates from one CA), or neither");
      throw std::runtime_error(
          "no depth surface from the remote at " + remote + " within " +
          fmt::format("{:g}", wait_s) + " s" + (duration_first ? " (--duration)" : "") +
          ": is telex-remote running and listening there (telex-remote --listen HOST:PORT)?");
    }
    std::this_thread::sleep_for(milliseconds(10));
  }
  return !stop_.load();
}

void Station::Run::make_tracker_now() {
  TrackerConfig tracker_cfg = cfg_.tracker;
  tracker_cfg.realtime_priority = cfg_.realtime ? kStationPathPriority : 0;
  if (surface_.first_centre_depth_m() > 0)
    tracker_cfg.surface_depth_m = surface_.first_centre_depth_m();
  if (faults_.hooked())
    tracker_cfg.natnet_receive_hook = [this] { faults_.check(StationLoop::Tracking); };
  if (cfg_.head_source == "hmd") tracker_cfg.head_from_hmd = view_.hmd_head_source();
  haptic_.set_tracker(make_tracker(cfg_.hand_spec, tracker_cfg));
  tracker_inputs_.update(monotonic_ns(), haptic_.tracker()->inputs());
}

void Station::Run::watch_tracker_inputs() {
  const std::int64_t now = monotonic_ns();
  if (!haptic_.tracker() || now < next_input_watch_ns_) return;
  next_input_watch_ns_ = now + 100'000'000;
  tracker_inputs_.update(now, haptic_.tracker()->inputs());
}

void Station::Run::start_haptics() {
  if (!haptic_.tracker()) make_tracker_now();
  if (view_.openxr()) haptic_.set_output_gate(&view_.output_gate());
  haptic_.set_link_pulse(&client_->stats().alive_ns);
  spdlog::info("surface at {:.3f} m ahead; hand {}; haptics {}",
               surface_.first_centre_depth_m() > 0 ? surface_.first_centre_depth_m()
                                                   : cfg_.tracker.surface_depth_m,
               haptic_.tracker()->name(), display_->name());
  haptic_thread_ = std::jthread([this](std::stop_token st) { haptic_.run(st); });
  name_thread(haptic_thread_.native_handle(), "telex-haptic");
  haptic_scheduling_ = haptic_.wait_scheduling();
  thread_scheduling_.emplace_back("haptic", haptic_scheduling_);
  if (const std::string t = haptic_.tracker()->scheduling(); !t.empty())
    thread_scheduling_.emplace_back("tracking", t);
  std::string path;
  for (const auto& [name, how] : thread_scheduling_)
    if (name != "haptic") path += (path.empty() ? "" : ", ") + name + " " + how;
  spdlog::info("depth-to-force path: {}", path);
  spdlog::info("haptic loop at {:.0f} Hz, {}; {}", cfg_.rate_hz, haptic_scheduling_,
               memory_lock_status().description);
}

// ---- main thread: drain samples, log, print, view, head ----
void Station::Run::main_loop() {
  const std::int64_t end_ns =
      cfg_.duration_s > 0 ? t_start_ns_ + static_cast<std::int64_t>(cfg_.duration_s * 1e9) : 0;
  std::int64_t next_status = monotonic_ns() + 1'000'000'000;
  std::int64_t next_view = 0;
  stats_.start_printing(monotonic_ns());
  // The first status line's rate counts from here, not from the frames built while waiting.
  surfaces_at_last_status_ = surface_.frames_built();
  last_status_ns_ = monotonic_ns();
  bool view_at_written = false;
  while (!stop_.load()) {
    // With a window the loop's 5 ms are spent waiting for its next picture, shown as soon as the
    // view hands it over.
    if (!view_.window())
      std::this_thread::sleep_for(milliseconds(5));
    else if (view_.pump_window(stop_, milliseconds(5)))
      break;
    faults_.check(StationLoop::Main);
    if (poll_thread_faults()) break;
    if (view_.window() && monotonic_ns() >= next_view && view_.stereo_idle()) {
      next_view = monotonic_ns() + view_.window_period_ns();  // the monitor's rate, not the video's
      view_.request_stereo(stats_.last().forces, last_status_);
    }
    if (view_.openxr()) {
      if (monotonic_ns() >= next_view) {  // the headset draws the newest at its own rate
        next_view = monotonic_ns() + kOnScreenViewPeriodNs;
        view_.request_stereo(stats_.last().forces, last_status_);
      }
      if (xr_ended()) break;
    }
    drain();
    drain_bodies();
    drain_stage_poses();
    report_supervisor_zeroings();
    watch_tracker_inputs();
    const std::int64_t now = monotonic_ns();
    head_.send(now, haptic_.head_out(), *client_);
    if (cfg_.view_at_s >= 0.0 && !view_at_written) {
      const std::int64_t t0 = haptic_.t0_ns();
      if (t0 != 0 && now >= t0 + static_cast<std::int64_t>(cfg_.view_at_s * 1e9)) {
        view_at_written = true;
        view_.write_files(stats_.last().forces, last_status_, true);
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
  view_.write_files(stats_.last().forces, last_status_);
  if (cfg_.view_at_s >= 0.0 && !view_at_written)
    spdlog::warn("--view-at {:g} s: the run ended before that moment; no view written",
                 cfg_.view_at_s);
}

// Orderly end: the haptic thread first (it zeroes the display), then what it logged, then the
// surface thread and the network.
void Station::Run::stop_threads() {
  if (haptic_thread_.joinable()) {
    haptic_thread_.request_stop();
    haptic_thread_.join();
  }
  drain();
  drain_bodies();
  surface_thread_.request_stop();
  surface_.close();
  if (surface_thread_.joinable()) surface_thread_.join();
  client_->stop();
  if (stereo_thread_.joinable()) {
    stereo_thread_.request_stop();  // after drawing what is pending
    stereo_thread_.join();
  }
  drain_stage_poses();
  log_.finish();
}

void Station::Run::drain() {
  TickSample s{};
  while (haptic_.samples().pop(s))
    log_.add_tick(s, stats_.add(s, client_->stats().clock_offset_ns.load()));
}

void Station::Run::drain_bodies() {
  HandState state{};
  while (haptic_.bodies().pop(state)) log_.add_bodies(state);
}

void Station::Run::drain_stage_poses() {
  StationView::StagePose pose;
  while (view_.take_stage_pose(pose)) log_.add_hmd_pose(pose.display_time_ns, pose.X_StageView);
}

// The display supervisor zeroed the display while the station was silent (stopped, hung): said
// once the station runs again.
void Station::Run::report_supervisor_zeroings() {
  if (cfg_.supervisor_heartbeat == nullptr) return;
  const std::uint64_t n = cfg_.supervisor_heartbeat->zeroings();
  if (n == supervisor_zeroings_) return;
  supervisor_zeroings_ = n;
  spdlog::warn(
      "{} ({} time(s) in this run; its line above says for how long): the forces start "
      "again from zero",
      kSupervisorZeroedLine, n);
}

// Once a second: the status line and the view PNG.
void Station::Run::print_status() {
  // Frames per second, as the source counts them: a frame's ROI part and rest are one frame.
  const std::uint64_t built = surface_.frames_built();
  const std::int64_t now_ns = monotonic_ns();
  const double fps = static_cast<double>(built - surfaces_at_last_status_) /
                     std::max(1e-3, static_cast<double>(now_ns - last_status_ns_) / 1e9);
  surfaces_at_last_status_ = built;
  const std::uint64_t eyes = view_.eye_frames_received();
  const double eye_fps = static_cast<double>(eyes - eyes_at_last_status_) /
                         std::max(1e-3, static_cast<double>(now_ns - last_status_ns_) / 1e9);
  eyes_at_last_status_ = eyes;
  last_status_ns_ = now_ns;
  std::string text =
      stats_.status_text(fps, surface_.build_ms(), client_->state(), haptic_.tracker());
  const unsigned said = surface_.remote_said();
  if (said & SurfaceStage::kSourceEnded)
    text += " | the remote's depth source ended: the last surface stays";
  // The eyes, when the view shows them: what the remote said of its eye source, not only a grey
  // background.
  if (view_.stereo())
    text += eye_fps > 0.0 ? fmt::format(" | eyes {:.1f} pairs/s", eye_fps)
            : (said & SurfaceStage::kEyesOff)
                ? std::string(" | eyes off (the remote runs without --stereo)")
            : (said & SurfaceStage::kEyesEnded)
                ? std::string(" | eyes ended (the remote's --stereo source played to its end)")
                : std::string(" | eyes none (no video from the remote yet: see its stats line)");
  text += photon_status(view_.photon_recent(), view_.writes_png());
  text += tracker_inputs_.status(now_ns);
  if (cfg_.status_line) {
    std::string forces;
    const TickSample& last = stats_.last();
    for (std::size_t i = 0; i < kFingerCount; ++i)
      if (last.tracked[i])
        forces += fmt::format(" {} {:.2f}/{:+.2f}N", kFingerNames[i], last.forces[i].normal_force_N,
                              last.forces[i].shear_along_axis_N);
    spdlog::info("{}{}{}", text, forces.empty() ? "" : " |" + forces,
                 cfg_.insecure ? " | INSECURE link (--insecure)" : "");
  }
  if (cfg_.insecure && ++statuses_since_insecure_warning_ >= 60) {
    statuses_since_insecure_warning_ = 0;
    spdlog::warn("{}", proto::insecure_warning());
  }
  last_status_ = text;
  view_.write_files(stats_.last().forces, last_status_);
  stats_.clear_window();
}

StationSummary Station::Run::summarize() {
  StationSummary s;
  stats_.summarize(s, haptic_.missed());
  surface_.summarize(s);
  head_.summarize(s);
  log_.summarize(s);
  s.scheduling = haptic_scheduling_;
  const MemoryLock memory = memory_lock_status();
  s.memory_locked = memory.locked;
  s.memory_lock = memory.description;
  s.thread_scheduling = thread_scheduling_;
  if (haptic_.tracker()) s.tracker = haptic_.tracker()->stats();
  s.tracker_silent = tracker_inputs_.summary(monotonic_ns());
  s.ticks_link_silent = haptic_.ticks_link_silent();
  s.ticks_tracking_silent = haptic_.ticks_tracking_silent();
  const ClientStats& cs = client_->stats();
  s.auth_failed = cs.auth_failed.load();
  s.unsealed = cs.unsealed.load();
  s.replayed = cs.replayed.load();
  s.dropped_malformed = cs.dropped_malformed.load();
  s.upstream_dropped = cs.upstream_dropped.load();
  s.udp_datagrams = cs.datagrams.load();
  s.udp_lost = cs.udp_lost.load();
  s.bytes_in = cs.bytes_in.load();
  s.video_bytes = cs.video_bytes.load();
  s.depth_bytes = cs.depth_bytes.load();
  view_.summarize(s);
  for (std::size_t n = 0; n < s.udp_messages_by_fragments.size(); ++n)
    s.udp_messages_by_fragments[n] = cs.udp_messages_by_fragments[n].load();
  if (view_.openxr()) {
    const StationView::XrStats x = view_.xr_stats();
    s.openxr = true;
    s.openxr_runtime = x.runtime;
    s.openxr_end_reason = x.end_reason;
    s.openxr_eye_width = x.eye_width;
    s.openxr_eye_height = x.eye_height;
    s.openxr_frames_submitted = x.frames_submitted;
    s.openxr_ticks_gated = haptic_.ticks_gated();
    s.openxr_gate_closed_ns = x.gate_closed_ns;
    s.hmd_poses_dropped = view_.stage_poses_dropped();
  }
  return s;
}

StationSummary Station::run() {
  // Before any of the run's threads: setenv is not safe beside a getenv on another thread.
  if (ViewSpec::parse(cfg_.view_spec).kind == ViewSpec::Kind::OpenXr) prepare_openxr_environment();
  Run run(cfg_, stop_);
  return run.execute();
}

}  // namespace telex::local
