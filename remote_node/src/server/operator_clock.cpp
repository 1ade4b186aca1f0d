// SPDX-License-Identifier: MIT
// OperatorClock: the station's clock offset from the remote's probes, the least-delayed answer of
// the newest few.
#include "telex/remote/operator_clock.h"

#include <algorithm>
#include <cstddef>

namespace telex::remote {

bool OperatorClock::add(std::int64_t t1_ns, std::int64_t t2_ns, std::int64_t t3_ns,
                        std::int64_t t4_ns) {
  const std::int64_t delay = (t4_ns - t1_ns) - (t3_ns - t2_ns);
  if (t4_ns < t1_ns || t3_ns < t2_ns || delay < 0) return false;
  samples_[count_ % kWindow] = {((t2_ns - t1_ns) + (t3_ns - t4_ns)) / 2, delay};
  ++count_;
  return true;
}

const OperatorClock::Sample* OperatorClock::best() const {
  if (count_ == 0) return nullptr;
  const std::size_t n = std::min(count_, kWindow);
  return &*std::min_element(
      samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(n),
      [](const Sample& a, const Sample& b) { return a.delay_ns < b.delay_ns; });
}

std::optional<std::int64_t> OperatorClock::offset_ns() const {
  const Sample* b = best();
  return b ? std::optional<std::int64_t>(b->offset_ns) : std::nullopt;
}

std::int64_t OperatorClock::delay_ns() const {
  const Sample* b = best();
  return b ? b->delay_ns : -1;
}

std::optional<std::int64_t> OperatorClock::station_time(std::int64_t remote_ns) const {
  const auto offset = offset_ns();
  if (!offset) return std::nullopt;
  return remote_ns + *offset;
}

}  // namespace telex::remote
