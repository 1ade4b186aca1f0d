// SPDX-License-Identifier: MIT
// The remote node's network side: TCP control (one operator at a time), depth and video over UDP or
// TCP.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "telex/base/thread_fault.h"
#include "telex/proto/messages.h"
#include "telex/proto/tls.h"
#include "telex/remote/pipeline.h"
#include "telex/remote/repair_cache.h"

namespace telex::remote {

struct ServerConfig {
  std::string host = "127.0.0.1";
  std::uint16_t port = 7300;  // 0 = any free port (tests)
  bool force_tcp = false;  // depth and video on the TCP connection even when the client offers UDP
  std::chrono::milliseconds client_timeout{3000};  // a silent operator is dropped after this
  std::size_t repair_cache_frames = 8;  // frames whose tiles a TileNack can still get (0 = none)
  std::size_t max_queued_frames = 3;    // depth frames waiting to go out; older ones are dropped
  // Video frames waiting, apart from depth and sent after it (send_queue.h); older ones dropped.
  std::size_t max_queued_video_frames = 2;
  RepairLimiter::Config repair_limits;     // what TileNacks may make the remote resend
  proto::Codec codec = proto::Codec::Zip;  // preferred; the client's list decides when it lacks it
  bool video_available = false;            // a stereo source is configured
  float fps = 30.0f;
  // The run's --registration ("none" | "hardware" | "rig"): told to each station after the stream
  // configuration as a Stats counter "registration_<name>" = 1 (its recording keeps it).
  std::string registration = "none";
  // --psk or --cert/--key/--ca: the TCP connection runs TLS 1.3 and every datagram is sealed
  // under keys exported from it (docs/PROTOCOL.md section 7); nothing unauthenticated is acted on.
  // Neither: plain TCP and UDP.
  proto::TlsConfig tls;
  // The operator's head as joint targets (PROTOCOL.md 2.6), with the time it was received (steady
  // clock) and that time on the station's clock (the offset the remote's own heartbeat probes
  // measure, OperatorClock; nullopt until the station answered one): called on the network
  // thread, so it must not block. Unset: counted and dropped.
  std::function<void(const proto::HeadCommand&, std::int64_t received_ns,
                     std::optional<std::int64_t> station_received_ns)>
      on_head_command;
  // The station's Picture Loss Indications and receiver reports (PROTOCOL.md 2.7), on the network
  // thread (must not block): the eyes' encoder makes an intra pair; a rate controller reads the
  // reports. Unset: counted only.
  std::function<void(const proto::PictureLoss&)> on_picture_loss;
  std::function<void(const proto::ReceiverReport&, std::int64_t received_ns)> on_receiver_report;
  // SCHED_FIFO priority of the network thread, which packs and sends every depth tile (0: the
  // scheduling it was started with). The daemon asks for kRemotePathPriority.
  int realtime_priority = 0;
};

// Why an operator's session ended; each is logged and counted (ServerCounters::sessions_ended).
enum class SessionEnd : std::uint8_t {
  ClientBye,       // the station said Bye
  ConnectionLost,  // the TCP connection closed or broke under a read
  WriteFailed,     // a write to the station failed
  ClientSilent,    // nothing that verified arrived for client_timeout
  Unparseable,     // the stream's framing broke (the byte boundary is lost)
  Refused,         // refused after connecting: not Hello first, wrong version, authentication
  ServerStopping,
};
inline constexpr std::size_t kSessionEndCount = 7;
std::string_view session_end_name(SessionEnd reason);

// Monotonic counters, readable from any thread.
struct ServerCounters {
  std::atomic<std::uint64_t> clients_accepted{0};
  std::atomic<std::uint64_t> clients_rejected{0};
  std::atomic<std::uint64_t> client_timeouts{0};
  std::atomic<std::uint64_t> frames_sent{0};
  std::atomic<std::uint64_t> frames_dropped{0};  // depth frames dropped from a full send queue
  std::atomic<std::uint64_t> video_frames_dropped{0};  // video frames dropped from theirs
  std::atomic<std::uint64_t> messages_sent{0};
  std::atomic<std::uint64_t> datagrams_sent{0};
  std::atomic<std::uint64_t> bytes_sent{0};  // depth + video payload bytes on the wire (UDP or TCP)
  std::atomic<std::uint64_t> video_bytes_sent{0};     // of them the eyes' (EncodedVideo)
  std::atomic<std::uint64_t> video_pairs_sent{0};     // EncodedVideo messages sent whole
  std::atomic<std::uint64_t> plis_in{0};              // PictureLoss from the station
  std::atomic<std::uint64_t> receiver_reports_in{0};  // ReceiverReport from the station
  std::atomic<std::uint64_t> malformed_in{0};  // messages from the client rejected by the parser
  // Refused by authentication (not in malformed_in): auth_failed counts TLS handshakes that failed
  // (another key, no TLS, a certificate the CA does not vouch for) and datagrams to the server's
  // UDP port that do not open under the station->remote key (forged, or reflected: a datagram the
  // remote sent is sealed under the other direction's key); unsealed: plain datagrams there while
  // the link is sealed; replayed: authentic datagrams seen before. udp_ignored: datagrams at that
  // port that open or arrive on a plain link: no message travels that way yet, so none is acted on.
  std::atomic<std::uint64_t> auth_failed{0};
  std::atomic<std::uint64_t> unsealed{0};
  std::atomic<std::uint64_t> replayed{0};
  std::atomic<std::uint64_t> udp_ignored{0};
  // Connections before authentication (server_pending.cpp): closed to make room under a cap (or
  // to give back a descriptor), closed for not finishing the handshake and Hello in time; and
  // failed accepts (out of descriptors: each followed by a pause, never a spin).
  std::atomic<std::uint64_t> preauth_evicted{0};
  std::atomic<std::uint64_t> preauth_timeouts{0};
  std::atomic<std::uint64_t> accept_errors{0};
  std::atomic<std::uint64_t> key_frame_requests{0};
  std::atomic<std::uint64_t> head_commands_in{0};  // HeadCommands from the station
  // Repair (PROTOCOL.md 2.5): TileNacks in, tiles resent from the cache, requested tiles the cache
  // no longer held (each of those makes the next frame a key frame).
  std::atomic<std::uint64_t> nacks_in{0};
  std::atomic<std::uint64_t> repair_tiles_sent{0};
  std::atomic<std::uint64_t> repair_unavailable{0};
  // What bounds NACK answers (RepairLimiter): resends (tiles and pairs) asked again within the
  // dedup interval, resends beyond the byte budget, tiles refused because the send queue already
  // held kMaxQueuedRepairBytes of resends (a station that does not read; pairs refused so are
  // video_repair_over_queue).
  std::atomic<std::uint64_t> repair_duplicates{0};
  std::atomic<std::uint64_t> repair_over_budget{0};
  std::atomic<std::uint64_t> repair_over_queue{0};
  // The eyes' repair (PROTOCOL.md 2.7): VideoNacks in, pairs sent again (kFlagRepair), pairs asked
  // for that the cache no longer held (the station's PLI recovers those), pairs refused because
  // the send queue already held kMaxQueuedRepairBytes of resends. The dedup interval and the byte
  // budget above bound them too (one budget for all resends).
  std::atomic<std::uint64_t> video_nacks_in{0};
  std::atomic<std::uint64_t> video_pairs_resent{0};
  std::atomic<std::uint64_t> video_repair_unavailable{0};
  std::atomic<std::uint64_t> video_repair_over_queue{0};
  // Control messages not queued because the station does not read them: heartbeat answers beyond
  // kMaxHeartbeatBacklog, anything beyond kMaxControlQueue.
  std::atomic<std::uint64_t> control_dropped{0};
  std::array<std::atomic<std::uint64_t>, kSessionEndCount> sessions_ended{};  // by SessionEnd
  std::uint64_t ended(SessionEnd reason) const {
    return sessions_ended[static_cast<std::size_t>(reason)].load();
  }
};

enum class ClientState { Waiting, Connected };
std::string_view client_state_name(ClientState state);

// Owns an io_context and its thread; split as Asio's chat server is: the acceptor and the one-
// operator policy (server.cpp), the connected operator's session (server_session.cpp), and the
// transport of frames over UDP or TCP (server_transport.cpp), with their shared declarations in
// src/server_impl.h. publish*() are called from the processing thread: they encode
// on the caller's thread and hand finished buffers to the network thread.
class RemoteServer {
 public:
  explicit RemoteServer(
      ServerConfig config);  // binds now; throws std::runtime_error naming HOST:PORT
  ~RemoteServer();
  RemoteServer(const RemoteServer&) = delete;
  RemoteServer& operator=(const RemoteServer&) = delete;

