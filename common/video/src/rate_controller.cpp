// SPDX-License-Identifier: MIT
// The eyes' delay- and loss-based rate controller (draft-ietf-rmcat-gcc-02; the trendline and the
// AIMD details as WebRTC's TrendlineEstimator and AimdRateControl).
#include "telex/video/rate_controller.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace telex::video {
namespace {

constexpr double kNsPerMs = 1e6;
constexpr double kNsPerS = 1e9;
// WebRTC's TrendlineEstimator: the gradient is scaled by the deltas seen, up to this many.
constexpr int kMaxDeltasInGain = 60;
// The threshold is not adapted to a gradient this far above it (a real over-use, not jitter).
constexpr double kThresholdSkipMs = 15.0;
constexpr double kMinThresholdMs = 6.0;
constexpr double kMaxThresholdMs = 600.0;
// One threshold step integrates at most this long a gap between groups.
constexpr double kMaxThresholdStepMs = 100.0;
// The rate never exceeds this times the delivery rate (plus the floor).
constexpr double kMaxOverDelivery = 1.5;
constexpr double kOverDeliveryFloorBps = 10'000.0;
// The capacity estimate: exponential mean of the delivery rate at over-use, and its band.
constexpr double kCapacitySmoothing = 0.05;
constexpr double kCapacityBandSigmas = 3.0;
constexpr double kCapacityMinRelativeSigma = 0.05;
// Additive increase never slower than this.
constexpr double kMinAdditiveIncreaseBps = 4'000.0;

void require(bool ok, const char* field, const char* why) {
  if (!ok) throw std::invalid_argument(std::string("RateControllerConfig.") + field + ": " + why);
}

}  // namespace

std::string_view bandwidth_usage_name(BandwidthUsage usage) {
  switch (usage) {
    case BandwidthUsage::Normal:
      return "normal";
    case BandwidthUsage::Overusing:
      return "overusing";
    case BandwidthUsage::Underusing:
      return "underusing";
  }
  return "unknown";
}

RateController::RateController(const RateControllerConfig& config)
    : config_(config),
      threshold_ms_(config.initial_threshold_ms),
      delay_rate_bps_(static_cast<double>(config.start_bitrate_bps)),
      loss_rate_bps_(static_cast<double>(config.start_bitrate_bps)),
      target_bps_(config.start_bitrate_bps) {
  require(config.min_bitrate_bps > 0, "min_bitrate_bps", "must be > 0");
  require(config.max_bitrate_bps >= config.min_bitrate_bps, "max_bitrate_bps",
          "must be >= min_bitrate_bps");
  require(config.start_bitrate_bps >= config.min_bitrate_bps &&
              config.start_bitrate_bps <= config.max_bitrate_bps,
          "start_bitrate_bps", "must lie within [min_bitrate_bps, max_bitrate_bps]");
  require(config.trendline_window >= 2, "trendline_window", "must be >= 2");
  require(config.delay_smoothing >= 0.0 && config.delay_smoothing < 1.0, "delay_smoothing",
          "must lie in [0, 1)");
  require(config.trendline_gain > 0.0, "trendline_gain", "must be > 0");
  require(config.initial_threshold_ms > 0.0, "initial_threshold_ms", "must be > 0");
  require(config.threshold_k_up >= 0.0 && config.threshold_k_down >= 0.0, "threshold_k_up",
          "threshold gains must be >= 0");
  require(config.overuse_time_ms >= 0.0, "overuse_time_ms", "must be >= 0");
  require(config.decrease_factor > 0.0 && config.decrease_factor < 1.0, "decrease_factor",
          "must lie in (0, 1)");
  require(config.increase_per_s > 0.0, "increase_per_s", "must be > 0");
  require(config.response_time_ns > 0, "response_time_ns", "must be > 0");
  require(config.packet_bytes > 0, "packet_bytes", "must be > 0");
  require(config.delivery_window_ns > 0, "delivery_window_ns", "must be > 0");
  require(config.loss_low >= 0.0 && config.loss_low <= config.loss_high && config.loss_high <= 1.0,
          "loss_high", "need 0 <= loss_low <= loss_high <= 1");
  require(config.loss_increase >= 1.0, "loss_increase", "must be >= 1");
}

