// SPDX-License-Identifier: MIT
// The main thread's statistics of a run: the haptic ticks' periods, jitter and capture-to-force
// latency, the peak forces, the live force lines on stdout and the once-a-second status text.
// In fixed memory, so a long run's resident size stays flat.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "messages.h"
#include "telex/base/periodic.h"
#include "telex/local/link/surface_client.h"
#include "telex/local/station/station_config.h"
#include "telex/local/station/station_summary.h"

namespace telex::local {

class RunStats {
 public:
  RunStats(const StationConfig& cfg, std::int64_t t_start_ns);

  // One tick sample from the haptic thread; clock_offset_ns is the remote's clock less ours.
  // Returns the tick's number (1 = the first).
  std::uint64_t add(const TickSample& s, std::int64_t clock_offset_ns);
  const TickSample& last() const { return last_; }
  // The force lines start with the first tick at or after now_ns (the main loop's start).
  void start_printing(std::int64_t now_ns) { next_print_ns_ = now_ns; }

  // The status line's text over the last window (surfaces built per second `fps`), then a new
  // window starts with clear_window().
  std::string status_text(double fps, double build_ms, ClientState state,
                          const HandTracker* tracker) const;
  void clear_window();

  // Ticks, rates, jitter, latencies and peak forces.
  void summarize(StationSummary& s, std::uint64_t missed_ticks) const;

 private:
  void add_latency(const TickSample& s, std::int64_t clock_offset_ns);
  void print_forces(const TickSample& s);

  const StationConfig& cfg_;
  const std::int64_t t_start_ns_;
  const std::int64_t period_ns_;
  const std::int64_t print_period_ns_;  // --print-forces; 0 = off
  Histogram period_us_{1.0, 20'000}, jitter_us_{1.0, 20'000}, latency_ms_{0.1, 20'000},
      contact_latency_ms_{0.1, 20'000};
  // Wake-up latency: the tick's wake-up less its deadline, what cyclictest measures.
  Histogram wake_us_{1.0, 20'000};
  std::vector<std::int64_t> window_periods_;
  std::vector<double> window_latency_;
  TickSample last_{};
  std::uint64_t tick_index_ = 0;
  std::int64_t first_deadline_ns_ = 0;
  std::uint64_t last_latency_frame_ = 0;
  std::int64_t last_latency_capture_ = 0;
  std::int64_t next_print_ns_ = 0;
  double peak_pressure_N_ = 0, peak_shear_N_ = 0;
};

}  // namespace telex::local