  void start();
  void stop();

  std::uint16_t port() const;  // the bound TCP port
  ClientState state() const;
  bool video_wanted() const;  // the connected client asked for video
  // A standing fact for the station (docs/PROTOCOL.md, Stats): sent now as a Stats counter
  // `key` = 1 to the connected operator and to every later one right after its Accept. Keys:
  // "source_ended" (the depth source played to its end), "eyes_ended" (the stereo source did).
  // The server adds "eyes_off" itself for a station that asks for video when there is no
  // stereo source. Any thread.
  void tell(const std::string& key);
  const ServerCounters& counters() const;
  // What the network thread got (try_realtime's description); empty before start().
  const std::string& scheduling() const;
  // The network thread's last-resort catch (the daemon polls it).
  const ThreadFault& fault() const;

  // The receiver's wishes for the next frame; clears a pending key-frame request.
  FrameRequest take_request();
  // Queues one processed frame (tiles + manifest) for the connected client; no-op without one.
  void publish(const ProcessedFrame& frame);
  // Queues tiles[from, end) of a part still being encoded (FramePipeline's tile sink) ahead of
  // it; publish() of the finished part then sends only what was not streamed, and the manifest.
  void publish_tiles(const ProcessedFrame& part, std::size_t from);
  // Queues one encoded stereo pair (EyeEncoder's bytes: EncodedFrameHeader + payload) for a
  // client that asked for video; no-op otherwise.
  void publish_video(std::uint32_t frame_id, std::int64_t capture_ns, bool is_intra,
                     std::vector<std::uint8_t> encoded_pair);

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace telex::remote
