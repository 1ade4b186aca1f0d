// SPDX-License-Identifier: MIT
// Threads of the remote daemon and its run loop (signals, duration, stats line).
#include "telex/remote/daemon.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <boost/asio.hpp>
#include <iostream>
#include <iterator>
#include <limits>

#include "telex/base/periodic.h"
#include "telex/common/head_kinematics.h"
#include "telex/common/opencv_workers.h"

namespace telex::remote {

using namespace std::chrono_literals;

void validate(const DaemonConfig& c) {
  if (c.depth_source.empty()) throw std::invalid_argument("--source must not be empty");
  if (c.jpeg_quality < 1 || c.jpeg_quality > 100)
    throw std::invalid_argument(fmt::format("--jpeg-quality {} is outside 1..100", c.jpeg_quality));
  video_encoder_names(c.video_codec);  // throws naming --video-codec
  if (c.video_bitrate_bps < 50'000 || c.video_bitrate_bps > 1'000'000'000)
    throw std::invalid_argument(
        fmt::format("--video-bitrate {} bit/s is outside 50k..1G", c.video_bitrate_bps));
  if (c.video_width < 0 || c.video_height < 0 || (c.video_width == 0) != (c.video_height == 0))
    throw std::invalid_argument(
        "--video-size must be WxH with both positive (or 0x0 for the source size)");
  if (c.duration_s < 0)
    throw std::invalid_argument(fmt::format("--duration {} is negative", c.duration_s));
  if (c.server.client_timeout.count() <= 0)
    throw std::invalid_argument("--client-timeout must be positive");
  if (c.server.max_queued_frames < 1)
    throw std::invalid_argument("--max-queued-frames must be >= 1");
  if (c.source_options.synthetic_fps <= 0 || c.source_options.synthetic_fps > 1000)
    throw std::invalid_argument(
        fmt::format("--fps {} is outside (0, 1000]", c.source_options.synthetic_fps));
  if (c.pipeline.tile_width < 8 || c.pipeline.tile_height < 8)
    throw std::invalid_argument("--tile must be at least 8x8 pixels");
  if (c.pipeline.stabilise_k_sigma < 0) throw std::invalid_argument("--stabilise must be >= 0");
  const HeadSpec head = parse_head_spec(c.head);
  c.head_limits.validate();
  if (!c.head_log_csv.empty() && head.kind == HeadSpec::Kind::None)
    throw std::invalid_argument(
        "--log-head logs the head loop, which runs only with a head: give "
        "--head sim|dynamixel:DEV|udp:HOST:PORT");
}

std::string_view eye_state_name(EyeState state) {
  switch (state) {
    case EyeState::Held:
      return "held";
    case EyeState::None:
      return "none";
    case EyeState::Live:
      return "live";
    case EyeState::Ended:
      return "ended";
    case EyeState::Off:
      break;
  }
  return "off";
}

RemoteDaemon::RemoteDaemon(DaemonConfig config)
    : config_(std::move(config)), pipeline_(config_.pipeline), head_control_([this] {
        HeadControllerConfig c;
        c.limits = config_.head_limits;
        c.link_timeout_s = config_.head_link_timeout_s;
        c.require_deadman = config_.require_deadman;
        return c;
      }()) {
  static_assert(static_cast<int>(Deadman::Released) ==
                static_cast<int>(proto::DeadmanState::Released));
  validate(config_);
  head_driven_ = parse_head_spec(config_.head).kind != HeadSpec::Kind::None;
  if (head_driven_) {
    check_head_axes(config_.robot_head);
    // A synthetic scene stays put in the room while the head turns (a real sensor's view).
    config_.source_options.head_orientation =
        [this](std::int64_t capture_ns) -> std::optional<glm::dmat3> {
      const HeadPose p = head_pose_at(capture_ns);
      if (!p.valid) return std::nullopt;
      return head_rotation(config_.robot_head, p.joint_rad);
    };
    // The operator's head, from the network thread; the head loop commands it.
    config_.server.on_head_command = [this](const proto::HeadCommand& c, std::int64_t now_ns,
                                            std::optional<std::int64_t> station_now_ns) {
      std::lock_guard lock(head_mu_);
      HeadTarget t;
      t.joint_rad = {c.joint_rad[0], c.joint_rad[1], c.joint_rad[2]};
      t.sample_id = c.sample_id;
      t.sample_age_ns = static_cast<std::int64_t>(c.sample_age_us) * 1000;
      t.deadman = static_cast<Deadman>(c.deadman);  // the same values (PROTOCOL.md 2.3)
      t.sample_ns = static_cast<std::int64_t>(c.operator_ns);
      // A stamp beyond int64 (a broken station) is as old as a sample can be.
      if (station_now_ns)
        t.arrival_age_ns = t.sample_ns < 0 ? std::numeric_limits<std::int64_t>::max() / 2
                                           : *station_now_ns - t.sample_ns;
      head_control_.set_target(t, now_ns);
    };
  }
  depth_ = make_depth_source(config_.depth_source, config_.source_options);
  stereo_ = make_eye_source(config_.depth_source, config_.stereo_source, config_.source_options);
  if (stereo_) open_eyes();
  config_.server.video_available = stereo_ != nullptr;
  config_.server.registration = std::string(depth_registration_name(config_.registration));
  config_.server.codec = config_.pipeline.codec;
}

RemoteDaemon::~RemoteDaemon() { stop(); }

void RemoteDaemon::set_frame_observer(std::function<void(const ProcessedFrame&)> observer) {
  observer_ = std::move(observer);
}

void RemoteDaemon::start() {
  if (running_) return;
  // First, so a missing or silent head fails the start before anything else opens.
  if (!head_) head_ = make_head_driver(config_.head, config_.head_limits);
  if (head_driven_ && !config_.head_log_csv.empty() && !head_log_.is_open()) {
    head_log_.open(config_.head_log_csv);
    if (!head_log_)
      throw std::invalid_argument("--log-head " + config_.head_log_csv.string() +
                                  ": cannot be written (check the folder exists and is writable)");
    head_log_ << "t_ns,measured_valid,yaw_rad,pitch_rad,roll_rad,cmd_yaw_rad,cmd_pitch_rad,"
                 "cmd_roll_rad,sample_id,sample_ns,sample_age_ms,deadman,hold\n";
  }
  start_opencv_workers();  // from this thread, so they never inherit the depth path's priority
  depth_->start();
  if (stereo_) stereo_->start();
  log_plays_once();
  eyes_ = !stereo_ ? EyeState::Off : stereo_->plays_once() ? EyeState::Held : EyeState::None;
  config_.server.fps = static_cast<float>(depth_->nominal_fps());
  const int path_priority = config_.realtime ? kRemotePathPriority : 0;
  config_.server.realtime_priority = path_priority;
  server_ = std::make_unique<RemoteServer>(config_.server);
  server_->start();
  // Tiles go to the network as they are encoded, so the station decodes while the rest encodes.
  pipeline_.set_tile_sink(
      [this](const ProcessedFrame& part, std::size_t from) { server_->publish_tiles(part, from); });
  running_ = true;
  capture_thread_ = std::thread([this] { capture_fault_.run([this] { capture_loop(); }); });
  process_thread_ = std::thread([this] { process_fault_.run([this] { process_loop(); }); });
  if (stereo_) {
    stereo_thread_ = std::thread([this] { stereo_fault_.run([this] { stereo_loop(); }); });
    video_thread_ = std::thread([this] { video_fault_.run([this] { video_loop(); }); });
  }
  if (head_driven_)
    head_thread_ = std::thread([this] { head_fault_.run([this] { head_loop(); }); });
  // From capture to the network, above video, logs and whatever else runs here (periodic.h).
  name_thread(capture_thread_.native_handle(), "telex-capture");
  name_thread(process_thread_.native_handle(), "telex-process");
  if (stereo_) {
    name_thread(stereo_thread_.native_handle(), "telex-stereo");
    name_thread(video_thread_.native_handle(), "telex-video");
  }
  if (head_driven_) name_thread(head_thread_.native_handle(), "telex-head");
  scheduling_.clear();
  scheduling_.emplace_back("capture", try_realtime(capture_thread_.native_handle(), path_priority));
  scheduling_.emplace_back("process", try_realtime(process_thread_.native_handle(), path_priority));
  scheduling_.emplace_back("network", server_->scheduling());
  if (head_driven_)
    scheduling_.emplace_back("head", try_realtime(head_thread_.native_handle(),
                                                  config_.realtime ? kHeadLoopPriority : 0));
}

void RemoteDaemon::stop() {
  if (!running_.exchange(false)) return;
  depth_slot_.close();
  stereo_slot_.close();
  for (auto* t :
       {&capture_thread_, &stereo_thread_, &process_thread_, &video_thread_, &head_thread_})
    if (t->joinable()) t->join();
  if (head_log_.is_open()) head_log_.flush();
  server_->stop();
  depth_->stop();
  if (stereo_) stereo_->stop();
}

std::uint16_t RemoteDaemon::port() const { return server_ ? server_->port() : 0; }

DaemonStats RemoteDaemon::stats() const {
  DaemonStats s;
  {
    std::lock_guard lock(stats_mu_);
    s = stats_;
  }
  s.frames_slot_dropped = depth_slot_.dropped();
  s.path_threads = static_cast<int>(scheduling_.size());
  s.realtime_threads =
      static_cast<int>(std::count_if(scheduling_.begin(), scheduling_.end(), [](const auto& t) {
        return t.second.rfind("SCHED_FIFO", 0) == 0;
      }));
  s.source_ended = source_ended_;
  s.eyes = eyes_;
  s.registration = config_.registration;
  if (server_) {
    const auto& c = server_->counters();
    s.frames_sent = c.frames_sent;
    s.frames_queue_dropped = c.frames_dropped;
    s.bytes_sent = c.bytes_sent;
    s.malformed_in = c.malformed_in;
    s.auth_failed = c.auth_failed;
    s.unsealed = c.unsealed;
    s.replayed = c.replayed;
    s.udp_ignored = c.udp_ignored;
    s.preauth_evicted = c.preauth_evicted;
    s.preauth_timeouts = c.preauth_timeouts;
    s.accept_errors = c.accept_errors;
    s.key_frame_requests = c.key_frame_requests;
    s.nacks_in = c.nacks_in;
    s.repair_tiles_sent = c.repair_tiles_sent;
    s.repair_unavailable = c.repair_unavailable;
    s.repair_duplicates = c.repair_duplicates;
    s.repair_over_budget = c.repair_over_budget;
    s.repair_over_queue = c.repair_over_queue;
    s.control_dropped = c.control_dropped;
    s.clients_accepted = c.clients_accepted;
    s.clients_rejected = c.clients_rejected;
    s.client_timeouts = c.client_timeouts;
    for (std::size_t i = 0; i < kSessionEndCount; ++i) s.sessions_ended[i] = c.sessions_ended[i];
    s.client = server_->state();
    s.head_commands_in = c.head_commands_in;
    s.video_bytes_sent = c.video_bytes_sent;
    s.video_pairs_sent = c.video_pairs_sent;
    s.plis_in = c.plis_in;
    s.video_nacks_in = c.video_nacks_in;
    s.video_pairs_resent = c.video_pairs_resent;
    s.video_repair_unavailable = c.video_repair_unavailable;
    s.video_repair_over_queue = c.video_repair_over_queue;
    s.receiver_reports_in = c.receiver_reports_in;
  }
  if (eye_stream_) s.video_bitrate_bps = eye_stream_->bitrate_bps();
  {
    std::lock_guard lock(head_mu_);
    s.head_control = head_control_.stats();
    s.head_holding = head_control_.holding();
    s.head_hold = head_control_.hold_reason();
    s.head = head_stats_;  // the head loop's copy: drivers are used from that thread only
  }
  return s;
}

// ---- head loop: read the head, then move it toward the operator's pose (rate-limited, clamped;
// still when the operator's link is lost). Its readings stamp every depth frame's capture. ----
void RemoteDaemon::head_loop() {
  const auto period =
      std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / config_.head_rate_hz));
  auto next = std::chrono::steady_clock::now();
  std::int64_t log_flushed_ns = steady_now_ns();
  while (running_) {
    const std::int64_t now = steady_now_ns();
    const HeadPose measured = head_->measured(now);
    std::optional<HeadAngles> command;
    std::uint32_t sample_id = 0;
    std::int64_t sample_age_ns = -1, sample_ns = 0;
    Deadman deadman = Deadman::NotUsed;
    HeadHold hold = HeadHold::None;
    {
      std::lock_guard lock(head_mu_);
      if (measured.valid) {
        head_history_.push_back(measured);
        if (head_history_.size() > 256) head_history_.pop_front();
      }
      command = head_control_.update(measured, now);
      sample_id = head_control_.sample_id();
      sample_age_ns = head_control_.sample_age_ns(now);
      sample_ns = head_control_.sample_ns();
      deadman = head_control_.deadman();
      hold = head_control_.hold_reason();
    }
    if (command) head_->command(*command, now);
    if (head_log_.is_open()) {
      // Buffered, flushed once a second: at most one write a second from this loop.
      head_log_ << fmt::format("{},{},{:.6f},{:.6f},{:.6f},", now, measured.valid ? 1 : 0,
                               measured.joint_rad[0], measured.joint_rad[1], measured.joint_rad[2]);
      if (command)
        head_log_ << fmt::format("{:.6f},{:.6f},{:.6f},", (*command)[0], (*command)[1],
                                 (*command)[2]);
      else
        head_log_ << ",,,";
      head_log_ << fmt::format("{},{},{:.3f},{},{}\n", sample_id, sample_ns,
                               sample_age_ns < 0 ? -1.0 : static_cast<double>(sample_age_ns) * 1e-6,
                               static_cast<int>(deadman), head_hold_name(hold));
      if (now - log_flushed_ns >= 1'000'000'000) {
        head_log_.flush();
        log_flushed_ns = now;
      }
    }
    {
      std::lock_guard lock(head_mu_);
      head_stats_ = head_->stats();
    }
    next += period;
    const auto wake = std::chrono::steady_clock::now();
    if (next < wake) next = wake;  // a slow bus: no burst to catch up
    std::this_thread::sleep_until(next);
  }
  // Leaving: the head holds where it is, whatever the driver. The last command may be ahead of the
  // head (it lags), and a lab's controller (--head udp) keeps the last target it was sent.
  const HeadPose last = head_->measured(steady_now_ns());
  if (last.valid) head_->command(last.joint_rad, last.time_ns);
  std::lock_guard lock(head_mu_);
  head_stats_ = head_->stats();
}

