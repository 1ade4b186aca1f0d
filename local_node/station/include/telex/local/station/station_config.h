// SPDX-License-Identifier: MIT
// What the station's parts are given (StationConfig), the names of its loops and the error that
// names the thread that failed. The parts (src/) include this, not station.h.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "telex/common/rig.h"
#include "telex/haptics/haptic_model.h"
#include "telex/local/displays/haptic_display.h"
#include "telex/local/inputs/tracker.h"
#include "telex/local/link/surface_builder.h"
#include "telex/local/link/surface_client.h"
#include "telex/local/record/recorder.h"
#include "telex/local/station/station_summary.h"

namespace telex::local {

struct StationHeartbeat;  // display_supervisor.h

// The station's loops, each on its own thread (Main is the thread that called Station::run;
// Network is the SurfaceClient's thread, at each frame's manifest; Tracking the NatNet client's
// receive thread, at each datagram from the server).
enum class StationLoop { Main, Surface, Haptic, Network, Tracking };

// What run() throws when one of the station's threads (its own or a device's or the network
// client's) stopped on an exception: names the thread and the error.
class StationThreadError : public std::runtime_error {
 public:
  StationThreadError(std::string thread, const std::string& what)
      : std::runtime_error("the " + thread + " thread failed: " + what),
        thread_(std::move(thread)) {}
  const std::string& thread() const { return thread_; }

 private:
  std::string thread_;
};

struct StationConfig {
  ClientConfig client;
  std::string hand_spec = "script:press";
  TrackerConfig tracker;
  std::string haptics_spec = "sim";
  DisplayConfig display;
  HapticParams haptic;
  SurfaceOptions surface;
  double rate_hz = 1000.0;
  bool realtime = true;         // try SCHED_FIFO for the threads on the depth-to-force path
  int haptic_cpu = -1;          // --haptic-cpu: the CPU the haptic thread is pinned to (-1: any)
  double max_tile_age_s = 0.5;  // a missing tile keeps its last value this long
  // Force goes to zero at once while the link has been silent this long (no authenticated
  // message: ClientStats::alive_ns, kept young by 100 Hz probes) or the tracker's frames have
  // stopped this long, and ramps up again from zero when they return; 0: off (only the model's
  // --stale-limit fade).
  double link_silence_s = 0.035;
  double tracking_silence_s = 0.035;
  // Repair (docs/PROTOCOL.md 2.5; client.repair announces it): a tile asked for is asked again
  // after max(nack_retry_min_s, the stream's transit + 2 RTT); key frames at most this often.
  double nack_retry_min_s = 0.025;
  double key_request_interval_s = 0.25;
  double duration_s = 0.0;  // 0 = until stopped
  double first_surface_timeout_s = 10.0;
  std::filesystem::path log_forces_csv;    // empty = off
  int log_every = 1;                       // one row per finger every N ticks
  std::filesystem::path log_tracking_csv;  // empty = off
  // --record-hmd-poses (--view openxr with NatNet): `telex calibrate hmd`'s CSV, the headset's view
  // in STAGE and the NatNet head body at the same moments, 10 a second (hmd_pose_pairer.h).
  std::filesystem::path record_hmd_poses_csv;  // empty = off
  // ROS 1 bag of the session (docs/RECORDING.md); empty = off. Forces at record_rate_hz.
  std::filesystem::path record_bag;
  double record_rate_hz = 100.0;
  std::string view_spec = "none";  // none | png:DIR | window | hmd[:MONITOR] | openxr
  // --head-source: the operator's head from the NatNet head body ("natnet") or, with --view
  // openxr, the headset's pose ("hmd") placed in the NatNet frame by X_NatNetStage (the rig's
  // operator.hmd_stage_in_natnet).
  std::string head_source = "natnet";
  RigidTransform X_NatNetStage;
  // --view-at: png views are written once, this many seconds after the first haptic tick (a hand
  // script's time zero), instead of once a second and at the end (< 0: off).
  double view_at_s = -1.0;
  // --eye-size: each eye of the stereo view rendered at this size; empty: the eye video's size
  // when video comes, else the depth's.
  cv::Size eye_size;
  // --view-layout: "sbs" (the eyes side by side) or "fig7" (the right eye beside the normal map
  // with the touch vectors; png:DIR also writes fig7.png, a window shows it instead of the pair).
  std::string view_layout = "sbs";
  // --view-overlays: the status band and the normal-map inset drawn into each eye: "on", "off",
  // or "auto" (on, except with --view hmd, where the operator's eyes are in the headset).
  std::string view_overlays = "auto";
  // The remote's eye cameras: the left eye this far to the right eye's left (the synthetic stereo
  // source's 65 mm by default); the stereo view's left eye sees the depth from there.
  double stereo_baseline_m = 0.065;
  // --warp on|off: the stereo view reprojects each eye's video from the robot head's pose at its
  // capture to the operator's head now (telex/local/view/warp.h), when both are known: the remote
  // reports its head's joints with the depth frame the video is paired with, and the tracker
  // has the operator's head. Otherwise, or off, the video is shown as captured.
  bool view_warp = true;
  // Each eye's intrinsics and distortion (the rig's eyes.*), by Side: the view undistorts that
  // eye's video into the depth's pinhole camera, the left eye also rotated by R_RightEyeLeftEye
  // (rectified). Absent: the video is drawn as it comes.
  std::array<std::optional<CameraModel>, 2> eye_camera;
  glm::dmat3 R_RightEyeLeftEye{1.0};
  // The operator's body for the view (the rig's operator.body) and its colour (operator.skin_rgb).
  BodyDims body;
  cv::Vec3b skin_bgr{150, 175, 225};
  // Head teleoperation (docs/RIG.md robot_head): with a tracked head the station sends it as the
  // robot head's joint targets at head_rate_hz, and places the fingertips into each surface's
  // camera with the joints the head measured at its capture (when the remote reports them).
  RobotHead robot_head;
  bool head_teleop = true;
  // false: the fingertips are placed with the operator's current head even when the remote
  // reports its head's pose at capture (the naive transform, for comparison).
  bool head_captured_pose = true;
  double head_rate_hz = 200.0;
  // --deadman SPEC (deadman.h): a key or pedal that must be held for the robot head to move; its
  // state goes in every HeadCommand. Empty: none (the commands say "not used").
  std::string deadman_spec;
  // The haptic display channel each finger drives (thumb first), by the haptic hand's Side.
  std::array<std::array<int, kFingerCount>, 2> display_channel{{{0, 1, 2, 3, 4}, {0, 1, 2, 3, 4}}};
  double print_forces_hz = 0.0;  // live force lines on stdout (0 = off)
  bool status_line = true;       // one status line per second on stderr
  // --insecure: a plain link off loopback, accepted on purpose: every status line says so and a
  // warning goes to stderr every minute (main() warns at start).
  bool insecure = false;
  bool roi_requests = true;  // ask the remote for full-rate tiles near the hands
  // The display supervisor's heartbeat (telex-local's main sets it; nullptr: none, as with
  // --no-supervisor): the haptic loop beats every tick, and after the supervisor zeroed the
  // display (the station was stopped or hung) its forces start again from zero.
  StationHeartbeat* supervisor_heartbeat = nullptr;
  // Test seam, never set by telex-local: called at the top of every pass of the named loop; an
  // exception it throws takes that loop's error path (tests/integration/station_faults_test.cpp).
  std::function<void(StationLoop)> fault_hook;
};

}  // namespace telex::local
