// SPDX-License-Identifier: MIT
// The eyes' target bit rate from the station's receiver reports: a delay- and loss-based
// controller in the spirit of WebRTC's Google Congestion Control (draft-ietf-rmcat-gcc-02).
//
// The model, as GCC's:
// - Delay. A link whose queue grows delays every frame a little more than the one before. For each
//   frame (a "group": all its fragments) the receiver reports when the sender sent it and when its
//   last fragment arrived; the inter-group delay variation d = (arrival delta) - (send delta) is
//   accumulated, smoothed, and a least-squares line is fitted through the last `trendline_window`
//   points of (arrival time, smoothed delay): its slope is the one-way-delay gradient. The gradient
//   (times min(deltas, 60) times `trendline_gain`, as WebRTC's TrendlineEstimator) is compared
//   with an adaptive threshold: above it for longer than `overuse_time_ms` means over-use (the
//   queue is building), below its negative means under-use (the queue is draining), else normal.
//   The threshold follows the gradient slowly (GCC's gamma with K_u, K_d) so that a link's normal
//   jitter does not keep signalling over-use. Clocks need not be synchronized: only differences
//   of the sender's times and of the receiver's times are used.
// - Rate (AIMD). Over-use cuts the rate to `decrease_factor` (GCC's beta, 0.85) times the measured
//   delivery rate, i.e. just below what the link actually carried, at most once per
//   `response_time_ns` (unless delivery fell below half the target). Under-use holds the rate while
//   the queue drains; normal increases it: multiplicatively (8 %/s) while the link's capacity is
//   unknown, additively (about one packet per response time) near the delivery rate last measured
//   at an over-use, where the link's capacity was. The rate never exceeds 1.5 times the delivery
//   rate (plus a floor), so a sender that cannot fill its target does not inflate it.
// - Loss. A second estimate from the loss fraction p of each report: p > `loss_high` (10 %)
//   multiplies the rate by (1 - p / 2), p < `loss_low` (2 %) lets it grow by 5 % per report, in
//   between holds it. The target is the smaller of the delay and loss estimates, clamped to
//   [min_bitrate_bps, max_bitrate_bps].
//
// A pure class: no clock (the caller passes `now_ns`), no I/O, no thread, deterministic. Bad
// reports (a non-positive interval, more lost than expected) are counted and ignored; it never
// throws. The remote calls update() for each receiver report and hands the result to
// EyeEncoder::set_bitrate().
#pragma once

#include <cstdint>
#include <deque>
#include <string_view>
#include <vector>

namespace telex::video {

// One group (a frame's fragments): when the sender sent it (its clock) and when its last fragment
// arrived (the receiver's clock).
struct DelaySample {
  std::int64_t send_ns = 0;
  std::int64_t arrival_ns = 0;
};

// What the receiver measured over one report interval.
struct ReceiverReport {
  std::int64_t interval_ns = 0;        // receiver time the report covers (> 0)
  std::uint64_t bytes_received = 0;    // video bytes (fragments' payload or datagrams) received
  std::uint64_t packets_expected = 0;  // fragments the sender sent in it (sequence span)
  std::uint64_t packets_lost = 0;      // of them not received (<= packets_expected)
  // One per group whose last fragment arrived in the interval, in arrival order. May be empty
  // (then the delay detector keeps its state).
  std::vector<DelaySample> delay_samples;
};

enum class BandwidthUsage : std::uint8_t { Normal = 0, Overusing, Underusing };
std::string_view bandwidth_usage_name(BandwidthUsage usage);

// GCC's rate-control states.
enum class RateControlState : std::uint8_t { Hold = 0, Increase, Decrease };

struct RateControllerConfig {
  std::int64_t min_bitrate_bps = 300'000;
  std::int64_t max_bitrate_bps = 8'000'000;
  std::int64_t start_bitrate_bps = 4'000'000;
  // Trendline (WebRTC's defaults).
  int trendline_window = 20;     // groups in the least-squares fit
  double delay_smoothing = 0.9;  // exponential smoothing of the accumulated delay
  double trendline_gain = 4.0;   // scales the slope before the threshold
  double initial_threshold_ms = 12.5;
  double threshold_k_up = 0.0087;   // GCC's K_u (per ms): threshold rises slowly
  double threshold_k_down = 0.039;  // GCC's K_d (per ms): and falls faster
  double overuse_time_ms = 10.0;    // over the threshold this long before over-use is signalled
  // Rate control.
  double decrease_factor = 0.85;                  // GCC's beta
  double increase_per_s = 0.08;                   // multiplicative increase, 8 %/s
  std::int64_t response_time_ns = 200'000'000;    // RTT + 100 ms: one decrease per this
  std::int64_t packet_bytes = 1'200;              // additive increase: one packet per response time
  std::int64_t delivery_window_ns = 500'000'000;  // delivery rate measured over this
  // Loss.
  double loss_high = 0.10;
  double loss_low = 0.02;
  double loss_increase = 1.05;  // per report below loss_low
};

struct RateControllerCounters {
  std::uint64_t reports = 0;          // reports taken
  std::uint64_t bad_reports = 0;      // ignored (non-positive interval, lost > expected)
  std::uint64_t delay_samples = 0;    // groups fed to the trendline
  std::uint64_t bad_samples = 0;      // ignored (send time not after the previous group's)
  std::uint64_t overuse_signals = 0;  // over-use detected
  std::uint64_t delay_decreases = 0;  // decreases applied for over-use
  std::uint64_t loss_decreases = 0;   // reports with loss above loss_high
};

class RateController {
 public:
  // Throws std::invalid_argument naming the field when the configuration is inconsistent
  // (bounds out of order, a start outside them, a window under 2, factors out of range).
  explicit RateController(const RateControllerConfig& config = {});

