// SPDX-License-Identifier: MIT
// The eyes' bit rate from the station's receiver reports: the link's budget from a GCC-style
// controller (telex::video::RateController) over everything the station received, less what the
// depth took, capped by --video-bitrate and by the eyes' own AIMD ceiling, which backs off on any
// loss above the controller's low threshold (2 %). Depth keeps priority: the eyes get what is left.
#pragma once

#include <cstdint>

#include "telex/proto/messages.h"
#include "telex/video/rate_controller.h"

namespace telex::remote {

class EyeRate {
 public:
  // `max_video_bps`: --video-bitrate, the most the eyes ever get; `min_video_bps`: the least.
  explicit EyeRate(std::int64_t max_video_bps, std::int64_t min_video_bps = 300'000);

  // One report (the remote's clock when it arrived, non-decreasing): the eyes' new bit rate.
  std::int64_t on_report(const proto::ReceiverReport& report, std::int64_t received_ns);

  std::int64_t video_bps() const { return video_bps_; }
  double depth_bps() const { return depth_bps_; }
  const video::RateController& controller() const { return controller_; }

  // The report as the controller takes it: counts, and the delay trend the station fitted as two
  // samples of that line at the interval's ends (only differences of delay matter to it).
  static video::ReceiverReport to_controller(const proto::ReceiverReport& report,
                                             std::int64_t received_ns);

 private:
  std::int64_t max_video_bps_, min_video_bps_;
  video::RateController controller_;
  std::int64_t video_bps_;
  double ceiling_bps_;  // the eyes' own AIMD bound
  double depth_bps_ = 0.0;
  static constexpr double kBackOff = 0.85;       // of what the eyes delivered, on loss
  static constexpr double kIncreasePerS = 0.05;  // of --video-bitrate, per second without loss
};

}  // namespace telex::remote
