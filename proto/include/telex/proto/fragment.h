// SPDX-License-Identifier: MIT
// UDP fragmentation (no datagram above 1400 bytes) and a bounded, newest-frame-wins reassembler.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <vector>

namespace telex::proto {

// "TF" in wire byte order, read as a little-endian u16.
inline constexpr std::uint16_t kFragmentMagic = 0x4654u;
inline constexpr std::size_t kFragmentHeaderSize = 20;
inline constexpr std::size_t kMaxDatagramBytes = 1400;
inline constexpr std::size_t kFragmentChunkBytes = kMaxDatagramBytes - kFragmentHeaderSize;

struct FragmentHeader {
  std::uint16_t magic = kFragmentMagic;
  std::uint16_t index = 0;       // 0 .. count-1
  std::uint16_t count = 0;       // ceil(total_len / kFragmentChunkBytes), >= 1
  std::uint16_t reserved = 0;    // 0 on send, ignored on receive
  std::uint32_t message_id = 0;  // sender-unique per message (wraps)
  std::uint32_t frame_id = 0;    // newest frame wins in the reassembler
  std::uint32_t total_len = 0;   // bytes of the whole message
};

// Splits a whole message (header + payload) into datagrams of at most kMaxDatagramBytes. Every
// fragment but the last carries exactly kFragmentChunkBytes. Throws std::invalid_argument for an
// empty message or one needing more than 65535 fragments.
std::vector<std::vector<std::uint8_t>> fragment_message(std::span<const std::uint8_t> message,
                                                        std::uint32_t message_id,
                                                        std::uint32_t frame_id);

// Parses a fragment header; nullopt when the datagram is short, has bad magic or an inconsistent
// index/count/length/chunk size.
std::optional<FragmentHeader> parse_fragment_header(std::span<const std::uint8_t> datagram);

struct ReassemblerLimits {
  std::size_t max_message_bytes = 1u << 20;   // larger total_len is malformed
  std::size_t max_buffered_bytes = 4u << 20;  // sum of total_len over in-flight messages
  std::size_t max_in_flight = 256;            // incomplete messages held at once
  std::uint64_t timeout_ns = 200'000'000;     // an incomplete message older than this is dropped
};

struct ReassemblerCounters {
  std::uint64_t fragments = 0;  // accepted datagrams
  std::uint64_t completed = 0;  // messages handed out
  std::uint64_t malformed = 0;  // datagrams with a bad fragment header or disagreeing fragments
  // Fragment already received, or of a message completed lately (a repair sent twice, section 4).
  std::uint64_t duplicates = 0;
  std::uint64_t stale = 0;  // fragment of a frame older than the newest completed one
  std::uint64_t dropped_superseded =
      0;                              // incomplete messages dropped because a newer frame completed
  std::uint64_t dropped_bound = 0;    // incomplete messages evicted to stay within the bounds
  std::uint64_t dropped_timeout = 0;  // incomplete messages that timed out
  // Loss as the receiver sees it: the fragments missing from the incomplete messages dropped
  // above, and the message ids skipped in the sender's sequence (message_id counts up by one per
  // message), each counted once since nothing tells their size. Assumes in-order delivery (a
  // message that arrives after a later one still counts as lost); a jump of 65536 or more ids,
  // or backwards, restarts the sequence (a restarted sender) without counting.
  std::uint64_t fragments_missing = 0;
  std::uint64_t messages_unseen = 0;
  std::uint64_t lost() const { return fragments_missing + messages_unseen; }
  // Messages seen (at least one fragment), by their fragment count: [n - 1] for n = 1..7, [7] for
  // 8 or more. With a known loss rate this tells how many whole messages of each size were lost,
  // which the counts above see as one datagram each.
  std::array<std::uint64_t, 8> messages_by_fragments{};
};

// Collects fragments into messages. Time comes in as an argument (any monotonic ns clock).
// Frame ids compare with serial arithmetic (wrap-safe within 2^31).
class Reassembler {
 public:
  explicit Reassembler(ReassemblerLimits limits = {});

  // Returns the whole message when this datagram completes one. Never throws on wire input.
  std::optional<std::vector<std::uint8_t>> push(std::span<const std::uint8_t> datagram,
                                                std::uint64_t now_ns);
  // Drops incomplete messages older than the timeout (push() also does this).
  void expire(std::uint64_t now_ns);

  const ReassemblerCounters& counters() const { return counters_; }
  std::size_t in_flight() const { return partial_.size(); }
  std::size_t buffered_bytes() const { return buffered_bytes_; }

 private:
  struct Partial {
    std::uint32_t frame_id = 0;
    std::uint16_t count = 0;
    std::uint16_t received = 0;
    std::uint64_t first_ns = 0;
    std::vector<std::uint8_t> bytes;
    std::vector<bool> have;
  };
  void drop(std::map<std::uint32_t, Partial>::iterator it, std::uint64_t& counter);
  bool evict_oldest();

  ReassemblerLimits limits_;
  std::map<std::uint32_t, Partial> partial_;  // by message_id
  std::size_t buffered_bytes_ = 0;
  void note_message_id(std::uint32_t id, std::uint16_t count);
  bool completed_lately(std::uint32_t id) const;
  // The ids of the last messages completed (a ring): a second copy's fragments are duplicates.
  static constexpr std::size_t kCompletedIds = 32;
  std::array<std::uint32_t, kCompletedIds> completed_ids_{};
  std::size_t completed_count_ = 0;
  bool have_newest_ = false;
  bool have_message_id_ = false;
  std::uint32_t next_message_id_ = 0;
  std::uint32_t newest_completed_frame_ = 0;
  ReassemblerCounters counters_;
};

}  // namespace telex::proto