std::int64_t RateController::update(const ReceiverReport& report, std::int64_t now_ns) {
  if (report.interval_ns <= 0 || report.packets_lost > report.packets_expected) {
    ++counters_.bad_reports;
    return target_bps_;
  }
  ++counters_.reports;
  measure_delivery(report);
  usage_ = detect_report(report.delay_samples);
  control_delay_rate(usage_, now_ns);
  control_loss_rate(report);
  target_bps_ =
      static_cast<std::int64_t>(std::llround(clamp_bps(std::min(delay_rate_bps_, loss_rate_bps_))));
  return target_bps_;
}

double RateController::clamp_bps(double bps) const {
  return std::clamp(bps, static_cast<double>(config_.min_bitrate_bps),
                    static_cast<double>(config_.max_bitrate_bps));
}

void RateController::measure_delivery(const ReceiverReport& report) {
  delivered_.push_back({report.interval_ns, report.bytes_received});
  std::int64_t span_ns = 0;
  std::uint64_t bytes = 0;
  for (const Delivered& d : delivered_) {
    span_ns += d.interval_ns;
    bytes += d.bytes;
  }
  // Keep the newest reports that fill the window (at least the one just taken).
  while (delivered_.size() > 1 &&
         span_ns - delivered_.front().interval_ns >= config_.delivery_window_ns) {
    span_ns -= delivered_.front().interval_ns;
    bytes -= delivered_.front().bytes;
    delivered_.pop_front();
  }
  delivery_rate_bps_ = static_cast<double>(bytes) * 8.0 * kNsPerS / static_cast<double>(span_ns);
}

// The report's usage: over-use if any of its groups signalled it (the detector resets after each
// signal), else the detector's state after the last group.
BandwidthUsage RateController::detect_report(const std::vector<DelaySample>& samples) {
  bool overused = false;
  for (const DelaySample& sample : samples) {
    add_delay_sample(sample);
    overused = overused || detector_usage_ == BandwidthUsage::Overusing;
  }
  return overused ? BandwidthUsage::Overusing : detector_usage_;
}

void RateController::add_delay_sample(const DelaySample& sample) {
  if (!have_previous_group_) {
    have_previous_group_ = true;
    previous_group_ = sample;
    first_arrival_ns_ = sample.arrival_ns;
    ++counters_.delay_samples;
    return;
  }
  if (sample.send_ns <= previous_group_.send_ns) {
    ++counters_.bad_samples;  // reordered or repeated group: its delta means nothing
    return;
  }
  ++counters_.delay_samples;
  const double send_delta_ms =
      static_cast<double>(sample.send_ns - previous_group_.send_ns) / kNsPerMs;
  const double arrival_delta_ms =
      static_cast<double>(sample.arrival_ns - previous_group_.arrival_ns) / kNsPerMs;
  previous_group_ = sample;
  num_deltas_ = std::min(num_deltas_ + 1, 1'000'000);

  accumulated_delay_ms_ += arrival_delta_ms - send_delta_ms;
  smoothed_delay_ms_ = config_.delay_smoothing * smoothed_delay_ms_ +
                       (1.0 - config_.delay_smoothing) * accumulated_delay_ms_;
  const double arrival_ms = static_cast<double>(sample.arrival_ns - first_arrival_ns_) / kNsPerMs;
  trend_points_.push_back({arrival_ms, smoothed_delay_ms_});
  if (trend_points_.size() > static_cast<std::size_t>(config_.trendline_window)) {
    trend_points_.pop_front();
  }
  if (trend_points_.size() == static_cast<std::size_t>(config_.trendline_window)) {
    // Least-squares slope of smoothed delay over arrival time: the one-way-delay gradient.
    double mean_x = 0.0, mean_y = 0.0;
    for (const TrendPoint& p : trend_points_) {
      mean_x += p.arrival_ms;
      mean_y += p.smoothed_delay_ms;
    }
    mean_x /= static_cast<double>(trend_points_.size());
    mean_y /= static_cast<double>(trend_points_.size());
    double num = 0.0, den = 0.0;
    for (const TrendPoint& p : trend_points_) {
      num += (p.arrival_ms - mean_x) * (p.smoothed_delay_ms - mean_y);
      den += (p.arrival_ms - mean_x) * (p.arrival_ms - mean_x);
    }
    if (den > 0.0) trend_ = num / den;
  }
  detect(trend_, send_delta_ms, arrival_ms);
}

