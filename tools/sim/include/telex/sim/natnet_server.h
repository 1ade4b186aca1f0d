// SPDX-License-Identifier: MIT
// A NatNet server (what telex-sim-natnet runs): answers connect requests and streams frames. A
// simulator of the other end of the station's NatNet client, so it lives with the tools.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "telex/natnet/natnet.h"

namespace telex::sim {

namespace natnet = local::natnet;

struct NatNetServerConfig {
  std::string bind_address = "127.0.0.1";
  int command_port = natnet::kCommandPort;  // 0 = any free port (tests); see command_port()
  bool multicast = false;  // true: frames to group:data_port; false: to each connected client
  std::string multicast_group = natnet::kMulticastGroup;
  std::string multicast_interface = "127.0.0.1";
  int data_port = natnet::kDataPort;
  natnet::Version version{3, 1};
  double rate_hz = 120.0;
  std::string app_name = "telex-sim-natnet";
  // The latency each frame reports from its cameras' mid-exposure to its transmission (3.0+'s
  // stamps, 2.x's software latency), as Motive's is a few milliseconds.
  double reported_latency_s = 0.004;
};

// Fills frame.rigid_bodies (and anything else) for time t_s since the start of streaming.
using NatNetMotion = std::function<void(double t_s, natnet::Frame& frame)>;

// Rigid body ids of the built-in motions.
inline constexpr std::int32_t kSimHeadId = 1;
inline constexpr std::int32_t kSimRightHandId = 2;
inline constexpr std::int32_t kSimRightShoulderId = 3;

// Operator standing still (head at 1.6 m, Motive axes, looking along -z); the right hand starts
// 0.25 m in front of the eyes and pushes to 0.55 m and back, period 4 s. Palm faces forward-down so
// the index points into the scene.
void natnet_press_motion(double t_s, natnet::Frame& frame);

// The same operator and hand, pressing into a surface `surface_depth_m` in front of the eyes (the
// station's default camera, 8 cm in front of the head body): the index fingertip (default hand
// geometry, straight) travels from kPressTipStartM short of the surface to kPressTipPastM beyond
// it and back, period 4 s. Throws std::invalid_argument outside [0.35, 5] m.
inline constexpr double kPressTipStartM = 0.30;
inline constexpr double kPressTipPastM = 0.04;
inline constexpr double kPressEyesAheadOfHeadM = 0.08;
NatNetMotion natnet_press_toward(double surface_depth_m);
// The same hand held still with the index tip kPressTipPastM / 2 beyond the surface: a steady
// press, so a fault shows as the force leaving and coming back (tools/fault_soak.sh).
NatNetMotion natnet_hold_toward(double surface_depth_m);
// How far ahead of the hand body the straight index fingertip is in the press's hand orientation.
double press_index_tip_ahead_of_hand_m();

// The press motion with the head body turning as telex/sim/head_turns.h's (on CLOCK_MONOTONIC, at
// the moment the frame says its cameras saw it: its sending less `reported_latency_s`), for the
// project's OpenXR runtime reporting the headset on that head.
NatNetMotion natnet_head_turns(double reported_latency_s);

// A recorded motion: CSV with header "time_s,body_id,x,y,z,qx,qy,qz,qw", one body per line, lines
// sorted by time; a frame plays every body whose newest line is at or before t (looping when
// `loop`). Throws std::runtime_error naming the file and line on bad input.
NatNetMotion load_natnet_csv(const std::filesystem::path& path, bool loop);

// The simulator's high-resolution clock (its frames' stamps and the server info's frequency).
inline constexpr std::uint64_t kSimClockHz = 10'000'000;

// The name a model description gives a body of the built-in motions ("body_ID" for others).
std::string body_name(std::int32_t id);

struct NatNetServerStats {
  std::uint64_t frames_sent = 0;
  std::uint64_t pings_answered = 0;
  std::uint64_t model_defs_answered = 0;
  std::uint64_t echoes_answered = 0;
  std::uint64_t clients = 0;
  std::uint64_t send_errors = 0;
};

class NatNetServer {
 public:
  // Binds the command socket; throws std::runtime_error naming address and port on failure.
  NatNetServer(NatNetServerConfig config, NatNetMotion motion);
  ~NatNetServer();
  int command_port() const;  // actually bound
  // Streams until `duration_s` has passed (0 = no end) or stop() is called; blocks the calling
  // thread.
  void run_for(double duration_s);
  void stop();  // thread-safe
  NatNetServerStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace telex::sim
