// SPDX-License-Identifier: MIT
// When the station asks the remote again for a lost tile (docs/PROTOCOL.md 2.5): only once the
// answer had time to come, the stream's transit and a round trip; key frames at most so often.
#pragma once

#include <cstdint>

namespace telex::local {

// Pure: the network thread feeds it each closed frame and the link's round trip; no clock here.
class RepairPolicy {
 public:
  // retry_min_s: the shortest wait before a tile is asked again; key_interval_s: the shortest
  // time between two key-frame requests.
  RepairPolicy(double retry_min_s, double key_interval_s);

  // A frame closed at now_ns (receiver clock) that was captured at capture_ns (sender clock,
  // offset_ns = sender - receiver): the stream's transit, smoothed over about eight frames.
  void on_frame(std::int64_t now_ns, std::int64_t capture_ns, std::int64_t clock_offset_ns);
  std::int64_t transit_ns() const { return transit_ns_; }

  // How long a tile asked for waits before it is asked again: max(retry_min, transit + 2 RTT).
  std::int64_t retry_ns(std::int64_t rtt_ns) const;
  std::int64_t key_interval_ns() const { return key_interval_ns_; }

 private:
  std::int64_t retry_min_ns_;
  std::int64_t key_interval_ns_;
  std::int64_t transit_ns_ = 0;  // 0 until the first frame
};

}  // namespace telex::local