void RateController::detect(double trend, double send_delta_ms, double arrival_ms) {
  if (num_deltas_ < 2) {
    detector_usage_ = BandwidthUsage::Normal;
    return;
  }
  const double modified = std::min(num_deltas_, kMaxDeltasInGain) * trend * config_.trendline_gain;
  modified_trend_ms_ = modified;
  if (modified > threshold_ms_) {
    time_over_using_ms_ =
        time_over_using_ms_ < 0.0 ? send_delta_ms / 2.0 : time_over_using_ms_ + send_delta_ms;
    ++overuse_count_;
    // Over-use is signalled when it lasts and the gradient is not already falling.
    if (time_over_using_ms_ > config_.overuse_time_ms && overuse_count_ > 1 &&
        trend >= previous_trend_) {
      time_over_using_ms_ = 0.0;
      overuse_count_ = 0;
      detector_usage_ = BandwidthUsage::Overusing;
      ++counters_.overuse_signals;
    }
  } else if (modified < -threshold_ms_) {
    time_over_using_ms_ = -1.0;
    overuse_count_ = 0;
    detector_usage_ = BandwidthUsage::Underusing;
  } else {
    time_over_using_ms_ = -1.0;
    overuse_count_ = 0;
    detector_usage_ = BandwidthUsage::Normal;
  }
  previous_trend_ = trend;
  update_threshold(modified, arrival_ms);
}

void RateController::update_threshold(double modified_trend, double arrival_ms) {
  if (last_threshold_update_ms_ < 0.0) last_threshold_update_ms_ = arrival_ms;
  const double magnitude = std::abs(modified_trend);
  if (magnitude > threshold_ms_ + kThresholdSkipMs) {
    last_threshold_update_ms_ = arrival_ms;
    return;
  }
  const double k = magnitude < threshold_ms_ ? config_.threshold_k_down : config_.threshold_k_up;
  const double step_ms =
      std::clamp(arrival_ms - last_threshold_update_ms_, 0.0, kMaxThresholdStepMs);
  threshold_ms_ += k * (magnitude - threshold_ms_) * step_ms;
  threshold_ms_ = std::clamp(threshold_ms_, kMinThresholdMs, kMaxThresholdMs);
  last_threshold_update_ms_ = arrival_ms;
}

// GCC's state machine: over-use -> Decrease (applied once, then Hold); under-use -> Hold while
// the queue drains; normal -> Increase (Hold first after a decrease).
void RateController::control_delay_rate(BandwidthUsage usage, std::int64_t now_ns) {
  switch (usage) {
    case BandwidthUsage::Overusing:
      state_ = RateControlState::Decrease;
      break;
    case BandwidthUsage::Underusing:
      state_ = RateControlState::Hold;
      break;
    case BandwidthUsage::Normal:
      if (state_ == RateControlState::Hold) state_ = RateControlState::Increase;
      break;
  }
  if (state_ == RateControlState::Decrease) {
    decrease_delay_rate(now_ns);
    state_ = RateControlState::Hold;
  } else if (state_ == RateControlState::Increase) {
    increase_delay_rate(now_ns);
  }
  have_last_update_ = true;
  last_update_ns_ = now_ns;
}

