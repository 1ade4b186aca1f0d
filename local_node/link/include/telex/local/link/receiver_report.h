// SPDX-License-Identifier: MIT
// What the station measures of the remote's datagrams between two receiver reports (PROTOCOL.md
// 2.7): bytes, loss and one-way delay with its trend, the input of a GCC-style rate controller.
// A pure class: the caller feeds it times and counts.
#pragma once

#include <cstdint>
#include <optional>

#include "telex/proto/messages.h"

namespace telex::local {

class ReceiverReportBuilder {
 public:
  // One datagram of `bytes` arrived (all of them, whole message or not).
  void add_datagram(std::size_t bytes) {
    bytes_ += bytes;
    ++datagrams_;
  }
  // The reassembler's loss count grew by `fragments`.
  void add_lost(std::uint64_t fragments) { lost_ += fragments; }
  // A whole message arrived at `arrival_ns` (the remote's clock: local + the heartbeat offset)
  // showing a capture at `capture_ns` (remote clock; 0: none, no delay sample). `video_bytes`: the
  // message's size when it is an encoded pair, else 0.
  void add_message(std::int64_t capture_ns, std::int64_t arrival_ns, std::size_t video_bytes);

  // The report over [last take, now_ns), then starts the next interval; nullopt for the first
  // call (it only starts the interval) or an empty or over-long interval.
  std::optional<proto::ReceiverReport> take(std::int64_t now_ns);

 private:
  std::int64_t started_ns_ = 0;
  std::uint64_t bytes_ = 0, video_bytes_ = 0, datagrams_ = 0, lost_ = 0;
  // Delay samples: count, sums for the mean and the least-squares slope over arrival time
  // (seconds since the interval's start), and the last.
  std::uint64_t n_ = 0;
  double sum_t_ = 0, sum_d_ = 0, sum_tt_ = 0, sum_td_ = 0;
  double last_d_us_ = 0;
};

}  // namespace telex::local
