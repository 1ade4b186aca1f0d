// SPDX-License-Identifier: MIT
// The run's statistics from the haptic thread's tick samples.
#include "run_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace telex::local {

RunStats::RunStats(const StationConfig& cfg, std::int64_t t_start_ns)
    : cfg_(cfg),
      t_start_ns_(t_start_ns),
      period_ns_(static_cast<std::int64_t>(std::llround(1e9 / cfg.rate_hz))),
      print_period_ns_(
          cfg.print_forces_hz > 0 ? static_cast<std::int64_t>(1e9 / cfg.print_forces_hz) : 0) {}

std::uint64_t RunStats::add(const TickSample& s, std::int64_t clock_offset_ns) {
  if (++tick_index_ == 1) first_deadline_ns_ = s.deadline_ns;
  last_ = s;
  if (tick_index_ > 1) {
    period_us_.add(static_cast<double>(s.period_ns) / 1e3);
    jitter_us_.add(std::abs(static_cast<double>(s.period_ns - period_ns_)) / 1e3);
    window_periods_.push_back(s.period_ns);
  }
  wake_us_.add(static_cast<double>(s.t_ns - s.deadline_ns) / 1e3);
  add_latency(s, clock_offset_ns);
  for (const auto& f : s.forces) {
    peak_pressure_N_ = std::max(peak_pressure_N_, f.normal_force_N);
    peak_shear_N_ = std::max(peak_shear_N_, std::abs(f.shear_along_axis_N));
  }
  if (print_period_ns_ && s.t_ns >= next_print_ns_) {
    next_print_ns_ = s.t_ns + print_period_ns_;
    print_forces(s);
  }
  return tick_index_;
}

// Capture-to-force latency: measured at the first tick that renders a newly arrived surface of a
// new capture (a frame's rest rebuilding its surface is not a new capture).
void RunStats::add_latency(const TickSample& s, std::int64_t clock_offset_ns) {
  if (s.surface_capture_ns == 0 || s.surface_frame == last_latency_frame_ ||
      s.surface_capture_ns == last_latency_capture_)
    return;
  last_latency_frame_ = s.surface_frame;
  last_latency_capture_ = s.surface_capture_ns;
  const double lat = static_cast<double>(s.t_ns - (s.surface_capture_ns - clock_offset_ns)) / 1e6;
  latency_ms_.add(lat);
  window_latency_.push_back(lat);
  // The same, for surfaces first rendered while a finger touches them: the samples whose force
  // depends on the surface's age (a surface no fingertip is near renders 0 N at any age; with
  // --roi the remote then processes whole frames, not ROI parts).
  if (std::any_of(s.forces.begin(), s.forces.end(), [](const auto& f) { return f.contact; }))
    contact_latency_ms_.add(lat);
}

// --print-forces: the live force lines, output for the operator on stdout.
void RunStats::print_forces(const TickSample& s) {
  std::string line =
      "t=" + std::to_string(static_cast<double>(s.t_ns - t_start_ns_) / 1e9).substr(0, 6) + "s";
  for (std::size_t i = 0; i < kFingerCount; ++i) {
    const auto& f = s.forces[i];
    if (!s.tracked[i]) continue;
    char b[96];
    std::snprintf(b, sizeof b, "  %s P=%5.2fN S=%+5.2fN%s", kFingerNames[i], f.normal_force_N,
                  f.shear_along_axis_N, f.contact ? " contact" : "");
    line += b;
  }
  std::printf("%s\n", line.c_str());
  std::fflush(stdout);
}

std::string RunStats::status_text(double fps, double build_ms, ClientState state,
                                  const HandTracker* tracker) const {
  const auto ps = summarize_periods(window_periods_, period_ns_);
  char b[256];
  std::snprintf(b, sizeof b,
                "surface %.1f fps | latency %.1f ms | haptic %.1f Hz jitter p99 %.0f us | "
                "build %.1f ms | %s",
                fps, percentile(window_latency_, 0.5), ps.mean_rate_hz, ps.p99_jitter_us, build_ms,
                std::string(to_string(state)).c_str());
  std::string text(b);
  if (tracker) {
    // What the tracker's checks dropped, when they dropped anything (docs/HARDWARE.md).
    const TrackerStats t = tracker->stats();
    const std::uint64_t rejected =
        t.rejected_nonfinite + t.rejected_quaternion + t.rejected_too_fast;
    if (t.foreign_datagrams + t.frame_jumps + rejected > 0)
      text += " | tracking dropped " + std::to_string(t.foreign_datagrams) +
              " foreign datagrams, " + std::to_string(t.frame_jumps) + " jumping frames, " +
              std::to_string(rejected) + " bad poses";
  }
  return text;
}

void RunStats::clear_window() {
  window_periods_.clear();
  window_latency_.clear();
}

void RunStats::summarize(StationSummary& s, std::uint64_t missed_ticks) const {
  s.ticks = tick_index_;
  s.haptic_rate_hz =
      period_us_.count() ? 1e6 * static_cast<double>(period_us_.count()) / period_us_.sum() : 0.0;
  s.period_p99_jitter_us = jitter_us_.quantile(0.99);
  s.period_median_us = period_us_.quantile(0.5);
  s.wake_latency_median_us = wake_us_.quantile(0.5);
  s.wake_latency_p99_us = wake_us_.quantile(0.99);
  s.wake_latency_max_us = wake_us_.max();
  s.missed_ticks = missed_ticks;
  s.nominal_rate_hz = cfg_.rate_hz;
  s.haptic_span_s =
      tick_index_ ? static_cast<double>(last_.deadline_ns - first_deadline_ns_) / 1e9 : 0.0;
  s.log_origin_monotonic_ns = t_start_ns_;
  s.latency_median_ms = latency_ms_.quantile(0.5);
  s.latency_p99_ms = latency_ms_.quantile(0.99);
  s.contact_latency_samples = contact_latency_ms_.count();
  s.contact_latency_median_ms = contact_latency_ms_.quantile(0.5);
  s.contact_latency_p99_ms = contact_latency_ms_.quantile(0.99);
  s.peak_pressure_N = peak_pressure_N_;
  s.peak_shear_N = peak_shear_N_;
}

}  // namespace telex::local
