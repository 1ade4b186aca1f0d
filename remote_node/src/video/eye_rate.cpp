// SPDX-License-Identifier: MIT
#include "telex/remote/eye_rate.h"

#include <algorithm>
#include <cmath>

namespace telex::remote {
namespace {

video::RateControllerConfig link_config(std::int64_t max_video_bps, std::int64_t min_video_bps) {
  video::RateControllerConfig c;
  // The whole link: depth and eyes. The controller never goes past 1.5 x what was delivered, so
  // a high ceiling does not run away on an idle link.
  c.min_bitrate_bps = min_video_bps;
  c.max_bitrate_bps = std::max<std::int64_t>(200'000'000, 4 * max_video_bps);
  // Start at the ceiling: the first report caps the target at 1.5 x what was delivered, so the
  // eyes start with what the depth leaves instead of climbing from a guess (depth alone can be
  // 16 Mbit/s: a low start left the eyes at their floor for seconds).
  c.start_bitrate_bps = c.max_bitrate_bps;
  return c;
}

}  // namespace

EyeRate::EyeRate(std::int64_t max_video_bps, std::int64_t min_video_bps)
    : max_video_bps_(max_video_bps),
      min_video_bps_(std::min(min_video_bps, max_video_bps)),
      controller_(link_config(max_video_bps, min_video_bps_)),
      video_bps_(max_video_bps),
      ceiling_bps_(static_cast<double>(max_video_bps)) {}

video::ReceiverReport EyeRate::to_controller(const proto::ReceiverReport& r,
                                             std::int64_t received_ns) {
  video::ReceiverReport out;
  out.interval_ns = static_cast<std::int64_t>(r.interval_us) * 1000;
  out.bytes_received = r.bytes_received;
  out.packets_expected = static_cast<std::uint64_t>(r.datagrams_received) + r.fragments_lost;
  out.packets_lost = r.fragments_lost;
  if (r.delay_samples >= 2 && out.interval_ns > 0) {
    // The station's least-squares line of delay over arrival time, sampled at the interval's
    // ends around its mean.
    const double half_s = static_cast<double>(out.interval_ns) * 0.5e-9;
    const double g = static_cast<double>(r.delay_gradient_us_per_s);
    const double d0_ns = (r.delay_mean_us - g * half_s) * 1e3;
    const double d1_ns = (r.delay_mean_us + g * half_s) * 1e3;
    const std::int64_t a0 = received_ns - out.interval_ns, a1 = received_ns;
    out.delay_samples.push_back({a0 - std::llround(d0_ns), a0});
    out.delay_samples.push_back({a1 - std::llround(d1_ns), a1});
  }
  return out;
}

std::int64_t EyeRate::on_report(const proto::ReceiverReport& report, std::int64_t received_ns) {
  if (report.interval_us == 0) return video_bps_;
  const std::int64_t link_bps = controller_.update(to_controller(report, received_ns), received_ns);
  const double interval_s = static_cast<double>(report.interval_us) * 1e-6;
  const double expected =
      static_cast<double>(report.datagrams_received) + static_cast<double>(report.fragments_lost);
  const double loss = expected > 0.0 ? report.fragments_lost / expected : 0.0;
  const std::uint64_t video_bytes = std::min(report.video_bytes, report.bytes_received);
  // What the depth sent, not only what arrived: its loss is the eyes' to make good.
  const double depth_now = static_cast<double>(report.bytes_received - video_bytes) * 8.0 /
                           interval_s / std::max(0.5, 1.0 - loss);
  // Smoothed over about a second of reports: depth comes in frames and key frames.
  depth_bps_ = depth_bps_ == 0.0 ? depth_now : 0.7 * depth_bps_ + 0.3 * depth_now;
  // The eyes' own ceiling, additive increase and multiplicative decrease: a link whose queue
  // overflows shows loss before any delay trend (its delay sits at the queue's end), and a loss
  // the controller holds at (2-10 %) is loss the depth suffers too. The eyes back off first.
  const double video_delivered = static_cast<double>(video_bytes) * 8.0 / interval_s;
  if (loss > controller_.config().loss_low)
    ceiling_bps_ = std::min(
        ceiling_bps_, kBackOff * std::max(video_delivered, static_cast<double>(min_video_bps_)));
  else
    ceiling_bps_ =
        std::min(static_cast<double>(max_video_bps_),
                 ceiling_bps_ + kIncreasePerS * static_cast<double>(max_video_bps_) * interval_s);
  const double left = std::min(static_cast<double>(link_bps) - depth_bps_, ceiling_bps_);
  video_bps_ = std::clamp<std::int64_t>(std::llround(left), min_video_bps_, max_video_bps_);
  return video_bps_;
}

}  // namespace telex::remote
