// SPDX-License-Identifier: MIT
// ReceiverReportBuilder: interval counts and the delay's mean, last value and slope.
#include "telex/local/link/receiver_report.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace telex::local {
namespace {

std::int32_t clamp_us(double us) {
  const double bound = static_cast<double>(proto::kMaxReportDelayUs);
  return static_cast<std::int32_t>(std::lround(std::clamp(us, -bound, bound)));
}

std::uint32_t saturate_u32(std::uint64_t v) {
  return static_cast<std::uint32_t>(
      std::min<std::uint64_t>(v, std::numeric_limits<std::uint32_t>::max()));
}

}  // namespace

void ReceiverReportBuilder::add_message(std::int64_t capture_ns, std::int64_t arrival_ns,
                                        std::size_t video_bytes) {
  video_bytes_ += video_bytes;
  if (capture_ns == 0 || started_ns_ == 0) return;
  const double t_s = static_cast<double>(arrival_ns - started_ns_) * 1e-9;
  const double d_us = static_cast<double>(arrival_ns - capture_ns) * 1e-3;
  ++n_;
  sum_t_ += t_s;
  sum_d_ += d_us;
  sum_tt_ += t_s * t_s;
  sum_td_ += t_s * d_us;
  last_d_us_ = d_us;
}

std::optional<proto::ReceiverReport> ReceiverReportBuilder::take(std::int64_t now_ns) {
  const std::int64_t started = started_ns_;
  proto::ReceiverReport r;
  r.interval_us = static_cast<std::uint32_t>(
      std::clamp<std::int64_t>((now_ns - started) / 1000, 0, proto::kMaxReportIntervalUs));
  r.bytes_received = bytes_;
  r.video_bytes = std::min(video_bytes_, bytes_);
  r.datagrams_received = saturate_u32(datagrams_);
  r.fragments_lost = saturate_u32(lost_);
  r.delay_samples = saturate_u32(n_);
  if (n_ > 0) {
    const double n = static_cast<double>(n_);
    r.delay_mean_us = clamp_us(sum_d_ / n);
    r.delay_last_us = clamp_us(last_d_us_);
    const double var_t = sum_tt_ - sum_t_ * sum_t_ / n;
    const double slope = var_t > 1e-12 ? (sum_td_ - sum_t_ * sum_d_ / n) / var_t : 0.0;
    r.delay_gradient_us_per_s = std::isfinite(slope) ? static_cast<float>(slope) : 0.0f;
    if (r.delay_gradient_us_per_s == 0.0f) r.delay_gradient_us_per_s = 0.0f;  // never -0
  }
  *this = ReceiverReportBuilder{};
  started_ns_ = now_ns;
  if (started == 0 || now_ns - started <= 1000 ||
      now_ns - started > static_cast<std::int64_t>(proto::kMaxReportIntervalUs) * 1000)
    return std::nullopt;
  return r;
}

}  // namespace telex::local
