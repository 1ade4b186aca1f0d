// SPDX-License-Identifier: MIT
// The repair retry policy: transit + 2 RTT, never under the configured minimum.
#include "telex/local/link/repair_policy.h"

#include <algorithm>

namespace telex::local {

RepairPolicy::RepairPolicy(double retry_min_s, double key_interval_s)
    : retry_min_ns_(static_cast<std::int64_t>(retry_min_s * 1e9)),
      key_interval_ns_(static_cast<std::int64_t>(key_interval_s * 1e9)) {}

void RepairPolicy::on_frame(std::int64_t now_ns, std::int64_t capture_ns,
                            std::int64_t clock_offset_ns) {
  const std::int64_t transit = now_ns - (capture_ns - clock_offset_ns);
  transit_ns_ = transit_ns_ == 0 ? transit : (7 * transit_ns_ + transit) / 8;
}

std::int64_t RepairPolicy::retry_ns(std::int64_t rtt_ns) const {
  return std::max(retry_min_ns_, std::max<std::int64_t>(transit_ns_, 0) + 2 * rtt_ns);
}

}  // namespace telex::local
