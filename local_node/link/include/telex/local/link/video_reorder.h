// SPDX-License-Identifier: MIT
// The eyes' jitter buffer (RFC 4585's NACK, by pair; PROTOCOL.md 2.7): encoded pairs go to the
// decoder in encode_seq order. A gap holds the pairs behind it and asks for the missing ones
// (VideoNack) at once, again after a retry interval, until its deadline; then the decoder gets
// what came after the gap, its missing reference asks for an intra pair (PLI), and a pair that
// arrives later is dropped. The deadline follows the round trip but never exceeds `hold_max_ns`,
// so no pair waits longer than that behind a loss.
//
// Asking sooner: a gap is only seen when a pair behind it arrives, one pair interval after the
// lost one was due, and the view shows the pair before it all that time. So the pair after the
// newest is also asked for when it is overdue: when no newer pair has arrived for the usual
// interval (the median of the last 8 between arrivals, per pair: two pairs apart, half the time
// between them) plus half of it, at least
// `overdue_slack_min_ns`; and again every retry interval, as a gap is, since the copy can be
// lost too. A copy keeps the pairs' schedule: the pair after it is due an interval after the
// copy's pair was, not after the copy. A pair merely late costs NACKs the remote answers with
// nothing (it has not sent it yet) or a copy dropped as late here; a lost pair is back a period
// sooner.
//
// Pure (no thread, no clock): time and the round trip come in as arguments. The station's decode
// thread owns one (VideoReceiver).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "telex/proto/messages.h"

namespace telex::local {

struct VideoReorderConfig {
  // A gap is waited for at least this long (three asks, 0, 12 and 24 ms after it is seen, and
  // a loopback round trip) ...
  std::int64_t hold_min_ns = 30'000'000;
  std::int64_t hold_max_ns = 60'000'000;  // ... and never longer (two periods at 30 Hz)
  // A NACK is repeated after 2 RTT + 2 ms, not sooner than this: the remote answers a pair asked
  // for again within 10 ms (its RepairLimiter's dedup interval) with nothing.
  std::int64_t retry_min_ns = 12'000'000;
  int max_nacks = 3;         // per missing pair
  std::size_t max_held = 8;  // pairs held behind a gap; one more gives it up
  bool ask_overdue = true;   // ask for an overdue pair before a later one shows its gap
  std::int64_t overdue_slack_min_ns = 10'000'000;  // overdue: interval + max(interval / 2, this)
};

struct VideoReorderCounters {
  std::uint64_t in_order = 0;  // pairs released without waiting
  std::uint64_t held = 0;      // pairs that waited behind a gap
  // Missing pairs that arrived in time (NACKed or late; one asked for as overdue only as the
  // remote's copy).
  std::uint64_t repaired = 0;
  std::uint64_t given_up = 0;       // missing pairs skipped at their deadline
  std::uint64_t late = 0;           // pairs behind the released sequence, or already held: dropped
  std::uint64_t nacks = 0;          // VideoNack messages made
  std::uint64_t restarts = 0;       // jumps no gap explains (a restarted encoder): started afresh
  std::uint64_t asked_overdue = 0;  // pairs asked for because they were overdue
};

class VideoReorder {
 public:
  explicit VideoReorder(VideoReorderConfig config = {}) : cfg_(config) {}

  // Takes a pair with its encode_seq; `now_ns` is when it arrived, `resent` whether the remote
  // sent it again on a NACK (a pair asked for as overdue is a repair only then).
  void push(std::uint32_t encode_seq, std::vector<std::uint8_t> frame, std::int64_t now_ns,
            bool resent = false);

  // Appends to `ready` the pairs the decoder can have now, in order, and to `nacks` the requests
  // due now (a missing pair is asked for when its gap is seen, then every retry interval, at most
  // max_nacks times); gives up on a gap whose deadline has passed. `rtt_ns` 0 means unknown.
  void poll(std::int64_t now_ns, std::int64_t rtt_ns, std::vector<std::vector<std::uint8_t>>& ready,
            std::vector<proto::VideoNack>& nacks);

  // When poll() next has work without a new pair: the earliest retry, deadline or overdue pair
  // (0: none).
  std::int64_t next_wake_ns(std::int64_t rtt_ns) const;
  // How long after the newest pair's arrival the next one is overdue: the usual interval plus
  // max(half of it, overdue_slack_min_ns); 0 while fewer than 2 intervals are known.
  std::int64_t overdue_ns() const;

  const VideoReorderCounters& counters() const { return counters_; }
  std::size_t held() const { return held_.size(); }

 private:
  struct Missing {
    std::int64_t seen_ns = 0;       // when the gap was first seen
    std::int64_t last_nack_ns = 0;  // 0: not asked yet
    int nacks = 0;
    bool overdue = false;  // asked for as overdue; no later pair has shown the gap yet
  };
  void note_arrival(std::uint32_t seq, std::int64_t now_ns, bool resent);
  std::int64_t usual_interval_ns() const;  // the median of the intervals known; 0: too few
  void ask_overdue(std::int64_t now_ns);
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
  // The newest pair's seq and arrival (for a copy, when it was due), the last intervals between
  // pairs' arrivals per pair (a ring), and whether the pair after the newest was asked for as
  // overdue.
  bool have_newest_ = false;
  std::uint32_t newest_seq_ = 0;
  std::int64_t newest_arrival_ns_ = 0;
  static constexpr std::size_t kIntervals = 8;
  static constexpr std::size_t kMinIntervals = 2;
  std::array<std::int64_t, kIntervals> intervals_ns_{};
  std::size_t interval_count_ = 0;
  bool overdue_asked_ = false;
};

}  // namespace telex::local