HeadPose RemoteDaemon::head_pose_at(std::int64_t t) const {
  std::lock_guard lock(head_mu_);
  HeadPose out;
  if (head_history_.empty()) return out;
  out.valid = true;
  out.time_ns = t;
  const auto lerp = [&](const HeadPose& a, const HeadPose& b, double u) {
    for (std::size_t j = 0; j < kHeadJoints; ++j)
      out.joint_rad[j] = a.joint_rad[j] + (b.joint_rad[j] - a.joint_rad[j]) * u;
  };
  const HeadPose& newest = head_history_.back();
  if (t <= head_history_.front().time_ns) {
    out.joint_rad = head_history_.front().joint_rad;
  } else if (t >= newest.time_ns) {
    // Past the newest reading: on along the last two readings' slope, at most 20 ms.
    if (head_history_.size() < 2) {
      out.joint_rad = newest.joint_rad;
    } else {
      const HeadPose& prev = head_history_[head_history_.size() - 2];
      const double span = static_cast<double>(newest.time_ns - prev.time_ns);
      const double ahead =
          static_cast<double>(std::min<std::int64_t>(t - newest.time_ns, 20'000'000));
      lerp(prev, newest, span > 0 ? 1.0 + ahead / span : 1.0);
    }
  } else {
    const auto it =
        std::upper_bound(head_history_.begin(), head_history_.end(), t,
                         [](std::int64_t v, const HeadPose& p) { return v < p.time_ns; });
    const HeadPose& b = *it;
    const HeadPose& a = *std::prev(it);
    lerp(a, b, static_cast<double>(t - a.time_ns) / static_cast<double>(b.time_ns - a.time_ns));
  }
  return out;
}

