// SPDX-License-Identifier: MIT
// Head teleoperation's sender: the operator's head to the remote as joint targets, at most
// head_rate_hz, with the tracking sample's id and true age and the dead-man's state.
#pragma once

#include <cstdint>
#include <memory>

#include "messages.h"
#include "telex/base/triple_buffer.h"
#include "telex/local/inputs/deadman.h"
#include "telex/local/link/surface_client.h"
#include "telex/local/station/station_config.h"
#include "telex/local/station/station_summary.h"

namespace telex::local {

class HeadSender {
 public:
  // Opens --deadman now, so a missing device stops the start.
  explicit HeadSender(const StationConfig& cfg);

  // Main thread: sends the newest head sample when one is due.
  void send(std::int64_t now_ns, TripleBuffer<HeadSample>& head_in, SurfaceClient& client);
  void summarize(StationSummary& s) const;

 private:
  const StationConfig& cfg_;
  std::unique_ptr<DeadmanInput> deadman_;
  std::int64_t next_ns_ = 0;
  HeadSample sample_;
  std::uint64_t commands_ = 0, samples_stale_ = 0, deadman_released_ = 0, commands_invalid_ = 0;
};

}  // namespace telex::local
