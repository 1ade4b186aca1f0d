// SPDX-License-Identifier: MIT
// Hand tracker interface: fingertip states in the remote camera's frame, from any input device.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "telex/base/thread_fault.h"
#include "telex/common/rig.h"
#include "telex/haptics/body.h"
#include "telex/local/hand_model.h"

namespace telex {
struct Surface;  // telex/haptics/haptic_surface.h
}  // namespace telex

namespace telex::local {

inline constexpr int kFingerCount = 5;  // 0 thumb, 1 index, 2 middle, 3 ring, 4 little

struct Fingertip {
  int finger = 0;
  glm::dvec3 p_CameraFingertip{0.0};
  glm::dvec3 v_CameraFingertip{0.0};
  // Unit vector along the distal phalanx, pointing out of the fingertip: shear "along the finger"
  // is measured against it.
  glm::dvec3 axis_Camera{0.0, 0.0, 1.0};
  bool valid = false;
};

// A rigid body exactly as the tracking system reported it, in the tracker's own world frame.
struct TrackedBody {
  std::int32_t id = -1;
  glm::dvec3 p_m{0.0};
  glm::dquat q{1.0, 0.0, 0.0, 0.0};  // w, x, y, z
  bool valid = false;                // tracked in this frame
};
inline constexpr int kMaxTrackedBodies = 8;

// One arm as tracked, in the remote camera frame, for the view's body (both arms are drawn; the
// haptic fingertips are those of HandState::tips).
struct ArmTrack {
  bool wrist_valid = false;
  bool wrist_orientation = false;  // X_CameraWrist.q is measured (a NatNet hand body)
  Pose X_CameraWrist;              // the hand (wrist) rigid body
  bool shoulder_valid = false, elbow_valid = false;
  glm::dvec3 p_CameraShoulder{0.0}, p_CameraElbow{0.0};
  // Per finger: MCP, PIP, DIP, tip (valid with wrist_valid).
  std::array<std::array<glm::dvec3, 4>, kFingerCount> joints_camera{};
};

// One tracker sample, everything in the remote camera frame (x right, y down, z forward, metres).
struct HandState {
  // When the sample was taken, on the caller's clock (poll's now_ns); with NatNet, the poll that
  // took the newest accepted mocap frame (a glove-only update does not make old poses new).
  std::int64_t time_ns = 0;
  // When the poses in it were sampled, CLOCK_MONOTONIC ns, the start of the view's motion to
  // photon: NatNet's mid-exposure (the frame's arrival less the latency the server reports), or
  // with --head-source hmd the older of that and the headset pose's; a script's poll; a glove
  // report's arrival. 0: not known.
  std::int64_t motion_ns = 0;
  std::array<Fingertip, kFingerCount> tips{};
  // Joint chain per finger for drawing: knuckle (MCP), PIP, DIP, tip. Valid when skeleton_valid.
  std::array<std::array<glm::dvec3, 4>, kFingerCount> joints_camera{};
  glm::dvec3 wrist_camera{0.0};
  glm::dvec3 shoulder_camera{0.0};  // valid when shoulder_valid (NatNet with a shoulder body)
  bool skeleton_valid = false;
  bool shoulder_valid = false;
  // Both arms by Side (telex/haptics/body.h: 0 left, 1 right), NatNet only; the haptic hand's arm
  // repeats wrist_camera and shoulder_camera with the wrist's orientation and an elbow marker.
  std::array<ArmTrack, 2> arms{};
  // The operator's head as the robot camera's orientation in the head base's frame
  // (operator_head_in_base; NatNet with a head body): the fingertips above are in this camera.
  // The station sends it to the remote as head joints and, given a surface captured with the
  // robot head elsewhere, turns the fingertips into that surface's camera.
  bool head_valid = false;
  glm::dmat3 R_BaseCamera{1.0};
  // Raw rigid bodies behind this state (NatNet only; body_count 0 for scripts and gloves), logged
  // by --log-tracking.
  std::array<TrackedBody, kMaxTrackedBodies> bodies{};
  int body_count = 0;
  bool bodies_fresh = false;  // the bodies come from a new tracker frame
  // When the NatNet frame behind `bodies` was seen (its mid-exposure, CLOCK_MONOTONIC ns), whatever
  // the head source: --record-hmd-poses pairs the head body with the headset by it. 0: not known.
  std::int64_t bodies_sampled_ns = 0;
};

struct TrackerStats {
  std::uint64_t polls = 0;           // calls to poll()
  std::uint64_t updates = 0;         // polls that returned a new state
  std::uint64_t frames_in = 0;       // device frames received (packets, reports)
  std::uint64_t frames_dropped = 0;  // frames overwritten before a poll took them
  std::uint64_t parse_errors = 0;    // malformed packets / reports rejected
  std::uint64_t io_errors = 0;       // socket or device read failures
  // NatNet: datagrams not from the server's endpoints (dropped unread), frames whose number or
  // stamp jumped (dropped whole), tracked bodies whose pose failed the checks (NatNetClient,
  // PoseLimits) by reason, and frames the tracker set aside because the head or the haptic hand
  // was among those: the last good state stays, ageing.
  std::uint64_t foreign_datagrams = 0;
  std::uint64_t frame_jumps = 0;
  std::uint64_t rejected_nonfinite = 0, rejected_quaternion = 0, rejected_too_fast = 0;
  std::uint64_t frames_rejected = 0;
  std::uint64_t thread_faults = 0;  // exceptions that stopped a receive thread
};

// One device input of a tracker (the NatNet stream, a glove): the frames it has delivered, what
// it is ("NatNet frames from 10.0.0.5 (multicast ...)") and, for when it delivers none, what to
// check ("is Motive streaming ...?"). The station says it when an input falls silent.
struct TrackerInput {
  std::uint64_t frames = 0;
  std::string what, check;
};

// The counters a tracker updates on the polling (haptic) thread, read from any other (the
// station's status line) without a lock.
struct TrackerCounters {
  std::atomic<std::uint64_t> polls{0}, updates{0}, frames_in{0}, frames_rejected{0};
  TrackerStats snapshot() const {
    TrackerStats s;
    s.polls = polls;
    s.updates = updates;
    s.frames_in = frames_in;
    s.frames_rejected = frames_rejected;
    return s;
  }
};

// Everything a tracker spec may need beyond its own string.
struct TrackerConfig {
  // Depth (m) of the surface at the image centre; built-in scripts are planned against it, then
  // aim at the surface they are shown (ScriptTracker). The daemon sets it from the first received
  // surface before creating a script tracker.
  double surface_depth_m = 0.8;
  bool repeat = false;  // scripts: loop instead of running once