void RemoteDaemon::log_plays_once() const {
  const auto once = [](std::int64_t n) {
    return n >= 0 ? fmt::format("{} frames once", n) : std::string("its frames once");
  };
  if (depth_->plays_once())
    spdlog::info(
        "depth source {} will play {}, when the first station connects (add ,loop to the "
        "--source spec to play it on a loop)",
        depth_->describe(), once(depth_->frame_count()));
  if (stereo_ && stereo_->plays_once())
    spdlog::info(
        "eye source {} will play {}, when the first station asks for video (add ,loop to its "
        "spec to play it on a loop)",
        stereo_->describe(), once(stereo_->frame_count()));
}

bool RemoteDaemon::depth_released() {
  if (!station_seen_ && server_->state() == ClientState::Connected) station_seen_ = true;
  return station_seen_;
}

bool RemoteDaemon::eyes_released() {
  if (!video_seen_ && server_->video_wanted()) video_seen_ = true;
  return video_seen_;
}

void RemoteDaemon::capture_loop() {
  auto last_log = std::chrono::steady_clock::time_point{};
  const bool hold = depth_->plays_once();
  while (running_) {
    // A source that plays once starts with the first station: played before, nobody would see it.
    if (hold && !depth_released()) {
      std::this_thread::sleep_for(20ms);
      continue;
    }
    auto r = depth_->read(100ms);
    if (r.status == ReadStatus::Frame) {
      {
        std::lock_guard lock(stats_mu_);
        ++stats_.frames_in;
      }
      // The head's pose when the frame was captured goes with it to the station.
      if (head_driven_) {
        const HeadPose h = head_pose_at(r.frame.capture_ns);
        r.frame.head.valid = h.valid;
        for (std::size_t j = 0; h.valid && j < kHeadJoints; ++j)
          r.frame.head.joint_rad[j] = static_cast<float>(h.joint_rad[j]);
      }
      depth_slot_.put(std::move(r.frame));
    } else if (r.status == ReadStatus::Error) {
      {
        std::lock_guard lock(stats_mu_);
        ++stats_.source_errors;
      }
      // Errors are counted every time, logged at most once a second.
      const auto now = std::chrono::steady_clock::now();
      if (now - last_log > 1s) {
        spdlog::warn("depth source {}: {}", depth_->describe(), r.error);
        last_log = now;
      }
      std::this_thread::sleep_for(10ms);
    } else if (r.status == ReadStatus::EndOfStream) {
      source_ended_ = true;
      server_->tell("source_ended");
      return;
    }
  }
}

