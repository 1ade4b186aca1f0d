// SPDX-License-Identifier: MIT
// The eyes' jitter buffer (RFC 4585's NACK, by pair; PROTOCOL.md 2.7): encoded pairs go to the
// decoder in encode_seq order. A gap holds the pairs behind it and asks for the missing ones
// (VideoNack) at once, again after a retry interval, until its deadline; then the decoder gets
// what came after the gap, its missing reference asks for an intra pair (PLI), and a pair that
// arrives later is dropped. The deadline follows the round trip but never exceeds `hold_max_ns`,
// so no pair waits longer than that behind a loss.
//
// Pure (no thread, no clock): time and the round trip come in as arguments. The station's decode
// thread owns one (VideoReceiver).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "telex/proto/messages.h"

namespace telex::local {

struct VideoReorderConfig {
  std::int64_t hold_min_ns = 20'000'000;  // a gap is waited for at least this long ...
  std::int64_t hold_max_ns = 60'000'000;  // ... and never longer (two periods at 30 Hz)
  std::int64_t retry_min_ns = 8'000'000;  // a NACK is repeated after 2 RTT + 2 ms, not sooner
  int max_nacks = 3;                      // per missing pair
  std::size_t max_held = 8;               // pairs held behind a gap; one more gives it up
};

struct VideoReorderCounters {
  std::uint64_t in_order = 0;  // pairs released without waiting
  std::uint64_t held = 0;      // pairs that waited behind a gap
  std::uint64_t repaired = 0;  // missing pairs that arrived in time (NACKed or late)
  std::uint64_t given_up = 0;  // missing pairs skipped at their deadline
  std::uint64_t late = 0;      // pairs behind the released sequence, or already held: dropped
  std::uint64_t nacks = 0;     // VideoNack messages made
  std::uint64_t restarts = 0;  // jumps no gap explains (a restarted encoder): started afresh
};

class VideoReorder {
 public:
  explicit VideoReorder(VideoReorderConfig config = {}) : cfg_(config) {}

  // Takes a pair with its encode_seq.
  void push(std::uint32_t encode_seq, std::vector<std::uint8_t> frame, std::int64_t now_ns);

  // Appends to `ready` the pairs the decoder can have now, in order, and to `nacks` the requests
  // due now (a missing pair is asked for when its gap is seen, then every retry interval, at most
  // max_nacks times); gives up on a gap whose deadline has passed. `rtt_ns` 0 means unknown.
  void poll(std::int64_t now_ns, std::int64_t rtt_ns, std::vector<std::vector<std::uint8_t>>& ready,
            std::vector<proto::VideoNack>& nacks);

  // When poll() next has work without a new pair: the earliest retry or deadline (0: none).
  std::int64_t next_wake_ns(std::int64_t rtt_ns) const;

  const VideoReorderCounters& counters() const { return counters_; }
  std::size_t held() const { return held_.size(); }

 private:
  struct Missing {
    std::int64_t seen_ns = 0;       // when the gap was first seen
    std::int64_t last_nack_ns = 0;  // 0: not asked yet
    int nacks = 0;
  };
  std::int64_t hold_ns(std::int64_t rtt_ns) const;
  std::int64_t retry_ns(std::int64_t rtt_ns) const;
  void release_in_order(std::vector<std::vector<std::uint8_t>>& ready);
  void give_up_head(std::vector<std::vector<std::uint8_t>>& ready);

  VideoReorderConfig cfg_;
  VideoReorderCounters counters_;
  bool started_ = false;
  std::uint32_t next_seq_ = 0;                               // the pair the decoder needs next
  std::map<std::uint32_t, std::vector<std::uint8_t>> held_;  // by encode_seq - next_seq_ order
  std::map<std::uint32_t, Missing> missing_;                 // seqs in [next_seq_, newest held)
};

}  // namespace telex::local
