// SPDX-License-Identifier: MIT
// Recording a station session to a ROS 1 bag (standard message types only, so rqt_bag,
// PlotJuggler and Foxglove open it as it is), and replaying one through the same surface build and
// force model. Topics and units: docs/RECORDING.md.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <thread>

#include "telex/base/spsc_ring.h"
#include "telex/base/thread_fault.h"
#include "telex/haptics/haptic_model.h"
#include "telex/local/inputs/tracker.h"
#include "telex/local/link/surface_builder.h"

namespace telex::bag {
class Writer;
}

namespace telex::local {

// Topic names (docs/RECORDING.md).
inline constexpr const char* kDepthTopic = "/telex/depth/image_raw";
inline constexpr const char* kDepthInfoTopic = "/telex/depth/camera_info";
inline constexpr const char* kFingertipsTopic = "/telex/fingertips";
inline constexpr const char* kConfigTopic = "/telex/config";
inline constexpr const char* kCameraFrame = "telex_camera";
// The remote's registration, JSON {"registration": "hardware"|"rig"|"none", "depth_pixels": ...},
// written before the first surface it applies to and again whenever it changes.
inline constexpr const char* kRemoteTopic = "/telex/remote";
std::string force_topic(int finger);    // /telex/force/<finger>: WrenchStamped, camera frame
std::string display_topic(int finger);  // /telex/display/<finger>: what the display was commanded
const char* finger_name(int finger);    // thumb, index, middle, ring, little

// The parameters a replay needs, as the session's /telex/config message holds them.
nlohmann::json session_config_json(const HapticParams& haptic, const SurfaceOptions& surface,
                                   double rate_hz);
// Reads them back; fields the JSON lacks keep the values passed in. Throws std::invalid_argument
// naming a field of the wrong type.
void apply_session_config(const nlohmann::json& j, HapticParams& haptic, SurfaceOptions& surface,
                          double& rate_hz);

// One haptic tick as the model saw it and what it gave, re-expressed in the newest surface's camera
// (reexpress): the Model frame of a replay against the recorded surfaces.
struct RecordedTick {
  std::int64_t t_ns = 0;  // station monotonic clock
  std::uint64_t surface_seq = 0;
  std::array<FingertipInput, kFingerCount> in{};
  std::array<FingertipForce, kFingerCount> out{};
};

// One surface as it was built: the depth as received and the station's sequence number.
struct RecordedSurface {
  std::uint64_t seq = 0;
  std::int64_t built_ns = 0;    // station monotonic clock
  std::int64_t capture_ns = 0;  // as the Surface holds it (the remote's clock)
  cv::Mat1w depth_mm;           // a private copy
  Intrinsics intrinsics;
  // The remote's --registration as its session said it ("" = not said: an older remote).
  std::string registration;
};

// What pixels a remote registration leaves the depth in, as /telex/remote names them.
std::string_view depth_pixels_of_registration(std::string_view registration);

struct RecorderConfig {
  std::string path;
  double force_rate_hz = 100.0;  // forces, display commands and fingertip frames on /tf
  double tick_rate_hz = 1000.0;  // the haptic loop's: those are written every N-th tick
  std::string config_json;       // written once on /telex/config
  // Bag stamps are CLOCK_MONOTONIC + this (the wall clock at the start of the session), so ROS
  // tools show the session's date; differences are kept to the nanosecond.
  std::int64_t monotonic_to_bag_ns = 0;
  std::size_t tick_queue = 8192;  // ~8 s of ticks at 1 kHz
  std::size_t surface_queue = 32;
  std::size_t body_queue = 1024;
};

struct RecorderStats {
  std::uint64_t ticks = 0, surfaces = 0, body_frames = 0;  // written
  std::uint64_t dropped_ticks = 0, dropped_surfaces = 0, dropped_bodies = 0;
  std::string error;  // the writer's failure (the recording stopped there), or empty
};

// Writes a session to a bag on its own thread. The producers never wait: each queue is a bounded
// lock-free ring (ticks and bodies from the station's main thread, surfaces from the surface
// thread); what does not fit is dropped and counted. A write failure (disk full) or any other
// exception stops the writer thread: the error is kept, reported by stats() and thread_fault(),
// and the station stops on it (a session that is not being recorded as asked is not run on).
class SessionRecorder {
 public:
  // Opens the bag (throws std::runtime_error naming the file) and starts the writer.
  explicit SessionRecorder(RecorderConfig config);
  // Stops the writer after it has written everything queued, and closes the bag.
  ~SessionRecorder();
  SessionRecorder(const SessionRecorder&) = delete;
  SessionRecorder& operator=(const SessionRecorder&) = delete;