void RemoteDaemon::stereo_loop() {
  const bool hold = stereo_->plays_once();
  while (running_) {
    // Video frames go out only once asked for, so a source that plays once waits for that.
    if (hold && !eyes_released()) {
      eyes_ = EyeState::Held;
      std::this_thread::sleep_for(20ms);
      continue;
    }
    if (eyes_ == EyeState::Held || eyes_ == EyeState::Off) eyes_ = EyeState::None;
    auto r = stereo_->read(100ms);
    if (r.status == ReadStatus::Frame) {
      eyes_ = EyeState::Live;
      stereo_slot_.put(std::move(r.frame));
    } else if (r.status == ReadStatus::Error) {
      std::lock_guard lock(stats_mu_);
      ++stats_.source_errors;
    } else if (r.status == ReadStatus::EndOfStream) {
      eyes_ = EyeState::Ended;
      server_->tell("eyes_ended");
      return;
    }
  }
}

void RemoteDaemon::process_loop() {
  while (running_) {
    auto frame = depth_slot_.take(100ms);
    if (!frame) continue;
    FrameRequest request = server_->take_request();
    // Fill and stabiliser keep their history; tiles are only cut and encoded for a receiver.
    request.select_tiles = server_->state() == ClientState::Connected;
    // ROI first: a receiver that takes frames in parts gets the ROI tiles before the rest of the
    // frame is even filled, and a newer frame waiting cuts the rest short so its ROI part does not
    // queue behind it; others get both parts as one message set.
    const ProcessedFrame p = pipeline_.process(
        *frame, request,
        [this](const ProcessedFrame& part) {
          if (observer_) observer_(part);
          server_->publish(part);
        },
        [this] { return depth_slot_.has_value(); });
    std::lock_guard lock(stats_mu_);
    if (p.rest_cut) ++stats_.rests_cut;
    ++stats_.frames_processed;
    stats_.tiles_sent += p.tiles.size();
    stats_.tiles_skipped += p.tiles_skipped;
    stats_.stage_ms_sum += p.times;
    stats_.first_part_ms_sum += p.first_part_ms;
  }
}

