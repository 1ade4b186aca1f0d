// SPDX-License-Identifier: MIT
// The operator station's clock seen from the remote: the offset the remote's own Heartbeat probes
// measure (docs/PROTOCOL.md 2.3, RFC 5905), so a HeadCommand's age can be judged at its arrival on
// the clock its sample was stamped with (2.6).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

namespace telex::remote {

// Pure: answers are added with their four stamps, nothing reads a clock. The offset is the one of
// the answer with the least round trip among the newest kWindow: a probe or an answer that waited
// in a queue on either side (the station's send queue is what issue 49 worries about) biases its
// offset by up to half its extra delay, and the quickest answer is the least biased one. Eight
// answers at the remote's 250 ms probes span 2 s, over which two crystal clocks drift by well
// under a millisecond.
class OperatorClock {
 public:
  static constexpr std::size_t kWindow = 8;
  // One answered probe: t1 when the remote sent it and t4 when the answer came (the remote's
  // clock), t2 when the station received it and t3 when it answered (the station's). Returns
  // false, and keeps nothing, for stamps that are no answer to a probe: t4 before t1, or a round
  // trip below zero (t3 before t2, or the station's span longer than the remote's).
  bool add(std::int64_t t1_ns, std::int64_t t2_ns, std::int64_t t3_ns, std::int64_t t4_ns);
  // The station's clock less the remote's; nullopt before the first answer.
  std::optional<std::int64_t> offset_ns() const;
  // The round trip of the answer offset_ns() comes from (-1 before the first): the offset is
  // right within half of it.
  std::int64_t delay_ns() const;
  // `remote_ns` (the remote's clock) on the station's clock; nullopt before the first answer.
  std::optional<std::int64_t> station_time(std::int64_t remote_ns) const;
  void reset() { *this = OperatorClock{}; }

 private:
  struct Sample {
    std::int64_t offset_ns = 0, delay_ns = 0;
  };
  const Sample* best() const;  // the least-delayed kept answer; nullptr before the first
  std::array<Sample, kWindow> samples_{};
  std::size_t count_ = 0;  // answers added, ever; the newest kWindow are kept
};

}  // namespace telex::remote
