// SPDX-License-Identifier: MIT
// Fixed-rate loop timing and period statistics.
#include "telex/base/periodic.h"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "telex/base/demand.h"

namespace telex {

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

namespace {

class MonotonicClock final : public TimerClock {
 public:
  std::int64_t now_ns() override { return monotonic_ns(); }
  void sleep_until_ns(std::int64_t deadline_ns) override {
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(deadline_ns / 1'000'000'000);
    ts.tv_nsec = static_cast<long>(deadline_ns % 1'000'000'000);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
};

}  // namespace

TimerClock& monotonic_clock() {
  static MonotonicClock clock;
  return clock;
}

PeriodicTimer::PeriodicTimer(std::int64_t period_ns, TimerClock& clock)
    : period_ns_(period_ns), clock_(clock) {
  TELEX_DEMAND(period_ns > 0);
}

std::int64_t PeriodicTimer::wait_next() {
  const std::int64_t now = clock_.now_ns();
  if (next_ns_ == 0) next_ns_ = now;
  next_ns_ += period_ns_;
  if (now - next_ns_ > period_ns_) {
    // Overran by more than a period: skip the deadlines that are a whole period or more in the
    // past (counted as missed) and tick at the latest one that has passed, staying on the grid.
    // No burst, and every deadline is either ticked or missed: ticks + missed = deadlines.
    const std::int64_t skipped = (now - next_ns_) / period_ns_;
    missed_ += static_cast<std::uint64_t>(skipped);
    next_ns_ += skipped * period_ns_;
  }
  clock_.sleep_until_ns(next_ns_);
  return clock_.now_ns();
}

void name_thread(pthread_t thread, const std::string& name) {
  pthread_setname_np(thread, name.substr(0, 15).c_str());
}

std::string try_realtime(int priority) { return try_realtime(pthread_self(), priority); }

std::string try_realtime(pthread_t thread, int priority) {
  if (priority <= 0) return "default scheduling";
  sched_param sp{};
  sp.sched_priority = priority;
  const int rc = pthread_setschedparam(thread, SCHED_FIFO, &sp);
  if (rc == 0) return "SCHED_FIFO priority " + std::to_string(priority);
  return std::string("default scheduling (SCHED_FIFO refused: ") + std::strerror(rc) + ")";
}

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double pos = std::clamp(p, 0.0, 1.0) * static_cast<double>(values.size() - 1);
  const auto k = static_cast<std::size_t>(pos);
  if (k + 1 >= values.size()) return values.back();
  return values[k] + (values[k + 1] - values[k]) * (pos - static_cast<double>(k));
}

void Histogram::add(double v) {
  if (!std::isfinite(v)) return;
  const double clamped = std::max(0.0, v);
  const auto bin = std::min(counts_.size() - 1, static_cast<std::size_t>(clamped / width_));
  ++counts_[bin];
  ++n_;
  sum_ += v;
  max_ = n_ == 1 ? v : std::max(max_, v);
}

double Histogram::quantile(double p) const {
  if (n_ == 0) return 0.0;
  const auto rank =
      static_cast<std::uint64_t>(std::ceil(std::clamp(p, 0.0, 1.0) * static_cast<double>(n_)));
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < counts_.size(); ++i) {
    seen += counts_[i];
    if (seen >= std::max<std::uint64_t>(rank, 1)) return (static_cast<double>(i) + 0.5) * width_;
  }
  return max_;
}

PeriodSummary summarize_periods(const std::vector<std::int64_t>& periods_ns,
                                std::int64_t nominal_ns) {
  PeriodSummary s;
  s.count = periods_ns.size();
  if (periods_ns.empty()) return s;
  double total = 0;
  std::vector<double> periods_us, jitter_us;
  periods_us.reserve(periods_ns.size());
  jitter_us.reserve(periods_ns.size());
  for (auto p : periods_ns) {
    total += static_cast<double>(p);
    periods_us.push_back(static_cast<double>(p) / 1e3);
    jitter_us.push_back(std::abs(static_cast<double>(p - nominal_ns)) / 1e3);
  }
  s.mean_rate_hz = 1e9 * static_cast<double>(periods_ns.size()) / total;
  s.median_period_us = percentile(periods_us, 0.5);
  s.p99_jitter_us = percentile(jitter_us, 0.99);
  s.max_jitter_us = *std::max_element(jitter_us.begin(), jitter_us.end());
  return s;
}

}  // namespace telex
