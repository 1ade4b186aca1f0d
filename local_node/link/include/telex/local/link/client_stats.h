// SPDX-License-Identifier: MIT
// The link's state and counters (ClientStats), readable from any thread: what the surface client
// counts and the station's status, summary and haptic loop read.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string_view>

namespace telex::local {

enum class ClientState : std::uint8_t { Connecting, Handshaking, Streaming, Backoff, Stopped };
std::string_view to_string(ClientState s);

// Counters readable from any thread.
struct ClientStats {
  std::atomic<std::uint64_t> connects{0};
  std::atomic<std::uint64_t> disconnects{0};
  std::atomic<std::uint64_t> rejects{0};
  std::atomic<std::uint64_t> messages{0};
  std::atomic<std::uint64_t> bytes_in{0};
  std::atomic<std::uint64_t> datagrams{0};
  // Datagrams of the depth stream the reassembler knows were lost on the way
  // (proto::ReassemblerCounters::lost(): missing fragments plus skipped message ids).
  std::atomic<std::uint64_t> udp_lost{0};
  // Depth-stream messages seen, by fragment count (ReassemblerCounters::messages_by_fragments).
  std::array<std::atomic<std::uint64_t>, 8> udp_messages_by_fragments{};
  std::atomic<std::uint64_t> dropped_malformed{0};  // parser + reassembler rejections
  // Messages to the remote dropped unsent: a head command replaced by a newer one while it waited,
  // or the oldest waiting message when 64 were already queued behind a stalled write.
  std::atomic<std::uint64_t> upstream_dropped{0};
  std::atomic<std::uint64_t> dropped_foreign{0};  // wrong session or source
  // Authentication: auth_failed counts TLS handshakes that the TLS layer failed (another key, a
  // peer without TLS, a certificate the CA does not vouch for; not a bare close or reset) and
  // datagrams that do not open under the remote->station key; unsealed: plain datagrams on a
  // sealed link; replayed: authentic datagrams seen before.
  std::atomic<std::uint64_t> auth_failed{0};
  std::atomic<std::uint64_t> unsealed{0};
  std::atomic<std::uint64_t> replayed{0};
  std::atomic<std::uint64_t> heartbeats{0};
  // Whole messages by stream (header + payload, without fragment headers and seals): the eyes'
  // EncodedVideo, and depth (tiles, manifests, stream configs).
  std::atomic<std::uint64_t> video_bytes{0}, depth_bytes{0};
  std::atomic<std::uint64_t> receiver_reports{0};  // ReceiverReports sent (PROTOCOL.md 2.7)
  std::atomic<std::int64_t> clock_offset_ns{0};    // remote clock minus local clock (NTP estimate)
  std::atomic<std::int64_t> rtt_ns{0};
  // Monotonic time of the session's last authenticated message from the remote; 0 while there
  // is no session (before Accept, after a disconnect or the remote's end).
  std::atomic<std::int64_t> alive_ns{0};
  std::atomic<std::uint8_t> state{static_cast<std::uint8_t>(ClientState::Stopped)};
};

}  // namespace telex::local
