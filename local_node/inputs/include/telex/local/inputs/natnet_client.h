// SPDX-License-Identifier: MIT
// NatNet client: connects to a Motive server, parses frames on its own thread, hands out the
// newest rigid-body poses without blocking the caller.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "telex/base/thread_fault.h"
#include "telex/base/triple_buffer.h"
#include "telex/local/inputs/hand_model.h"
#include "telex/natnet/natnet.h"

namespace telex::local {

struct NatNetClientConfig {
  std::string server_ip = "127.0.0.1";
  bool multicast = true;  // false: frames arrive on the command socket (unicast)
  std::string multicast_group = natnet::kMulticastGroup;
  std::string local_address = "0.0.0.0";  // interface to join the group on
  int command_port = natnet::kCommandPort;
  int data_port = natnet::kDataPort;
  std::string app_name = "telex-local";
  // Layout to parse before (or instead of) the server's answer; unset = wait for PINGRESPONSE.
  std::optional<natnet::Version> version;
  std::vector<std::int32_t> body_ids;  // rigid bodies to publish (at most kMaxBodies)
  // SCHED_FIFO priority of the receive thread (0: the scheduling it was started with): the
  // station asks for kStationPathPriority, as the hand's pose is on the path to the force.
  int realtime_priority = 0;
  // Test seam, never set by telex-local: called on the receive thread for every datagram from the
  // server before it is parsed; an exception it throws takes that thread's fault path.
  std::function<void()> receive_hook;
};

// What every tracked rigid body must pass before a frame carries it (docs/HARDWARE.md, "What the
// station checks"). The defaults pass real Motive data with a wide margin and reject what no
// operator can do.
struct PoseLimits {
  // Motive's volumes are tens of metres at most; a coordinate beyond this is corrupt.
  double max_abs_coordinate_m = 100.0;
  // Motive sends unit quaternions in float32: |q| is within about 1e-6 of 1. Within this
  // tolerance the quaternion is normalised; beyond it the pose is rejected.
  double quaternion_norm_tolerance = 1e-3;
  // Hand and head speeds while teleoperating stay below 3 m/s and a boxer's punch peaks near
  // 10 m/s; two bodies swapped by a labelling error jump by their distance (0.3 m in one 120 Hz
  // frame is 36 m/s). Faster than this, plus jump_slack_m for noise, is rejected.
  double max_speed_m_per_s = 10.0;
  double jump_slack_m = 0.01;
};

enum class PoseVerdict { Ok, NonFinite, BadQuaternion, TooFast };
std::string_view to_string(PoseVerdict v);

// One body's pose from a frame against `limits` (pure). `previous` is the body's last accepted
// pose, `dt_s` the time since it (ignored without one). On Ok, `out` holds the pose with its
// quaternion normalised.
PoseVerdict check_pose(const natnet::RigidBody& body, const PoseLimits& limits,
                       const Pose* previous, double dt_s, Pose& out);

// A frame's place in the server's stream (its number and its server stamp, seconds) and when it
// arrived here (steady clock).
struct FrameStamp {
  std::uint32_t frame_number = 0;
  double timestamp_s = 0;
  std::int64_t received_ns = 0;
};

// How a frame's number and stamp may move against the last accepted frame's (docs/HARDWARE.md,
// "What the station checks"): forward, and by no more than the time between their arrivals here
// allows, so a sender's own stamps never vouch for themselves.
struct TimelineLimits {
  // Motive's cameras run at 1000 Hz at most; twice that bounds how fast frame numbers advance.
  double max_rate_hz = 2000.0;
  // How far a frame's stamp (and its number, at max_rate_hz) may run ahead of the time between
  // the arrivals: a server's jitter and a burst after a stalled network stay well within it.
  double max_ahead_s = 0.25;
  // No frame accepted for this long: the next one starts a new timeline (a restarted Motive
  // counts from zero again, a take played in a loop goes back at each loop).
  double resync_s = 0.5;
  // The speed check's dt: the stamps' difference, but at most the arrivals' plus this (frames
  // that queued in a stalled network arrive together yet moved for their stamps' dt).
  double max_dt_over_arrival_s = 0.05;
};

enum class FrameVerdict { Ok, NewTimeline, Backwards, TooFarAhead };
std::string_view to_string(FrameVerdict v);

// `frame` against `previous`, the last accepted frame (pure). Backwards: its number is not above
// the previous one's (a repeat included) or its stamp is below; TooFarAhead: either ran further
// ahead than max_ahead_s past the arrivals' difference allows; NewTimeline: nothing was accepted
// for resync_s, so anything goes.
FrameVerdict check_frame(const FrameStamp& previous, const FrameStamp& frame,
                         const TimelineLimits& limits);

// The dt check_pose takes between a body's last accepted pose (in `previous`) and `frame`: the
// stamps' difference, at most the arrivals' plus max_dt_over_arrival_s; the arrivals' alone when
// the stamps went back (another timeline).
double speed_check_dt_s(const FrameStamp& previous, const FrameStamp& frame,
                        const TimelineLimits& limits);

// "SERVER_IP[,multicast|,unicast][,local=IP][,cmd=PORT][,data=PORT][,version=X.Y]" (the
// station's natnet: spec after its prefix, `telex calibrate body --natnet`) over `base`. Throws
// std::invalid_argument starting with `what` and naming the valid options.
NatNetClientConfig parse_natnet_spec(std::string_view text, const std::string& what,
                                     NatNetClientConfig base = {});

// --natnet-multicast's group: throws std::invalid_argument unless it is an IPv4 multicast address.
void check_multicast_group(const std::string& group);

// The latency a server reports for a frame, from the cameras' mid-exposure to its transmission
// (ns, pure): NatNet 3.0+'s stamps over the server's high-resolution clock (`high_res_clock_hz`,
// from its SERVERINFO), 2.x's software latency. 0 when the frame says nothing usable: no clock
// rate, stamps unset or out of order, a latency outside 0..1 s.
std::int64_t natnet_reported_latency_ns(const natnet::Frame& frame, const natnet::Version& v,
                                        std::uint64_t high_res_clock_hz);

struct NatNetSample {
  static constexpr int kMaxBodies = 8;
  struct Body {
    std::int32_t id = -1;
    Pose pose;
    bool present = false;   // in this frame
    bool valid = false;     // present, tracked and its pose passed check_pose
    bool rejected = false;  // present and tracked, but its pose failed check_pose (pose unset)
  };
  std::uint32_t frame_number = 0;
  double timestamp_s = 0;        // server clock (2.6+), else the arrival time
  std::int64_t received_ns = 0;  // steady clock on receipt
  // When the cameras exposed it, steady clock: the arrival less the latency the server reports
  // (natnet_reported_latency_ns), or the arrival when it reports none.
  std::int64_t mid_exposure_ns = 0;
  std::array<Body, kMaxBodies> bodies{};
  const Body* find(std::int32_t id) const;
};

struct NatNetClientStats {
  std::uint64_t datagrams = 0;
  std::uint64_t frames = 0;
  std::uint64_t parse_errors = 0;
  std::uint64_t before_version = 0;  // frames dropped while the layout was still unknown
  std::uint64_t pings_sent = 0;
  std::uint64_t io_errors = 0;
  // Datagrams not from the server's endpoints (another address, or another port of its address
  // than its command port and its frames' learnt source): dropped, never believed.
  std::uint64_t foreign_datagrams = 0;
  // Frames whose number or stamp went back, or ran further ahead than their arrival allows
  // (check_frame): dropped whole.
  std::uint64_t frame_jumps = 0;
  // Tracked bodies whose pose check_pose rejected, by reason (a frame with a non-finite
  // timestamp counts once under rejected_nonfinite).
  std::uint64_t rejected_nonfinite = 0, rejected_quaternion = 0, rejected_too_fast = 0;
  std::uint64_t thread_faults = 0;  // exceptions that stopped the receive thread
};

// Owns one thread running its io_context: the haptic thread only calls latest(), which never
// blocks. The constructor opens and binds the sockets and throws std::runtime_error naming the
// address and port when it cannot. Only the server's endpoints are read: its replies from its
// command endpoint (SERVER_IP:cmd), its frames from that endpoint or from the one source port of
// its address that the client learns and pins (natnet_client.cpp says how); each frame must pass
// check_frame and each tracked body check_pose. An exception on the receive thread stops it and is
// kept in thread_fault().
class NatNetClient {
 public:
  explicit NatNetClient(NatNetClientConfig config);
  ~NatNetClient();
  NatNetClient(const NatNetClient&) = delete;
  NatNetClient& operator=(const NatNetClient&) = delete;

  bool latest(NatNetSample& out) { return samples_.take(out); }
  std::optional<natnet::ServerInfo> server_info() const;
  NatNetClientStats stats() const;
  std::uint64_t overwritten() const { return samples_.overwritten(); }
  std::string last_error() const;  // reason of the newest rejected packet (for logs)
  int command_port() const;        // the command socket's local port (replies arrive there)
  std::optional<ThreadFaultReport> thread_fault() const;
  const std::string& scheduling() const { return scheduling_; }  // the receive thread's

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  TripleBuffer<NatNetSample> samples_;
  std::thread thread_;
  std::string scheduling_;
};

}  // namespace telex::local
