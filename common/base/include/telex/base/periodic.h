// SPDX-License-Identifier: MIT
// Fixed-rate loop timing (absolute deadlines, no drift) and period statistics, for the haptic
// thread and anything else that runs at a rate.
#pragma once

#include <pthread.h>

#include <cstdint>
#include <string>
#include <vector>

namespace telex {

std::int64_t monotonic_ns();

// What a PeriodicTimer reads and how it waits. The daemons use monotonic_clock() (CLOCK_MONOTONIC,
// clock_nanosleep with an absolute deadline); tests substitute a simulated clock.
class TimerClock {
 public:
  virtual ~TimerClock() = default;
  virtual std::int64_t now_ns() = 0;
  virtual void sleep_until_ns(std::int64_t deadline_ns) = 0;
};
TimerClock& monotonic_clock();

// Sleeps until absolute deadlines spaced by period_ns. A tick that overran by more than a whole
// period skips the deadlines it overran (counted as missed) instead of bursting to catch up, and
// stays on the grid: from the first deadline to deadline(), ticks + missed() = deadlines.
class PeriodicTimer {
 public:
  explicit PeriodicTimer(std::int64_t period_ns, TimerClock& clock = monotonic_clock());
  // Waits for the next deadline; returns the actual wake-up time.
  std::int64_t wait_next();
  std::uint64_t missed() const { return missed_; }
  // The deadline the last wait_next() waited for (0 before the first).
  std::int64_t deadline_ns() const { return next_ns_; }
  std::int64_t period_ns() const { return period_ns_; }

 private:
  std::int64_t period_ns_;
  TimerClock& clock_;
  std::int64_t next_ns_ = 0;
  std::uint64_t missed_ = 0;
};

// Tries SCHED_FIFO at `priority` for the calling thread; returns a description of what was applied.
std::string try_realtime(int priority);
// The same for `thread` (std::thread::native_handle()), set by the thread that started it. A
// priority of 0 leaves the thread as it is and says "default scheduling".
std::string try_realtime(pthread_t thread, int priority);

// Names `thread` for top -H, gdb and /proc/PID/task/*/comm (at most 15 characters are kept).
void name_thread(pthread_t thread, const std::string& name);

// SCHED_FIFO priorities of the threads between a depth capture and the force it produces
// (docs/ARCHITECTURE.md, "Threads"). On one machine (loopback) the haptic loop preempts the
// station's surface path, which preempts the remote's; everything else (video, view, logs, other
// programs) runs below all of them. Measured in docs/BENCHMARKS.md: with two busy processes on
// the two cores, contact latency p99 stayed at 2.35-2.45 ms with these, against 7.25-10.85 ms
// without.
inline constexpr int kHapticPriority = 80;
inline constexpr int kStationPathPriority = 70;  // depth network thread, surface thread, tracking
inline constexpr int kHeadLoopPriority = 60;     // the remote's servo loop
inline constexpr int kRemotePathPriority = 50;   // capture, process, network
// The station's display supervisor (a process, blocked until the station ends): below every thread
// above, so it can never delay one, and above every program at default scheduling, so the zero
// force it sends when the station dies does not wait for a CPU.
inline constexpr int kSupervisorPriority = 1;

struct PeriodSummary {
  std::size_t count = 0;
  double mean_rate_hz = 0;
  double median_period_us = 0;
  double p99_jitter_us = 0;  // 99th percentile of |period - nominal|
  double max_jitter_us = 0;
};

// Summary of observed periods (ns) against the nominal period.
PeriodSummary summarize_periods(const std::vector<std::int64_t>& periods_ns,
                                std::int64_t nominal_ns);

// Fixed-memory histogram for long runs: counts in bins of `bin_width` from 0, the last bin
// collecting everything above the range. Quantiles are exact to one bin.
class Histogram {
 public:
  Histogram(double bin_width, std::size_t bins) : width_(bin_width), counts_(bins, 0) {}
  void add(double v);
  std::uint64_t count() const { return n_; }
  double sum() const { return sum_; }
  double max() const { return max_; }
  // The p-quantile (0..1) as the centre of the bin that holds it (0 when empty).
  double quantile(double p) const;

 private:
  double width_;
  std::vector<std::uint64_t> counts_;
  std::uint64_t n_ = 0;
  double sum_ = 0;
  double max_ = 0;
};

// The p-quantile (0..1) of a sample, linearly interpolated (copies, does not modify input).
double percentile(std::vector<double> values, double p);

}  // namespace telex
