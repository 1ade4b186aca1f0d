// SPDX-License-Identifier: MIT
// The remote daemon: capture threads, the processing thread, the server, and the stats line.
#pragma once

#include <array>
#include <atomic>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "telex/base/latest_slot.h"
#include "telex/base/pi_mutex.h"
#include "telex/base/thread_fault.h"
#include "telex/common/rig.h"
#include "telex/remote/eye_rate.h"
#include "telex/remote/eye_stream.h"
#include "telex/remote/head.h"
#include "telex/remote/pipeline.h"
#include "telex/remote/server.h"
#include "telex/remote/sources.h"

namespace telex::remote {

struct DaemonConfig {
  std::string depth_source = "synthetic";  // see make_depth_source
  std::string stereo_source;               // empty: no video
  SourceOptions source_options;
  PipelineConfig pipeline;
  // The one registration of the run (--registration): hardware sets
  // source_options.hardware_registration, rig the pipeline's registration stage.
  DepthRegistration registration = DepthRegistration::None;
  ServerConfig server;
  int jpeg_quality = 80;  // 1..100, --video-codec mjpeg
  int video_width = 0;    // 0: the stereo source's size
  int video_height = 0;
  // --video-codec h264 | h264-vaapi | h264-nvenc | mjpeg | auto and --video-bitrate (bit/s).
  std::string video_codec = "h264";
  std::int64_t video_bitrate_bps = 4'000'000;
  double duration_s = 0.0;    // 0: until SIGINT/SIGTERM
  bool stats_line = true;     // one line a second on stderr
  bool stats_full = false;    // ... the long form (format_stats_line), not the short one
  std::string head = "none";  // the robot head's driver: see make_head_driver
  HeadLimits head_limits = kDefaultHeadLimits;
  // The head's joint axes (the rig's robot_head): a synthetic depth scene is seen from the head's
  // measured pose with them.
  RobotHead robot_head;
  double head_rate_hz = 100.0;       // the head loop: measure, then command
  double head_link_timeout_s = 0.2;  // no operator head pose this long: the head holds still
  // --require-deadman: the head moves only while the station reports its dead-man pressed.
  bool require_deadman = false;
  // --log-head: one CSV row per head loop: t_ns (the remote's steady clock), the measured pose,
  // the command, the target's tracking sample (id, its time on the station's clock, its age),
  // the dead-man state and why the head holds (docs/PROTOCOL.md 2.6); empty = none.
  std::filesystem::path head_log_csv;
  // SCHED_FIFO for the threads from capture to the network (kRemotePathPriority) and the head loop
  // (kHeadLoopPriority); --no-realtime turns it off. Video and the stats line stay below them.
  bool realtime = true;
  // --insecure: a plain link off loopback, accepted on purpose; every stats line says so and a
  // warning is logged at start and every minute.
  bool insecure = false;
};

// Throws std::invalid_argument naming the first bad value.
void validate(const DaemonConfig& config);

// The eye view (--stereo, or a bag's colour topic) as the stats line reports it: off (no eye
// source), held (a source that plays once waits for a station that wants video), none (reading,
// nothing delivered yet: a camera that never delivers stays here), live (delivering), ended (a
// finite source played its last frame).
enum class EyeState : std::uint8_t { Off, Held, None, Live, Ended };
std::string_view eye_state_name(EyeState state);

struct DaemonStats {
  std::uint64_t frames_in = 0;            // captured
  std::uint64_t frames_slot_dropped = 0;  // replaced in the slot before processing
  std::uint64_t frames_processed = 0;
  std::uint64_t rests_cut = 0;  // rests cut short because a newer frame was waiting
  std::uint64_t frames_sent = 0;
  std::uint64_t frames_queue_dropped = 0;
  std::uint64_t tiles_sent = 0;
  std::uint64_t tiles_skipped = 0;
  std::uint64_t bytes_sent = 0;
  std::uint64_t source_errors = 0;
  std::uint64_t video_frames = 0;  // pairs encoded and published
  // The eyes: encoder refusals, PLIs applied, bytes and pairs on the wire (bytes_sent holds
  // them too), the encoder's target, the station's newest receiver report.
  std::uint64_t video_failed = 0, video_intra_requests = 0;
  std::uint64_t video_bytes_sent = 0, video_pairs_sent = 0, plis_in = 0, receiver_reports_in = 0;
  // The eyes' repair (PROTOCOL.md 2.7): VideoNacks in, pairs sent again, pairs no longer cached,
  // pairs refused over the bound of queued resends.
  std::uint64_t video_nacks_in = 0, video_pairs_resent = 0, video_repair_unavailable = 0;
  std::uint64_t video_repair_over_queue = 0;
  std::int64_t video_bitrate_bps = 0;
  proto::ReceiverReport last_report;
  std::uint64_t malformed_in = 0;
  std::uint64_t auth_failed = 0, unsealed = 0, replayed = 0, udp_ignored = 0;
  std::uint64_t preauth_evicted = 0, preauth_timeouts = 0, accept_errors = 0;  // server.h
  // Repair (PROTOCOL.md 2.5): key-frame requests and TileNacks from the station, tiles resent,
  // tiles asked for that the cache no longer held.
  std::uint64_t key_frame_requests = 0, nacks_in = 0, repair_tiles_sent = 0, repair_unavailable = 0;
  std::uint64_t repair_duplicates = 0, repair_over_budget = 0, repair_over_queue = 0;
  std::uint64_t control_dropped = 0;
  // Head teleoperation: operator poses received, the controller's counts, whether the head holds
  // still (no operator pose for head_link_timeout_s), the driver's counts.
  std::uint64_t head_commands_in = 0;
  HeadControlStats head_control;
  bool head_holding = true;
  HeadHold head_hold = HeadHold::Link;  // why it holds
  HeadStats head;
  std::uint64_t clients_accepted = 0, clients_rejected = 0, client_timeouts = 0;
  std::array<std::uint64_t, kSessionEndCount> sessions_ended{};  // by SessionEnd
  StageTimes stage_ms_sum;                                       // summed over frames_processed
  double first_part_ms_sum = 0;  // processing time until the first part (ROI part) was published
  ClientState client = ClientState::Waiting;
  bool source_ended = false;
  // Threads on the depth path (capture, process, network, head) and how many got SCHED_FIFO.
  int path_threads = 0, realtime_threads = 0;
  EyeState eyes = EyeState::Off;
  DepthRegistration registration = DepthRegistration::None;  // the run's (--registration)
};

// "frames in/out", mean ms per stage, bytes/s, tiles skipped and client state between two
// snapshots.
std::string format_stats_line(const DaemonStats& now, const DaemonStats& before, double seconds);
// The default, short line (about a sixth of the full one): rates, the station, the eyes, the
// head and the problem counters that are not zero.
std::string format_stats_short(const DaemonStats& now, const DaemonStats& before, double seconds);

class RemoteDaemon {
 public:
  explicit RemoteDaemon(DaemonConfig config);  // validates and creates the sources (throws)
  ~RemoteDaemon();
  RemoteDaemon(const RemoteDaemon&) = delete;
  RemoteDaemon& operator=(const RemoteDaemon&) = delete;