void RateController::increase_delay_rate(std::int64_t now_ns) {
  const double dt_s =
      have_last_update_
          ? std::clamp(static_cast<double>(now_ns - last_update_ns_) / kNsPerS, 0.0, 1.0)
          : 0.0;
  const double capacity_sigma =
      std::max(std::sqrt(capacity_var_bps2_), kCapacityMinRelativeSigma * capacity_bps_);
  // Delivery well above the capacity last measured: the link changed; search again.
  if (have_capacity_ && delivery_rate_bps_ > capacity_bps_ + kCapacityBandSigmas * capacity_sigma) {
    have_capacity_ = false;
  }
  double increase_bps = 0.0;
  if (have_capacity_) {
    const double response_s = static_cast<double>(config_.response_time_ns) / kNsPerS;
    const double per_s = std::max(kMinAdditiveIncreaseBps,
                                  static_cast<double>(config_.packet_bytes) * 8.0 / response_s);
    increase_bps = per_s * dt_s;
  } else {
    increase_bps = delay_rate_bps_ * (std::pow(1.0 + config_.increase_per_s, dt_s) - 1.0);
  }
  double next = delay_rate_bps_ + increase_bps;
  if (delivery_rate_bps_ > 0.0) {
    // Never run far ahead of what is delivered (a sender below its target must not inflate it),
    // but never cut below the rate already reached here.
    next = std::min(next, std::max(delay_rate_bps_,
                                   kMaxOverDelivery * delivery_rate_bps_ + kOverDeliveryFloorBps));
  }
  delay_rate_bps_ = clamp_bps(next);
}

void RateController::decrease_delay_rate(std::int64_t now_ns) {
  const bool too_soon =
      have_last_decrease_ && now_ns - last_decrease_ns_ < config_.response_time_ns;
  if (too_soon && delivery_rate_bps_ >= 0.5 * delay_rate_bps_) return;
  const double measured = delivery_rate_bps_ > 0.0 ? delivery_rate_bps_ : delay_rate_bps_;
  update_capacity(measured);
  delay_rate_bps_ = clamp_bps(std::min(delay_rate_bps_, config_.decrease_factor * measured));
  have_last_decrease_ = true;
  last_decrease_ns_ = now_ns;
  ++counters_.delay_decreases;
}

void RateController::update_capacity(double delivery_bps) {
  if (have_capacity_) {
    const double sigma =
        std::max(std::sqrt(capacity_var_bps2_), kCapacityMinRelativeSigma * capacity_bps_);
    // Far below the capacity known: the link got worse; start the estimate afresh.
    if (delivery_bps < capacity_bps_ - kCapacityBandSigmas * sigma) have_capacity_ = false;
  }
  if (!have_capacity_) {
    have_capacity_ = true;
    capacity_bps_ = delivery_bps;
    capacity_var_bps2_ = 0.0;
    return;
  }
  const double error = delivery_bps - capacity_bps_;
  capacity_bps_ += kCapacitySmoothing * error;
  capacity_var_bps2_ =
      (1.0 - kCapacitySmoothing) * capacity_var_bps2_ + kCapacitySmoothing * error * error;
}

void RateController::control_loss_rate(const ReceiverReport& report) {
  if (report.packets_expected == 0) return;
  const double loss =
      static_cast<double>(report.packets_lost) / static_cast<double>(report.packets_expected);
  const double current = static_cast<double>(target_bps_);
  if (loss > config_.loss_high) {
    loss_rate_bps_ = clamp_bps(current * (1.0 - 0.5 * loss));
    ++counters_.loss_decreases;
  } else if (loss < config_.loss_low) {
    loss_rate_bps_ = clamp_bps(std::max(loss_rate_bps_, current) * config_.loss_increase);
  } else {
    loss_rate_bps_ = clamp_bps(current);
  }
}

}  // namespace telex::video
