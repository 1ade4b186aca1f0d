// SPDX-License-Identifier: MIT
// NatNet client: connects to a Motive server, parses frames on its own thread, hands out the
// newest rigid-body poses without blocking the caller.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "telex/base/triple_buffer.h"
#include "telex/local/hand_model.h"
#include "telex/local/natnet.h"

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
};

// "SERVER_IP[,multicast|,unicast][,local=IP][,cmd=PORT][,data=PORT][,version=X.Y]" (the
// station's natnet: spec after its prefix, `telex calibrate body --natnet`) over `base`. Throws
// std::invalid_argument starting with `what` and naming the valid options.
NatNetClientConfig parse_natnet_spec(std::string_view text, const std::string& what,
                                     NatNetClientConfig base = {});

struct NatNetSample {
  static constexpr int kMaxBodies = 8;
  struct Body {
    std::int32_t id = -1;
    Pose pose;
    bool present = false;  // in this frame
    bool valid = false;    // present and tracked
  };
  std::uint32_t frame_number = 0;
  double timestamp_s = 0;        // server clock (2.6+), else the arrival time
  std::int64_t received_ns = 0;  // steady clock on receipt
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
};

// Owns one thread running its io_context: the haptic thread only calls latest(), which never
// blocks. The constructor opens and binds the sockets and throws std::runtime_error naming the
// address and port when it cannot.
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
  const std::string& scheduling() const { return scheduling_; }  // the receive thread's

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  TripleBuffer<NatNetSample> samples_;
  std::thread thread_;
  std::string scheduling_;
};

}  // namespace telex::local