  void start();  // opens the devices, binds, starts the threads (throws naming what failed)
  void stop();
  std::uint16_t port() const;
  DaemonStats stats() const;
  const DepthSource& depth_source() const { return *depth_; }
  // Per thread on the depth path (capture, process, network, head): what start() got for it.
  const std::vector<std::pair<std::string, std::string>>& scheduling() const { return scheduling_; }
  // The robot head's driver, made by start() (nullptr before). With a head, the daemon's head loop
  // uses it from start() to stop(): a driver is not thread-safe, so read it through stats().
  HeadDriver* head() { return head_.get(); }
  // Called on the processing thread with every processed frame, before it is published.
  void set_frame_observer(std::function<void(const ProcessedFrame&)> observer);

  // Runs until SIGINT/SIGTERM, the configured duration, the end of a non-looping recording, or a
  // thread that failed (an exception escaped it: logged, the threads stopped, the head left holding
  // its last target, exit 1), printing the stats line every second. Returns the process exit code.
  // A source that plays once (DepthSource::plays_once) starts when the first station connects, and
  // the daemon stays up after its end while that station is connected.
  int run();

 private:
  void capture_loop();
  void stereo_loop();
  void process_loop();
  // The eyes' encoder (throws std::invalid_argument naming --video-codec) and its hooks into the
  // server: PLIs and receiver reports.
  void open_eyes();
  void video_loop();
  // Puts the robot head's joints at the encoded pair's capture time in its header.
  void stamp_head_pose(std::vector<std::uint8_t>& encoded) const;
  // Network thread: the station's receiver report sets the eyes' bit rate (EyeRate).
  void on_receiver_report(const proto::ReceiverReport& report, std::int64_t received_ns);
  void head_loop();
  // The head's measured pose at time t (the remote's steady clock): interpolated between the head
  // loop's readings, extrapolated at most 20 ms past the newest; invalid without readings.
  HeadPose head_pose_at(std::int64_t t_ns) const;

  DaemonConfig config_;
  std::vector<std::pair<std::string, std::string>> scheduling_;  // set by start()
  std::unique_ptr<DepthSource> depth_;
  std::unique_ptr<StereoSource> stereo_;
  std::unique_ptr<EyeStream> eye_stream_;  // with stereo_: the eyes' encoder (video thread)
  std::unique_ptr<EyeRate> eye_rate_;      // its bit rate from receiver reports (network thread)
  std::unique_ptr<HeadDriver> head_;
  std::unique_ptr<RemoteServer> server_;
  FramePipeline pipeline_;
  LatestSlot<DepthFrame> depth_slot_;
  LatestSlot<StereoFrame> stereo_slot_;
  std::atomic<bool> running_{false};
  std::atomic<bool> source_ended_{false};
  // Sources that play once wait for these: a station connected, one that wants video.
  void log_plays_once() const;
  bool depth_released();
  bool eyes_released();
  std::atomic<bool> station_seen_{false}, video_seen_{false};
  std::atomic<EyeState> eyes_{EyeState::Off};
  std::thread capture_thread_, stereo_thread_, process_thread_, video_thread_, head_thread_;
  // Each thread's last-resort catch: run() ends the daemon with exit 1 and names the thread when
  // one has failed (the network thread's is the server's).
  ThreadFault capture_fault_{"capture (telex-capture)"}, stereo_fault_{"stereo (telex-stereo)"},
      process_fault_{"process (telex-process)"}, video_fault_{"video (telex-video)"},
      head_fault_{"head (telex-head)"};
  std::optional<ThreadFaultReport> thread_fault() const;
  // Head teleoperation: the operator's targets (network thread) and the measured poses (head
  // loop) read by the capture thread.
  bool head_driven_ = false;  // --head is not none
  mutable PiMutex head_mu_;
  HeadController head_control_;
  std::deque<HeadPose> head_history_;  // the last readings, oldest first
  HeadStats head_stats_;               // the driver's counts, copied by the head loop
  std::ofstream head_log_;             // --log-head, written by the head loop
  std::function<void(const ProcessedFrame&)> observer_;
  mutable PiMutex stats_mu_;
  DaemonStats stats_;
};

}  // namespace telex::remote