  // Takes one receiver report at `now_ns` (the sender's clock, any epoch, non-decreasing) and
  // returns the new target in bits/s, always within [min_bitrate_bps, max_bitrate_bps].
  std::int64_t update(const ReceiverReport& report, std::int64_t now_ns);

  std::int64_t target_bps() const { return target_bps_; }
  // Bits/s delivered over the last delivery_window_ns of reports (0 before the first).
  double delivery_rate_bps() const { return delivery_rate_bps_; }
  BandwidthUsage usage() const { return usage_; }
  RateControlState state() const { return state_; }
  // The gradient compared with the threshold (ms, after the gain), and the threshold itself.
  double modified_trend_ms() const { return modified_trend_ms_; }
  double threshold_ms() const { return threshold_ms_; }
  const RateControllerCounters& counters() const { return counters_; }
  const RateControllerConfig& config() const { return config_; }

 private:
  void measure_delivery(const ReceiverReport& report);
  BandwidthUsage detect_report(const std::vector<DelaySample>& samples);
  void add_delay_sample(const DelaySample& sample);
  void detect(double trend, double send_delta_ms, double arrival_ms);
  void update_threshold(double modified_trend, double arrival_ms);
  void control_delay_rate(BandwidthUsage usage, std::int64_t now_ns);
  void increase_delay_rate(std::int64_t now_ns);
  void decrease_delay_rate(std::int64_t now_ns);
  void control_loss_rate(const ReceiverReport& report);
  void update_capacity(double delivery_bps);
  double clamp_bps(double bps) const;

  RateControllerConfig config_;
  RateControllerCounters counters_;

  // Delivery rate: the last reports within delivery_window_ns.
  struct Delivered {
    std::int64_t interval_ns;
    std::uint64_t bytes;
  };
  std::deque<Delivered> delivered_;
  double delivery_rate_bps_ = 0.0;

  // Trendline.
  struct TrendPoint {
    double arrival_ms;
    double smoothed_delay_ms;
  };
  bool have_previous_group_ = false;
  DelaySample previous_group_;
  std::int64_t first_arrival_ns_ = 0;
  int num_deltas_ = 0;
  double accumulated_delay_ms_ = 0.0;
  double smoothed_delay_ms_ = 0.0;
  std::deque<TrendPoint> trend_points_;
  double trend_ = 0.0;

  // Over-use detector.
  BandwidthUsage detector_usage_ = BandwidthUsage::Normal;
  double modified_trend_ms_ = 0.0;
  double previous_trend_ = 0.0;
  double threshold_ms_;
  double last_threshold_update_ms_ = -1.0;
  double time_over_using_ms_ = -1.0;
  int overuse_count_ = 0;

  // AIMD on the delay estimate (GCC's A_r).
  BandwidthUsage usage_ = BandwidthUsage::Normal;
  RateControlState state_ = RateControlState::Hold;
  double delay_rate_bps_;
  bool have_last_update_ = false;
  std::int64_t last_update_ns_ = 0;
  bool have_last_decrease_ = false;
  std::int64_t last_decrease_ns_ = 0;
  // The link's capacity: the delivery rate at over-use, its mean and variance (bits/s).
  bool have_capacity_ = false;
  double capacity_bps_ = 0.0;
  double capacity_var_bps2_ = 0.0;

  // Loss estimate (GCC's A_s) and the output.
  double loss_rate_bps_;
  std::int64_t target_bps_;
};

}  // namespace telex::video
