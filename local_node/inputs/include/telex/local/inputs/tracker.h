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
#include "telex/local/inputs/hand_model.h"
#include "telex/local/inputs/hand_state.h"

namespace telex {
struct Surface;  // telex/haptics/haptic_surface.h
}  // namespace telex

namespace telex::local {

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
  virtual ~HandTracker() = default;
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

}  // namespace telex::local
