// SPDX-License-Identifier: MIT
// Operator-side network client: session over TCP, depth tiles over UDP or TCP, heartbeats with
// clock-offset estimation, ROI requests, and reconnection with back-off when the remote goes away.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "telex/base/thread_fault.h"
#include "telex/local/link/client_stats.h"
#include "telex/proto/messages.h"
#include "telex/proto/tls.h"

namespace telex::local {

struct ClientConfig {
  std::string host = "127.0.0.1";
  // host's addresses, resolved once at start (proto::resolve_host): the ones the loopback rule
  // checked are the ones connected to. Empty: host is resolved at each connect.
  std::vector<std::string> addresses;
  std::uint16_t port = 7300;
  bool use_udp = true;      // ask for depth over UDP (the remote may still choose TCP)
  bool want_video = false;  // ask for the eyes' video (EncodedVideo)
  bool frame_parts = true;  // take frames as an ROI part and a rest (PROTOCOL.md 2.4)
  bool repair = true;       // announce kCapRepair: the remote caches tiles for TileNacks (2.5)
  std::int64_t heartbeat_ns = 250'000'000;
  std::int64_t timeout_ns = 1'000'000'000;  // remote silent this long: disconnect and reconnect
  // During a session a Heartbeat probe this often (0: none beyond heartbeat_ns's): its answers
  // keep ClientStats::alive_ns young, so the haptic loop learns of a cut link in tens of ms.
  std::int64_t alive_probe_ns = 10'000'000;
  std::int64_t backoff_min_ns = 100'000'000;
  // At most half a second between attempts: a remote that was restarted is streaming to the
  // station within about that of its start (tools/fault_soak.sh: remote_kill).
  std::int64_t backoff_max_ns = 500'000'000;
  proto::DecodeLimits limits{};
  // Fault tests put telex-sim-impair in the depth path: bind UDP on udp_bind_port (0 = any) and
  // tell the remote to send to udp_announce_port (0 = the bound port), where the proxy listens.
  std::uint16_t udp_bind_port = 0;
  std::uint16_t udp_announce_port = 0;
  // --psk or --cert/--key/--ca: TLS 1.3 on TCP and sealed datagrams under keys exported from it
  // (docs/PROTOCOL.md section 7); nothing else is accepted. Neither: plain TCP and UDP.
  proto::TlsConfig tls;
  // SCHED_FIFO priority of the network thread (0: the scheduling it was started with). The
  // station asks for kStationPathPriority: tiles are decoded there, on the path to the force.
  int realtime_priority = 0;
};

// Callbacks run on the client's network thread; they must be quick (hand work to another thread).
struct ClientEvents {
  std::function<void(const proto::StreamConfig&)> on_config;
  std::function<void(const proto::Header&, const proto::DepthTile&)> on_tile;
  std::function<void(const proto::Header&, const proto::FrameManifest&)> on_manifest;
  std::function<void(const proto::Header&, const proto::EncodedVideo&)> on_video;
  // The remote's Stats counters (e.g. registration_rig = 1 after each StreamConfig).
  std::function<void(const proto::Stats&)> on_stats;
  std::function<void(ClientState, const std::string&)> on_state;  // with a human-readable reason
  // Dropped messages, at most one call a second (counts are in ClientStats).
  std::function<void(const std::string&)> on_warning;
  // The remote, or whoever answered, failed authentication: another key, no TLS, a certificate
  // in --psk mode, a Reject for authentication. Counted in auth_failed; the station logs an error.
  std::function<void(const std::string&)> on_auth_failed;
};

class SurfaceClient {
 public:
  SurfaceClient(ClientConfig config, ClientEvents events);
  ~SurfaceClient();
  SurfaceClient(const SurfaceClient&) = delete;
  SurfaceClient& operator=(const SurfaceClient&) = delete;

  void start();  // spawns the network thread; returns at once
  void stop();   // sends Bye when connected, joins the thread
  // Thread-safe: asks the remote for full-rate tiles in these rectangles.
  void request_roi(const proto::RoiRequest& roi);
  // Thread-safe: asks the remote to resend tiles (PROTOCOL.md 2.5), or for a key frame (a Stats
  // message with key_frame_request = 1). Dropped when no session is up.
  void send_nack(const proto::TileNack& nack);
  // The operator's head as joint targets (PROTOCOL.md 2.6); dropped while not connected.
  void send_head(const proto::HeadCommand& head);
  void request_key_frame();
  // Thread-safe: a Picture Loss Indication for the eyes (PROTOCOL.md 2.7); dropped when no
  // session is up.
  void send_picture_loss(const proto::PictureLoss& pli);
  // Thread-safe: asks for lost pairs again (PROTOCOL.md 2.7); dropped when no session is up.
  void send_video_nack(const proto::VideoNack& nack);

  const ClientStats& stats() const { return stats_; }
  // What the network thread got (try_realtime's description); empty before start().
  const std::string& scheduling() const { return scheduling_; }
  ClientState state() const { return static_cast<ClientState>(stats_.state.load()); }
  // The network thread stops on an exception (its own or an event handler's) instead of
  // terminating the process; the owner polls this and stops (the station: with zero force).
  std::optional<ThreadFaultReport> thread_fault() const;

 private:
  struct Impl;
  ClientStats stats_;
  std::string scheduling_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace telex::local
