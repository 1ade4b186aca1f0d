// SPDX-License-Identifier: MIT
// RateController against a simulated link: a sender at the controller's target, a bottleneck of
// capacity C with a bounded queue, and the receiver's reports every 100 ms. Simulated time only.
#include "telex/video/rate_controller.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

namespace telex::video {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kFramePeriodNs = 33'333'333;  // 30 Hz
constexpr std::int64_t kReportPeriodNs = 100 * kMs;
constexpr std::int64_t kPacketBytes = 1'200;

// A bottleneck link: packets leave at capacity_bps in order; a packet that finds more than
// queue_limit_bytes ahead of it is dropped; random loss and arrival jitter with a fixed seed.
struct LinkModel {
  double capacity_bps = 10e6;
  std::int64_t queue_limit_bytes = 150'000;
  std::int64_t propagation_ns = 10 * kMs;
  double random_loss = 0.0;
  std::int64_t jitter_ns = 0;  // uniform in [0, jitter_ns]
  std::int64_t busy_until_ns = 0;
  std::mt19937 rng{28};

  // Returns the arrival time, or -1 when dropped.
  std::int64_t send(std::int64_t now_ns, std::int64_t bytes) {
    const std::int64_t start_ns = std::max(now_ns, busy_until_ns);
    const double backlog_bytes = static_cast<double>(start_ns - now_ns) * capacity_bps / 8e9;
    if (backlog_bytes + static_cast<double>(bytes) > static_cast<double>(queue_limit_bytes)) {
      return -1;
    }
    busy_until_ns =
        start_ns + static_cast<std::int64_t>(static_cast<double>(bytes) * 8e9 / capacity_bps);
    if (random_loss > 0.0 && std::uniform_real_distribution<double>(0.0, 1.0)(rng) < random_loss) {
      return -1;  // lost on the wire after taking its slot
    }
    const std::int64_t jitter =
        jitter_ns > 0 ? std::uniform_int_distribution<std::int64_t>(0, jitter_ns)(rng) : 0;
    return busy_until_ns + propagation_ns + jitter;
  }
};

struct Packet {
  std::int64_t send_ns;
  std::int64_t arrival_ns;  // -1: lost
  std::int64_t bytes;
};
struct Group {
  std::int64_t send_ns;
  std::int64_t last_arrival_ns;  // -1: every fragment lost
};

// The sender (frames of target/30 bytes in 1200-byte fragments, sent as a burst each period),
// the link and the receiver's reports, advanced report by report.
class Simulation {
 public:
  explicit Simulation(const RateControllerConfig& config = {}) : controller_(config) {}

  LinkModel link;

  // Runs for `duration_ns`; returns the target after each report.
  std::vector<std::int64_t> run(std::int64_t duration_ns) {
    std::vector<std::int64_t> targets;
    const std::int64_t end_ns = now_ns_ + duration_ns;
    while (now_ns_ < end_ns) {
      const std::int64_t report_ns = now_ns_ + kReportPeriodNs;
      while (next_frame_ns_ <= report_ns) send_frame(next_frame_ns_);
      targets.push_back(controller_.update(report(now_ns_, report_ns), report_ns));
      now_ns_ = report_ns;
    }
    return targets;
  }
  RateController& controller() { return controller_; }

 private:
  void send_frame(std::int64_t t_ns) {
    std::int64_t left = std::max<std::int64_t>(1, controller_.target_bps() / 30 / 8);
    Group group{t_ns, -1};
    while (left > 0) {
      const std::int64_t bytes = std::min(left, kPacketBytes);
      left -= bytes;
      const std::int64_t arrival = link.send(t_ns, bytes);
      packets_.push_back({t_ns, arrival, bytes});
      group.last_arrival_ns = std::max(group.last_arrival_ns, arrival);
    }
    groups_.push_back(group);
    next_frame_ns_ += kFramePeriodNs;
  }