std::optional<ThreadFaultReport> RemoteDaemon::thread_fault() const {
  for (const ThreadFault* f :
       {&capture_fault_, &stereo_fault_, &process_fault_, &video_fault_, &head_fault_})
    if (f->failed()) return f->report();
  if (server_ && server_->fault().failed()) return server_->fault().report();
  return std::nullopt;
}

int RemoteDaemon::run() {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::signal_set signals(io, SIGINT, SIGTERM);
  int exit_code = 0;
  signals.async_wait([&](boost::system::error_code ec, int sig) {
    if (!ec) spdlog::info("signal {}: stopping", sig);
    io.stop();
  });
  const auto t_start = std::chrono::steady_clock::now();
  auto last = t_start;
  auto last_insecure_warning = t_start;  // main() warned at start
  DaemonStats before = stats();
  bool end_logged = false;
  asio::steady_timer tick(io);
  std::function<void()> arm = [&] {
    tick.expires_after(100ms);
    tick.async_wait([&](boost::system::error_code ec) {
      if (ec) return;
      const auto now = std::chrono::steady_clock::now();
      // A failed thread ends the run: the session closes (the station sees it), the head loop
      // stops commanding and the head holds its last target.
      if (const auto fault = thread_fault()) {
        spdlog::error("thread {} stopped: {}; stopping (the head holds still)", fault->thread,
                      fault->what());
        exit_code = 1;
        io.stop();
        return;
      }
      if (config_.insecure && now - last_insecure_warning >= 60s) {
        spdlog::warn("{}", proto::insecure_warning());
        last_insecure_warning = now;
      }
      if (config_.stats_line && now - last >= 1s) {
        const DaemonStats s = stats();
        const double span_s = std::chrono::duration<double>(now - last).count();
        std::cerr << (config_.stats_full ? format_stats_line(s, before, span_s)
                                         : format_stats_short(s, before, span_s))
                  << (config_.insecure ? " | INSECURE link (--insecure)" : "") << std::endl;
        before = s;
        last = now;
      }
      if (config_.duration_s > 0 &&
          now - t_start >= std::chrono::duration<double>(config_.duration_s)) {
        io.stop();
        return;
      }
      if (source_ended_ &&
          depth_slot_.put_count() == stats().frames_processed + depth_slot_.dropped()) {
        // What played for a station stays on its screen until it leaves.
        if (depth_->plays_once() && server_->state() == ClientState::Connected) {
          if (!end_logged)
            spdlog::info("depth source {} ended; stopping when the station leaves",
                         depth_->describe());
          end_logged = true;
          arm();
          return;
        }
        spdlog::info("depth source {} ended", depth_->describe());
        io.stop();
        return;
      }
      arm();
    });
  };
  arm();
  io.run();
  stop();
  return exit_code;
}

}  // namespace telex::remote