  bool add_tick(const RecordedTick& tick);
  bool add_surface(const RecordedSurface& surface);
  bool add_bodies(const HandState& state);
  // Writes what is queued, closes the bag and returns the totals (idempotent).
  RecorderStats finish();
  RecorderStats stats() const;
  std::optional<ThreadFaultReport> thread_fault() const { return fault_.report(); }
  const std::string& path() const { return cfg_.path; }

 private:
  void writer_loop(std::stop_token stop);
  bool write_pending();
  void write_tick(const RecordedTick& t);
  void write_surface(const RecordedSurface& s);
  void write_bodies(const HandState& h);

  RecorderConfig cfg_;
  std::unique_ptr<bag::Writer> writer_;
  SpscRing<RecordedTick> ticks_;
  SpscRing<RecordedSurface> surfaces_;
  SpscRing<HandState> bodies_;
  std::uint64_t force_every_;  // ticks
  std::uint64_t tick_count_ = 0;
  std::string registration_written_;  // writer thread: the last /telex/remote's
  std::atomic<std::uint64_t> ticks_written_{0}, surfaces_written_{0}, bodies_written_{0};
  mutable std::mutex error_mu_;
  std::string error_;
  bool finished_ = false;
  RecorderStats final_{};
  ThreadFault fault_{"recorder (bag writer)"};
  std::jthread thread_;  // last: stopped first
};

// What replaying a recorded session gave against what was recorded.
struct ReplayResult {
  std::uint64_t ticks = 0;      // ticks re-run
  std::uint64_t surfaces = 0;   // surfaces rebuilt
  std::uint64_t rows = 0;       // recorded force samples compared (one per finger per sample)
  std::uint64_t unmatched = 0;  // recorded force samples with no tick of the same time
  double rms_diff_N = 0;        // RMS of |F_replayed - F_recorded| over the rows
  double max_diff_N = 0;
  double peak_N = 0;           // largest |F| the replay gave at the recorded samples
  double recorded_peak_N = 0;  // largest recorded |F|
};

// Up to `max_frames` of a recorded session's depth frames (as received), spread evenly over the
// session, with their intrinsics; seq is the station's surface sequence number and built_ns the
// bag time. Throws std::runtime_error naming the file when it holds no session depth.
std::vector<RecordedSurface> read_session_depth(const std::string& bag_path,
                                                std::size_t max_frames);

// The recorded session's parameters (its /telex/config), for a replay to start from. Throws
// std::runtime_error naming the file when the bag is not a telex session.
void read_session_config(const std::string& bag_path, HapticParams& haptic, SurfaceOptions& surface,
                         double& rate_hz);

// Told the fraction (0..1] of a session's recorded ticks a replay has re-run: about every per cent,
// and 1 at the end.
using ReplayProgress = std::function<void(double done)>;

// Re-runs the surface build (over the whole frame) and the force model, tick by tick, on the
// recorded depth and fingertips, and compares with the recorded forces.
ReplayResult replay_session(const std::string& bag_path, const HapticParams& haptic,
                            const SurfaceOptions& surface, const ReplayProgress& progress = {});

}  // namespace telex::local