  // NatNet rigid body ids (-1 = not streamed).
  int head_body_id = 1;
  int right_hand_body_id = 2;
  int left_hand_body_id = -1;
  int right_shoulder_body_id = 3;
  int left_shoulder_body_id = -1;
  int right_elbow_body_id = -1;
  int left_elbow_body_id = -1;
  bool use_left_hand = false;  // the haptic fingertips are the left hand's
  int natnet_command_port = 1510;
  int natnet_data_port = 1511;
  std::string natnet_multicast_group = "239.255.42.99";
  std::string natnet_local_address = "0.0.0.0";  // interface to join the group on
  int realtime_priority = 0;  // the NatNet receive thread's SCHED_FIFO priority (0: none)
  // --head-source hmd: the operator's head is the headset's pose (in the NatNet frame) that this
  // returns (false: not tracked now), not the head marker body's. Empty: the head body (natnet).
  // `sampled_ns` (CLOCK_MONOTONIC) is when the headset's pose was located.
  std::function<bool(Pose& X_NatNetHead, std::int64_t& sampled_ns)> head_from_hmd;
  // Test seam (NatNetClientConfig::receive_hook), never set by telex-local.
  std::function<void()> natnet_receive_hook;

  HandModelConfig hand;  // the right hand's geometry and the head-to-camera offset
  HandGeometry left_hand = BodyDims::left_hand();  // the left hand's geometry
  // Finger bends (0 straight .. 1 fist) used when no glove is attached.
  std::array<double, kFingerCount> default_bend{0.3, 0.1, 0.3, 0.4, 0.4};
  // Glove spec combined with a NatNet wrist: "" (none), "5dt-usb[:PATH]", "5dt-serial:DEV".
  std::string glove_spec;
  std::string glove_calibration_path;  // JSON from docs/HARDWARE.md; empty = glove_range or full
  // The gloves' ranges by Side from the rig (operator.gloves), used when no path is given.
  std::array<std::optional<GloveRange>, 2> glove_range;
  // The other hand's glove (that hand is drawn, not felt).
  std::string other_glove_spec;
  // Wrist pose in the camera frame for a glove used without NatNet.
  glm::dvec3 p_CameraGloveWrist{0.0, 0.05, 0.45};
};

class HandTracker {
 public:
  virtual ~HandTracker();
  // Non-blocking: fills `out` with the newest state and returns true when a state newer than the
  // last one returned is available. Never throws, never allocates on the steady path.
  virtual bool poll(std::int64_t now_ns, HandState& out) = 0;
  // The surface the fingertips are felt against now (null: none yet), given on the polling thread
  // before each poll and valid until the next call. A scripted hand aims at it; a tracked one
  // follows the operator and ignores it.
  virtual void see_surface(const Surface* /*newest*/) {}
  virtual std::string name() const = 0;
  virtual TrackerStats stats() const = 0;
  // Its receive thread's scheduling (try_realtime's description); empty without a thread.
  virtual std::string scheduling() const { return {}; }
  // Its device inputs (none for a script), read from any thread as stats() is.
  virtual std::vector<TrackerInput> inputs() const { return {}; }
  // The first of its threads (NatNet, gloves) that an exception stopped; empty while all run.
  virtual std::optional<ThreadFaultReport> thread_fault() const { return std::nullopt; }
};

// Spec grammar (docs/HARDWARE.md):
//   script:press | script:stroke | script:tap | script:FILE
//   natnet:SERVER_IP[,multicast|,unicast][,local=IP][,cmd=PORT][,data=PORT][,version=X.Y]
//                                                          (glove from config.glove_spec)
//   5dt-usb[:HIDPATH] | 5dt-serial:DEV                     (glove alone, wrist fixed)
// Throws std::invalid_argument naming the spec and the valid forms; std::runtime_error when a
// device cannot be opened (the message names it and says what to try).
std::unique_ptr<HandTracker> make_tracker(const std::string& spec, const TrackerConfig& config);

// The spec's grammar alone, before anything starts (no device is opened, a script file is only
// checked to exist): throws std::invalid_argument as make_tracker would.
void check_hand_spec(const std::string& spec);

}  // namespace telex::local