  // What the receiver saw in (from_ns, to_ns]: packets delivered (or due, when lost) in it and the
  // groups whose last fragment arrived in it.
  ReceiverReport report(std::int64_t from_ns, std::int64_t to_ns) {
    ReceiverReport r;
    r.interval_ns = to_ns - from_ns;
    for (const Packet& p : packets_) {
      const std::int64_t due_ns = p.arrival_ns >= 0 ? p.arrival_ns : p.send_ns;
      if (due_ns <= from_ns || due_ns > to_ns) continue;
      ++r.packets_expected;
      if (p.arrival_ns < 0) {
        ++r.packets_lost;
      } else {
        r.bytes_received += static_cast<std::uint64_t>(p.bytes);
      }
    }
    for (const Group& g : groups_) {
      if (g.last_arrival_ns > from_ns && g.last_arrival_ns <= to_ns) {
        r.delay_samples.push_back({g.send_ns, g.last_arrival_ns});
      }
    }
    std::sort(
        r.delay_samples.begin(), r.delay_samples.end(),
        [](const DelaySample& a, const DelaySample& b) { return a.arrival_ns < b.arrival_ns; });
    // Forget what can no longer fall in a later report (a 2 s margin covers the deepest queue).
    std::erase_if(packets_, [&](const Packet& p) { return p.send_ns < to_ns - 2'000 * kMs; });
    std::erase_if(groups_, [&](const Group& g) { return g.send_ns < to_ns - 2'000 * kMs; });
    return r;
  }

  RateController controller_;
  std::int64_t now_ns_ = 0;
  std::int64_t next_frame_ns_ = 0;
  std::vector<Packet> packets_;
  std::vector<Group> groups_;
};

double mean_of(const std::vector<std::int64_t>& v, std::size_t from) {
  double sum = 0.0;
  for (std::size_t i = from; i < v.size(); ++i) sum += static_cast<double>(v[i]);
  return sum / static_cast<double>(v.size() - from);
}

constexpr std::int64_t kS = 1'000 * kMs;

TEST(RateController, StepsDownUnderAThrottledLinkAndConvergesBelowIt) {
  Simulation sim;
  sim.link.capacity_bps = 20e6;
  const auto free_run = sim.run(5 * kS);
  EXPECT_GE(free_run.back(), 4'000'000) << "no congestion: no decrease";
  EXPECT_EQ(sim.controller().counters().delay_decreases, 0u);

  sim.link.capacity_bps = 1.5e6;
  const auto throttled = sim.run(30 * kS);
  // Down below the link within 3 s of the throttle.
  const auto first_below = std::find_if(throttled.begin(), throttled.end(),
                                        [](std::int64_t t) { return t < 1'500'000; });
  ASSERT_NE(first_below, throttled.end());
  EXPECT_LT(first_below - throttled.begin(), 30) << "reports before the target fell below C";
  EXPECT_GT(sim.controller().counters().delay_decreases, 0u);
  // Converged: the last 20 s average below C, and not collapsed far under it.
  const double settled = mean_of(throttled, 100);
  EXPECT_LT(settled, 1.5e6);
  EXPECT_GT(settled, 0.6 * 1.5e6);
  for (std::size_t i = 100; i < throttled.size(); ++i) {
    EXPECT_LT(throttled[i], 1.5e6 * 1.15) << "report " << i;
  }
}

TEST(RateController, StepsBackUpAfterTheLimitIsLifted) {
  Simulation sim;
  sim.link.capacity_bps = 1.5e6;
  const auto throttled = sim.run(20 * kS);
  ASSERT_LT(mean_of(throttled, 150), 1.5e6) << "the last 5 s below the link";

  sim.link.capacity_bps = 20e6;
  const auto lifted = sim.run(30 * kS);

  EXPECT_GT(lifted.back(), 6'000'000) << "the target climbed back after the limit was lifted";
  // Monotone climb: no decrease without congestion.
  const auto decreases_after = sim.controller().counters().delay_decreases;
  sim.run(5 * kS);
  EXPECT_EQ(sim.controller().counters().delay_decreases, decreases_after);
}

TEST(RateController, ReactsToLoss) {
  Simulation sim;
  sim.link.capacity_bps = 50e6;  // no queueing: loss alone
  sim.link.random_loss = 0.2;
  const auto lossy = sim.run(5 * kS);
  EXPECT_LT(lossy.back(), 1'000'000) << "20 % loss cut the rate";
  EXPECT_GT(sim.controller().counters().loss_decreases, 10u);
  EXPECT_EQ(sim.controller().counters().delay_decreases, 0u);

  sim.link.random_loss = 0.05;  // between the thresholds: hold
  const auto held = sim.run(3 * kS);
  const std::int64_t held_max = *std::max_element(held.begin(), held.end());
  EXPECT_LE(held_max, lossy.back() * 2) << "5 % loss does not let the rate run up";

  sim.link.random_loss = 0.0;
  const auto clean = sim.run(20 * kS);
  EXPECT_GT(clean.back(), 4'000'000) << "the rate recovered once loss stopped";
}

TEST(RateController, NeverLeavesItsBounds) {
  RateControllerConfig config;
  config.min_bitrate_bps = 500'000;
  config.max_bitrate_bps = 3'000'000;
  config.start_bitrate_bps = 2'000'000;
  Simulation sim(config);
  for (const double capacity : {50e6, 0.2e6, 50e6, 0.05e6}) {
    sim.link.capacity_bps = capacity;
    sim.link.random_loss = capacity < 1e6 ? 0.5 : 0.0;
    for (const std::int64_t t : sim.run(15 * kS)) {
      ASSERT_GE(t, config.min_bitrate_bps);
      ASSERT_LE(t, config.max_bitrate_bps);
    }
  }
  EXPECT_EQ(sim.controller().target_bps(), config.min_bitrate_bps);
}

TEST(RateController, StaysPutOnASteadyLink) {
  // Capacity above the ceiling, with a few ms of arrival jitter: at the ceiling, never a decrease.
  Simulation sim;
  sim.link.capacity_bps = 30e6;
  sim.link.jitter_ns = 3 * kMs;
  const auto targets = sim.run(60 * kS);
  for (std::size_t i = 100; i < targets.size(); ++i) {
    ASSERT_EQ(targets[i], 8'000'000) << "report " << i;
  }
  EXPECT_EQ(sim.controller().counters().delay_decreases, 0u);
  EXPECT_EQ(sim.controller().counters().overuse_signals, 0u);
}

TEST(RateController, HoldsASteadyBandUnderAFixedLimit) {
  Simulation sim;
  sim.link.capacity_bps = 3e6;
  sim.link.jitter_ns = 2 * kMs;
  const auto targets = sim.run(90 * kS);
  // After convergence the target keeps to a band below C: neither drifting off nor collapsing.
  const double first_half =
      mean_of(std::vector<std::int64_t>(targets.begin() + 300, targets.begin() + 600), 0);
  const double second_half = mean_of(targets, 600);
  EXPECT_LT(second_half, 3e6);
  EXPECT_GT(second_half, 0.7 * 3e6);
  EXPECT_NEAR(first_half, second_half, 0.1 * 3e6);
}

TEST(RateController, IgnoresBadReportsAndCountsThem) {
  RateController controller;
  ReceiverReport bad;
  bad.interval_ns = 0;
  EXPECT_EQ(controller.update(bad, 0), 4'000'000);
  bad.interval_ns = kReportPeriodNs;
  bad.packets_expected = 3;
  bad.packets_lost = 4;
  EXPECT_EQ(controller.update(bad, kReportPeriodNs), 4'000'000);
  EXPECT_EQ(controller.counters().bad_reports, 2u);
  EXPECT_EQ(controller.counters().reports, 0u);

  // A group sent before the previous one is ignored, not taken as a huge gradient.
  ReceiverReport r;
  r.interval_ns = kReportPeriodNs;
  r.bytes_received = 50'000;
  r.delay_samples = {{100 * kMs, 120 * kMs}, {90 * kMs, 125 * kMs}};
  controller.update(r, 2 * kReportPeriodNs);
  EXPECT_EQ(controller.counters().bad_samples, 1u);
  EXPECT_EQ(controller.counters().delay_samples, 1u);
}

TEST(RateController, SameReportsGiveTheSameTargets) {
  Simulation a, b;
  a.link.capacity_bps = b.link.capacity_bps = 2e6;
  a.link.jitter_ns = b.link.jitter_ns = 4 * kMs;
  EXPECT_EQ(a.run(20 * kS), b.run(20 * kS));
}

TEST(RateController, RejectsAnInconsistentConfigNamingTheField) {
  RateControllerConfig config;
  config.start_bitrate_bps = config.max_bitrate_bps + 1;
  try {
    RateController controller(config);
    FAIL() << "accepted a start above the maximum";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("start_bitrate_bps"), std::string::npos) << e.what();
  }
  config = {};
  config.trendline_window = 1;
  EXPECT_THROW(RateController{config}, std::invalid_argument);
}

}  // namespace
}  // namespace telex::video
