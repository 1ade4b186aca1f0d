// SPDX-License-Identifier: MIT
// The robot head: limits, --head specs, the controller (clamp, rate limit, hold on link loss),
// the sim head against its analytic response, none, and udp against a local peer socket.
#include "telex/remote/head.h"

#include <gtest/gtest.h>

#include <boost/asio.hpp>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <thread>

#include "test_support.h"

namespace telex::remote {
namespace {

using ::telex::test::expect_contains;
using ::telex::test::message_of;

using namespace std::chrono_literals;
constexpr double kPi = std::numbers::pi;
constexpr std::int64_t kMs = 1'000'000;

TEST(HeadLimits, DefaultsAreTheDocumentedOnesAndValid) {
  EXPECT_NO_THROW(kDefaultHeadLimits.validate());
  EXPECT_DOUBLE_EQ(kDefaultHeadLimits.joint[0].max_rad, kPi / 2);
  EXPECT_DOUBLE_EQ(kDefaultHeadLimits.joint[1].min_rad, -kPi / 4);
  EXPECT_DOUBLE_EQ(kDefaultHeadLimits.joint[2].max_rad, kPi / 6);
  for (const auto& j : kDefaultHeadLimits.joint) {
    EXPECT_DOUBLE_EQ(j.max_rate_rad_s, kPi);
    EXPECT_DOUBLE_EQ(j.max_accel_rad_s2, 10 * kPi);  // 1800 deg/s^2
  }
}

TEST(HeadLimits, ABadJointIsNamed) {
  HeadLimits l = kDefaultHeadLimits;
  l.joint[1].min_rad = 0.5;
  l.joint[1].max_rad = 0.2;
  EXPECT_THROW(l.validate(), std::invalid_argument);
  EXPECT_NE(message_of([&] { l.validate(); }).find("head pitch"), std::string::npos);
  l = kDefaultHeadLimits;
  l.joint[2].max_rate_rad_s = 0;
  EXPECT_NE(message_of([&] { l.validate(); }).find("head roll: max_rate"), std::string::npos);
  l = kDefaultHeadLimits;
  l.joint[0].max_rad = 4.0;
  EXPECT_NE(message_of([&] { l.validate(); }).find("head yaw"), std::string::npos);
  l = kDefaultHeadLimits;
  l.joint[0].min_rad = std::nan("");
  EXPECT_THROW(l.validate(), std::invalid_argument);
}

TEST(HeadSpec, ValidForms) {
  EXPECT_EQ(parse_head_spec("none").kind, HeadSpec::Kind::None);
  const HeadSpec sim = parse_head_spec("sim");
  EXPECT_EQ(sim.kind, HeadSpec::Kind::Sim);
  EXPECT_DOUBLE_EQ(sim.sim_tau_s, 0.08);
  EXPECT_DOUBLE_EQ(parse_head_spec("sim,tau_ms=40").sim_tau_s, 0.04);
  const HeadSpec d = parse_head_spec("dynamixel:/dev/ttyUSB0");
  EXPECT_EQ(d.kind, HeadSpec::Kind::Dynamixel);
  EXPECT_EQ(d.device, "/dev/ttyUSB0");
  EXPECT_EQ(d.ids, (std::array<std::uint8_t, 3>{1, 2, 3}));
  EXPECT_EQ(d.baud, 57600);
  const HeadSpec d2 =
      parse_head_spec("dynamixel:/dev/serial/by-id/usb-FTDI-if00,ids=7,8,9,baud=1000000");
  EXPECT_EQ(d2.device, "/dev/serial/by-id/usb-FTDI-if00");
  EXPECT_EQ(d2.ids, (std::array<std::uint8_t, 3>{7, 8, 9}));
  EXPECT_EQ(d2.baud, 1000000);
  EXPECT_EQ(parse_head_spec("dynamixel:/dev/ttyACM0,baud=115200,ids=3,1,2").ids,
            (std::array<std::uint8_t, 3>{3, 1, 2}));
  const HeadSpec u = parse_head_spec("udp:10.0.0.5:9100");
  EXPECT_EQ(u.kind, HeadSpec::Kind::Udp);
  EXPECT_EQ(u.host, "10.0.0.5");
  EXPECT_EQ(u.port, 9100);
  EXPECT_EQ(parse_head_spec("udp:[::1]:9100").host, "::1");
}

TEST(HeadSpec, BadFormsNameThePartAndTheValidForms) {
  const std::pair<const char*, const char*> cases[] = {
      {"servo", "unknown head kind 'servo'"},
      {"", "unknown head kind ''"},
      {"none:x", "'none' takes nothing"},
      {"sim:fast", "takes no ':'"},
      {"sim,tau_ms=0", "tau_ms '0'"},
      {"sim,speed=2", "unknown sim option 'speed=2'"},
      {"dynamixel", "needs the serial port"},
      {"dynamixel:", "serial port is empty"},
      {"dynamixel:/dev/ttyUSB0,baud=12345", "57600"},
      {"dynamixel:/dev/ttyUSB0,ids=1,2", "three servo ids"},
      {"dynamixel:/dev/ttyUSB0,ids=1,2,2", "given twice"},
      {"dynamixel:/dev/ttyUSB0,ids=1,2,300", "outside 0..252"},
      {"dynamixel:/dev/ttyUSB0,4", "unknown dynamixel option '4'"},
      {"udp:host", "HOST:PORT"},
      {"udp:host:0", "port '0'"},
      {"udp:host:70000", "port '70000'"},
  };
  for (const auto& [spec, part] : cases) {
    EXPECT_THROW(parse_head_spec(spec), std::invalid_argument) << spec;
    const std::string m = message_of([&] { parse_head_spec(spec); });
    EXPECT_NE(m.find(part), std::string::npos) << spec << ": " << m;
    EXPECT_NE(m.find("dynamixel:DEV[,ids=1,2,3][,baud=57600]"), std::string::npos) << m;
  }
  EXPECT_THROW(make_head_driver("servo"), std::invalid_argument);
}

TEST(HeadNone, MeasuredIsNeverValid) {
  auto head = make_head_driver("none");
  head->command({0.1, 0.2, 0.3}, 0);
  EXPECT_FALSE(head->measured(10 * kMs).valid);
  EXPECT_EQ(head->name(), "none");
  EXPECT_EQ(head->stats().reads, 1u);
}

TEST(HeadSim, SmallStepIsTheFirstOrderLag) {
  // 0.1 rad is within max_rate * tau (pi * 0.08 = 0.25 rad): no rate limit, x = 0.1 (1 - e^-t/tau).
  auto head = make_head_driver("sim");
  EXPECT_TRUE(head->measured(0).valid);
  head->command({0.1, -0.05, 0.02}, 0);
  for (const double t_s : {0.001, 0.01, 0.04, 0.08, 0.2, 0.5}) {
    const HeadPose p = head->measured(static_cast<std::int64_t>(t_s * 1e9));
    ASSERT_TRUE(p.valid);
    const double k = 1.0 - std::exp(-t_s / 0.08);
    EXPECT_NEAR(p.joint_rad[0], 0.1 * k, 1e-12) << t_s;
    EXPECT_NEAR(p.joint_rad[1], -0.05 * k, 1e-12) << t_s;
    EXPECT_NEAR(p.joint_rad[2], 0.02 * k, 1e-12) << t_s;
    EXPECT_EQ(p.time_ns, static_cast<std::int64_t>(t_s * 1e9));
  }
}

TEST(HeadSim, LargeStepIsRateLimitedThenExponential) {
  const double tau = 0.08, rate = kPi, step = 1.0;
  const double t_linear = (step - rate * tau) / rate;  // 0.238 s at pi rad/s
  auto head = make_head_driver("sim,tau_ms=80");
  head->measured(0);
  head->command({step, 0, 0}, 0);
  double last = 0;
  for (int ms = 1; ms <= 1000; ++ms) {
    const double t = ms * 1e-3;
    const double x = head->measured(ms * kMs).joint_rad[0];
    const double expected =
        t <= t_linear ? rate * t : step - rate * tau * std::exp(-(t - t_linear) / tau);
    ASSERT_NEAR(x, expected, 1e-9) << "t = " << t;
    ASSERT_LE(x - last, rate * 1e-3 + 1e-12) << "faster than the rate limit at t = " << t;
    last = x;
  }
}

TEST(HeadSim, ResultDoesNotDependOnHowTimeIsSplit) {
  auto coarse = make_head_driver("sim");
  auto fine = make_head_driver("sim");
  coarse->measured(0);
  fine->measured(0);
  coarse->command({1.2, -0.7, 0.4}, 0);
  fine->command({1.2, -0.7, 0.4}, 0);
  for (int us = 1; us <= 300'000; us += 7) fine->measured(us * 1000LL);
  const HeadPose a = coarse->measured(300'000'000);
  const HeadPose b = fine->measured(300'000'000);
  for (std::size_t j = 0; j < 3; ++j) EXPECT_NEAR(a.joint_rad[j], b.joint_rad[j], 1e-12);
  // An earlier time leaves the state where it is.
  EXPECT_EQ(coarse->measured(100'000'000).joint_rad, a.joint_rad);
}

TEST(HeadSim, TargetsAreClampedToTheLimits) {
  auto head = make_head_driver("sim");
  head->measured(0);
  head->command({3.0, -2.0, 0.0}, 0);
  const HeadPose p = head->measured(5'000'000'000);
  EXPECT_NEAR(p.joint_rad[0], kPi / 2, 1e-9);
  EXPECT_NEAR(p.joint_rad[1], -kPi / 4, 1e-9);
  EXPECT_EQ(head->stats().clamped, 2u);
  head->command({std::nan(""), 0, 0}, 5'000'000'001);
  EXPECT_EQ(head->stats().rejected, 1u);
}

TEST(HeadSim, JointAdvanceIsExactAtTheBandEdge) {
  // Starting exactly at the edge of the band the motion is exponential at once.
  const double band = kPi * 0.08;
  EXPECT_NEAR(sim_joint_advance(0, band, 0.08, 0.08, kPi), band * (1 - std::exp(-1.0)), 1e-15);
  EXPECT_EQ(sim_joint_advance(0.3, 1.0, 0.0, 0.08, kPi), 0.3);
  EXPECT_EQ(sim_joint_advance(0.3, 1.0, -1.0, 0.08, kPi), 0.3);
}

TEST(HeadController, NothingToCommandUntilAPoseOrTarget) {
  HeadController c;
  EXPECT_FALSE(c.update(HeadPose{}, 0).has_value());
  EXPECT_TRUE(c.holding());
  const auto cmd = c.update(HeadPose{{0.1, 0.0, 0.0}, 1, true}, 1);
  ASSERT_TRUE(cmd.has_value());
  EXPECT_EQ(*cmd, (HeadAngles{0.1, 0.0, 0.0}));  // holds where the head is
}

// A fresh sample from the operator's head: a new id each call, 2 ms old, no dead-man.
HeadTarget fresh(const HeadAngles& joint_rad) {
  static std::uint32_t id = 0;
  return {joint_rad, ++id, 2 * kMs, Deadman::NotUsed};
}

// The limits with an acceleration too high to matter, for the tests of the rate limit alone.
HeadControllerConfig rate_only() {
  HeadControllerConfig cfg;
  for (auto& j : cfg.limits.joint) j.max_accel_rad_s2 = 1e9;
  return cfg;
}

TEST(HeadController, ClampsAndRateLimitsFromThePreviousCommand) {
  HeadController c(rate_only());
  const HeadPose at_zero{{0, 0, 0}, 0, true};
  c.set_target(fresh({1.0, 2.0, -0.1}), 0);  // pitch beyond +45 deg
  EXPECT_EQ(c.stats().clamped, 1u);
  auto cmd = c.update(at_zero, 0);
  ASSERT_TRUE(cmd);
  EXPECT_EQ(*cmd, (HeadAngles{0, 0, 0}));  // dt = 0: no motion yet
  for (int ms = 10; ms <= 100; ms += 10) {
    c.set_target(fresh({1.0, 2.0, -0.1}), ms * kMs);
    cmd = c.update(at_zero, ms * kMs);
  }
  // 100 ms at pi rad/s: 0.314 rad for yaw and pitch; roll reached -0.1 within its first 40 ms.
  EXPECT_NEAR((*cmd)[0], kPi * 0.1, 1e-9);
  EXPECT_NEAR((*cmd)[1], kPi * 0.1, 1e-9);
  EXPECT_NEAR((*cmd)[2], -0.1, 1e-12);
  for (int ms = 110; ms <= 1000; ms += 10) {
    c.set_target(fresh({1.0, 2.0, -0.1}), ms * kMs);
    cmd = c.update(at_zero, ms * kMs);
  }
  EXPECT_DOUBLE_EQ((*cmd)[0], 1.0);
  EXPECT_DOUBLE_EQ((*cmd)[1], kPi / 4);  // clamped
  EXPECT_GT(c.stats().rate_limited, 0u);
  EXPECT_FALSE(c.holding());
}

// Targets that jump about (steps of up to a radian, reversals, a target at a joint limit) at a
// head loop whose period wanders between 7 and 13 ms: the commands' own speed (their difference
// over the loop's dt) never exceeds max_rate and changes by at most max_accel * dt per loop, and a
// target held long enough is reached exactly.
TEST(HeadController, AccelerationAndRateLimitsAreRespected) {
  HeadControllerConfig cfg;                    // the rig's defaults: 180 deg/s, 1800 deg/s^2
  cfg.limits.joint[1].max_accel_rad_s2 = 5.0;  // pitch: a slow one
  HeadController c(cfg);
  std::mt19937 rng(27);
  std::uniform_real_distribution<double> yaw(-1.8, 1.8), pitch(-0.9, 0.9), roll(-0.6, 0.6);
  std::uniform_int_distribution<int> period_ms(7, 13);
  std::int64_t t = 0;
  HeadAngles prev{}, prev_v{};
  HeadAngles goal{0.0, 0.0, 0.0};
  double worst_rate = 0, worst_accel = 0;  // as fractions of the limits
  int loops = 0;
  for (int phase = 0; phase < 40; ++phase) {
    goal = {yaw(rng), pitch(rng), roll(rng)};  // beyond the limits at times: clamped
    const int steps = phase % 5 == 4 ? 600 : 40;
    for (int i = 0; i < steps; ++i) {
      const std::int64_t dt = period_ms(rng) * kMs;
      t += dt;
      c.set_target(fresh(goal), t);
      const auto cmd = c.update(HeadPose{prev, t, true}, t);
      ASSERT_TRUE(cmd);
      ASSERT_FALSE(c.holding());
      if (loops++ > 0) {
        for (std::size_t j = 0; j < kHeadJoints; ++j) {
          const HeadJointLimits& l = cfg.limits.joint[j];
          const double dt_s = static_cast<double>(dt) * 1e-9;
          const double v = ((*cmd)[j] - prev[j]) / dt_s;
          worst_rate = std::max(worst_rate, std::abs(v) / l.max_rate_rad_s);
          const double accel = std::abs(v - prev_v[j]) / dt_s / l.max_accel_rad_s2;
          EXPECT_LE(accel, 1.0 + 1e-6)
              << "joint " << j << " loop " << loops << ": from " << prev[j] << " at " << prev_v[j]
              << " rad/s to " << (*cmd)[j] << " at " << v << " rad/s toward " << goal[j];
          worst_accel = std::max(worst_accel, accel);
          prev_v[j] = v;
        }
      }
      prev = *cmd;
    }
    if (steps == 600) {  // 6 s or more: long enough to arrive anywhere
      HeadAngles want = goal;
      clamp_to_limits(want, cfg.limits);
      EXPECT_EQ(prev, want) << "phase " << phase;
    }
  }
  std::printf(
      "HeadController: %d loops, worst speed %.6f x max_rate, worst speed change %.6f x "
      "max_accel * dt; %llu loops accel-limited, %llu rate-limited\n",
      loops, worst_rate, worst_accel, static_cast<unsigned long long>(c.stats().accel_limited),
      static_cast<unsigned long long>(c.stats().rate_limited));
  EXPECT_LE(worst_rate, 1.0 + 1e-9);
  EXPECT_LE(worst_accel, 1.0 + 1e-6);
  EXPECT_GT(worst_accel, 0.99);  // the limit was reached: the test exercised it
  EXPECT_GT(c.stats().accel_limited, 0u);
  EXPECT_GT(c.stats().rate_limited, 0u);
}

TEST(HeadController, NonFiniteTargetsAreDropped) {
  HeadController c;
  c.set_target(fresh({std::nan(""), 0, 0}), 0);
  c.set_target(fresh({0, std::numeric_limits<double>::infinity(), 0}), 0);
  EXPECT_EQ(c.stats().rejected_targets, 2u);
  EXPECT_EQ(c.stats().targets, 0u);
}

TEST(HeadController, RejectsBadConfig) {
  HeadControllerConfig cfg;
  cfg.link_timeout_s = 0;
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
  cfg = {};
  cfg.limits.joint[0].max_rate_rad_s = -1;
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
  cfg = {};
  cfg.limits.joint[2].max_accel_rad_s2 = 0;
  EXPECT_NE(message_of([&] { HeadController{cfg}; }).find("head roll: max_accel"),
            std::string::npos);
  cfg = {};
  cfg.max_sample_age_s = std::nan("");
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
  cfg = {};
  cfg.max_sample_repeat_s = -0.05;
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
}

// The sim head driven by the controller at the remote's 100 Hz, toward a yaw of 1 rad far ahead
// of it (the head lags at its rate and acceleration limits) until `stop_ms`; from there on each
// loop gets the target `after(t)` gives (or none) and the hold must come by `hold_by_ms`. Returns
// the measured yaw and the commanded yaw at each loop from stop_ms on.
struct HoldRun {
  std::vector<double> yaw_after;      // measured at every loop from stop_ms
  std::vector<double> cmd_yaw_after;  // commanded at every loop from stop_ms
  double yaw_before = 0;              // measured 50 ms before stop_ms
  double yaw_at_stop = 0;
  HeadHold reason = HeadHold::None;
  std::int64_t held_at_ns = -1;
  double hold_yaw = 0;  // the hold pose's yaw
  HeadControlStats stats;
};
using AfterStop = std::function<std::optional<HeadTarget>(std::int64_t, const HeadTarget& last)>;
HoldRun run_until_hold(int stop_ms, int end_ms, const AfterStop& after) {
  HeadController c;
  auto head = make_head_driver("sim");
  HoldRun r;
  HeadTarget last;
  HeadAngles prev_cmd{};
  for (std::int64_t t = 0; t <= end_ms * kMs; t += 10 * kMs) {
    const HeadPose p = head->measured(t);
    if (t == (stop_ms - 50) * kMs) r.yaw_before = p.joint_rad[0];
    if (t < stop_ms * kMs) {
      last = fresh({1.0, 0.0, 0.0});
      c.set_target(last, t);
    } else {
      if (r.yaw_after.empty()) r.yaw_at_stop = p.joint_rad[0];
      r.yaw_after.push_back(p.joint_rad[0]);
      if (const auto target = after(t, last)) c.set_target(*target, t);
    }
    const auto cmd = c.update(p, t);
    EXPECT_TRUE(cmd);
    if (t >= stop_ms * kMs) r.cmd_yaw_after.push_back((*cmd)[0]);
    if (c.holding() && r.held_at_ns < 0 && t >= stop_ms * kMs) {
      r.held_at_ns = t;
      r.reason = c.hold_reason();
      EXPECT_TRUE(c.hold_pose());
      r.hold_yaw = c.hold_pose().value_or(HeadAngles{})[0];
      // Where the last command comes to rest braking at 1800 deg/s^2 from at most 180 deg/s: at
      // most pi^2 / (2 * 10 pi) = 0.157 rad on, in the direction it was moving.
      EXPECT_GE(r.hold_yaw, prev_cmd[0]) << "the hold is behind the last command";
      EXPECT_LE(r.hold_yaw, prev_cmd[0] + kPi / 20 + 1e-9) << "the hold is past the braking";
    }
    prev_cmd = *cmd;
    head->command(*cmd, t);
  }
  r.stats = c.stats();
  return r;
}

// Once held, the command brakes to the hold pose (0.1 s at max_accel from max_rate, and the last
// millimetres at shrinking steps: within 0.2 s), then stays exactly there; the sim head goes on
// only toward it, never past it, and settles on it.
void expect_still_after(const HoldRun& r, int stop_ms, const char* what) {
  ASSERT_GE(r.held_at_ns, 0) << what << ": never held";
  const auto first = static_cast<std::size_t>((r.held_at_ns - stop_ms * kMs) / (10 * kMs));
  std::size_t rest = first;
  while (rest < r.cmd_yaw_after.size() && r.cmd_yaw_after[rest] != r.hold_yaw) ++rest;
  std::printf("%s: the command came to rest %zu loops into the hold\n", what, rest - first);
  EXPECT_LE(rest, first + 20) << what << ": the command did not come to rest within 0.2 s";
  for (std::size_t i = rest; i < r.cmd_yaw_after.size(); ++i)
    EXPECT_EQ(r.cmd_yaw_after[i], r.hold_yaw) << what << ": moved again, loop " << i;
  for (std::size_t i = first + 1; i < r.yaw_after.size(); ++i) {
    EXPECT_GE(r.yaw_after[i], r.yaw_after[i - 1]) << what << ": turned back, loop " << i;
    EXPECT_LE(r.yaw_after[i], r.hold_yaw + 1e-12) << what << ": past the hold, loop " << i;
  }
  EXPECT_NEAR(r.yaw_after.back(), r.hold_yaw, 1e-6) << what;
  // And the head was moving when the samples stopped, and stopped short of the target.
  EXPECT_GT(r.yaw_at_stop - r.yaw_before, 0.05) << what;
  EXPECT_LT(r.hold_yaw, 0.9) << what;
}

// The station goes on sending, but its sample stops changing and ages (tracking lost: the
// tracker stopped or lost the head body): held as the sample turns 100 ms old at the latest.
// Here the station says so honestly, with a growing age and the same id, so the repeat rule
// (50 ms on the remote's clock) holds first.
TEST(HeadController, AStaleSampleHoldsTheSimHeadWithinATenthOfASecond) {
  const int stop_ms = 200;
  const HoldRun r = run_until_hold(stop_ms, 1500, [&](std::int64_t t, const HeadTarget& last) {
    HeadTarget again = last;
    again.sample_age_ns = t - (stop_ms - 10) * kMs + 2 * kMs;
    return std::optional<HeadTarget>(again);
  });
  std::printf("stale: held %.0f ms after the last fresh sample (%s), yaw %.4f -> %.4f rad\n",
              static_cast<double>(r.held_at_ns - (stop_ms - 10) * kMs) * 1e-6,
              head_hold_name(r.reason), r.yaw_at_stop, r.yaw_after.back());
  EXPECT_LE(r.held_at_ns - (stop_ms - 10) * kMs, 100 * kMs);
  expect_still_after(r, stop_ms, "stale");
  // Each new sample older than 100 ms (a tracker 150 ms late) holds by the stale rule itself.
  std::uint32_t id = 1000;
  const HoldRun late = run_until_hold(stop_ms, 1500, [&](std::int64_t, const HeadTarget&) {
    return std::optional<HeadTarget>(HeadTarget{{1.0, 0.0, 0.0}, ++id, 150 * kMs});
  });
  EXPECT_EQ(late.reason, HeadHold::Stale);
  EXPECT_EQ(late.held_at_ns, stop_ms * kMs);
  EXPECT_EQ(late.stats.stale_holds, 1u);
  expect_still_after(late, stop_ms, "late samples");
}

// The old station's bug: the same sample resent every 5 ms as if it were new (age 0). The repeat
// rule holds once it has been the newest for more than 50 ms on the remote's clock, while a
// sample repeated for 30 ms (a 33 Hz tracker between two frames) keeps the head moving.
TEST(HeadController, ASampleRepeatedTooLongHolds) {
  const int stop_ms = 200;
  const HoldRun r = run_until_hold(stop_ms, 1500, [&](std::int64_t, const HeadTarget& last) {
    HeadTarget again = last;
    again.sample_age_ns = 0;
    return std::optional<HeadTarget>(again);
  });
  EXPECT_EQ(r.reason, HeadHold::Repeat);
  EXPECT_EQ(r.stats.repeat_holds, 1u);
  // First carried at stop_ms - 10; held at the first loop more than 50 ms later.
  EXPECT_EQ(r.held_at_ns, (stop_ms - 10 + 60) * kMs);
  expect_still_after(r, stop_ms, "repeat");

  HeadController c;
  std::uint32_t id = 5000;
  for (std::int64_t t = 0; t <= 2000 * kMs; t += 5 * kMs) {
    if (t % (30 * kMs) == 0) ++id;  // a new sample every 30 ms, resent every 5 ms
    c.set_target({{0.5, 0.0, 0.0}, id, 0, Deadman::NotUsed}, t);
    c.update(HeadPose{{0, 0, 0}, t, true}, t);
    ASSERT_FALSE(c.holding()) << "at " << t * 1e-6 << " ms";
  }
}

// The operator lets go of the dead-man: held at the next loop; pressed again, the head moves on
// from rest. A station without one (not used) moves the head.
TEST(HeadController, AReleasedDeadmanHolds) {
  const int stop_ms = 200;
  const HoldRun r = run_until_hold(stop_ms, 1500, [&](std::int64_t, const HeadTarget&) {
    HeadTarget t = fresh({1.0, 0.0, 0.0});
    t.deadman = Deadman::Released;
    return std::optional<HeadTarget>(t);
  });
  EXPECT_EQ(r.reason, HeadHold::Deadman);
  EXPECT_EQ(r.held_at_ns, stop_ms * kMs);
  EXPECT_EQ(r.stats.deadman_holds, 1u);
  expect_still_after(r, stop_ms, "dead-man");

  const HeadPose at_zero{{0, 0, 0}, 0, true};
  for (const Deadman d : {Deadman::Pressed, Deadman::NotUsed}) {
    HeadController c;
    HeadTarget t = fresh({0.5, 0.0, 0.0});
    t.deadman = d;
    c.set_target(t, 0);
    c.update(at_zero, 0);
    c.set_target(t, 10 * kMs);
    const auto cmd = c.update(at_zero, 10 * kMs);
    EXPECT_FALSE(c.holding()) << static_cast<int>(d);
    EXPECT_GT((*cmd)[0], 0.0) << static_cast<int>(d);
  }
  // A lab that requires a dead-man (--require-deadman): a station without one holds the head.
  HeadControllerConfig required;
  required.require_deadman = true;
  for (const Deadman d : {Deadman::NotUsed, Deadman::Released, Deadman::Pressed}) {
    HeadController c(required);
    HeadTarget t = fresh({0.5, 0.0, 0.0});
    t.deadman = d;
    c.set_target(t, 0);
    c.update(at_zero, 0);
    c.set_target(t, 10 * kMs);
    const auto cmd = c.update(at_zero, 10 * kMs);
    const bool moves = d == Deadman::Pressed;
    EXPECT_EQ(c.holding(), !moves) << static_cast<int>(d);
    EXPECT_EQ(c.hold_reason(), moves ? HeadHold::None : HeadHold::Deadman) << static_cast<int>(d);
    EXPECT_EQ((*cmd)[0] > 0.0, moves) << static_cast<int>(d);
  }
}

// The operator yaws at 60 deg/s; at 1 s the link goes silent. 100 ms on, the newest sample is
// stale and the head holds where it was last commanded: the command brakes at max_accel from
// 60 deg/s (1.05 rad/s: 1.05^2 / (2 * 10 pi) = 17.5 mrad on) and stays there, and the sim head,
// lagging behind it, settles on it without passing it; at 200 ms the link counts as lost. A new
// target moves it again from rest.
TEST(HeadController, LinkLostHoldsTheSimHeadStill) {
  HeadController c;
  auto head = make_head_driver("sim");
  const double yaw_rate = 60.0 * kPi / 180.0;
  std::int64_t t = 0;
  std::optional<HeadAngles> cmd;
  for (; t <= 1000 * kMs; t += 10 * kMs) {
    c.set_target(fresh({yaw_rate * t * 1e-9, 0.1, 0}), t);
    cmd = c.update(head->measured(t), t);
    ASSERT_TRUE(cmd);
    head->command(*cmd, t);
  }
  // Within 100 ms of the last sample: commands keep following the last target.
  for (; t <= 1090 * kMs; t += 10 * kMs) {
    cmd = c.update(head->measured(t), t);
    head->command(*cmd, t);
    EXPECT_FALSE(c.holding());
  }
  // The sample was 2 ms old when it came at 1000 ms: past 100 ms at 1100 ms (92 ms after it).
  t = 1100 * kMs;
  const HeadAngles last_command = *cmd;
  const HeadPose at_loss = head->measured(t);
  cmd = c.update(at_loss, t);
  ASSERT_TRUE(cmd);
  EXPECT_EQ(c.hold_reason(), HeadHold::Stale);
  ASSERT_TRUE(c.hold_pose());
  const HeadAngles held = *c.hold_pose();
  EXPECT_GE(held[0], last_command[0]);
  EXPECT_LE(held[0], last_command[0] + yaw_rate * yaw_rate / (2 * 10 * kPi) + 1e-9);
  EXPECT_NEAR(held[1], 0.1, 1e-12);
  head->command(*cmd, t);
  double yaw = at_loss.joint_rad[0];
  for (t += 10 * kMs; t <= 3000 * kMs; t += 10 * kMs) {
    const HeadPose p = head->measured(t);
    EXPECT_GE(p.joint_rad[0], yaw) << "turned back while holding at t = " << t * 1e-9;
    EXPECT_LE(p.joint_rad[0], held[0] + 1e-12) << "past the hold at t = " << t * 1e-9;
    yaw = p.joint_rad[0];
    cmd = c.update(p, t);
    if (t >= 1200 * kMs) {
      EXPECT_EQ(*cmd, held) << "command not at rest at t = " << t * 1e-9;
    }
    head->command(*cmd, t);
  }
  EXPECT_NEAR(yaw, held[0], 1e-9);
  EXPECT_EQ(c.hold_reason(), HeadHold::Link);
  EXPECT_EQ(c.stats().stale_holds, 1u);
  EXPECT_EQ(c.stats().link_losses, 1u);
  // The link returns with a target 0.5 rad away: the command starts from the held pose at rest,
  // 1800 deg/s^2 (10 pi rad/s^2) * (10 ms)^2 in the first loop, three times that in the second.
  for (int step = 1; step <= 2; ++step, t += 10 * kMs) {
    c.set_target(fresh({held[0] + 0.5, 0.1, 0}), t);
    cmd = c.update(head->measured(t), t);
    EXPECT_FALSE(c.holding());
    EXPECT_NEAR((*cmd)[0], held[0] + 10.0 * kPi * 1e-4 * (step == 1 ? 1 : 3), 1e-12);
  }
}

// Issue 49: the lab's controller (--head udp) answered once, with the head at yaw 0.548 rad, then
// went silent; the operator turned the head to 1.2 rad over the next 2 s. Releasing the dead-man
// holds the head where it was last commanded, not at the 2 s old reading (that was a jump of
// 0.65 rad in one 10 ms loop); pressed again, it moves on from there. No loop's command moves
// more than max_rate * dt.
TEST(HeadController, AReleaseHoldsAtTheLastCommandNotAStaleMeasurement) {
  HeadController c;
  const double max_step = kPi * 0.01 + 1e-12;  // the default max_rate over one 10 ms loop
  std::int64_t t = 0;
  ASSERT_TRUE(c.update(HeadPose{{0.548, 0, 0}, t, true}, t));
  std::optional<HeadAngles> prev;
  const auto loop = [&](Deadman deadman, double yaw) {
    HeadTarget target = fresh({yaw, 0, 0});
    target.deadman = deadman;
    c.set_target(target, t);
    const auto cmd = c.update(HeadPose{}, t);  // the controller no longer answers
    ASSERT_TRUE(cmd);
    if (prev) {
      EXPECT_LE(std::abs((*cmd)[0] - (*prev)[0]), max_step)
          << "jumped from " << (*prev)[0] << " to " << (*cmd)[0] << " rad at " << t * 1e-6 << " ms";
    }
    prev = cmd;
    t += 10 * kMs;
  };
  while (t < 2000 * kMs) loop(Deadman::Pressed, 1.2);
  EXPECT_NEAR((*prev)[0], 1.2, 1e-9);
  for (int i = 0; i < 50; ++i) loop(Deadman::Released, 1.2);
  EXPECT_EQ(c.hold_reason(), HeadHold::Deadman);
  EXPECT_NEAR((*prev)[0], 1.2, 1e-9) << "held away from where the head was last commanded";
  for (int i = 0; i < 100; ++i) loop(Deadman::Pressed, 0.9);
  EXPECT_FALSE(c.holding());
  EXPECT_NEAR((*prev)[0], 0.9, 1e-9);
}

// Before anything was commanded the head is held where it is measured now: a reading 2 s old is
// not that (the head may have been moved since), so there is nothing to command until a fresh one.
TEST(HeadController, BeforeAnyCommandOnlyAFreshMeasurementIsHeld) {
  HeadController c;
  EXPECT_FALSE(c.update(HeadPose{{0.3, 0, 0}, 0, true}, 2000 * kMs).has_value());
  EXPECT_TRUE(c.holding());
  const auto cmd = c.update(HeadPose{{0.2, 0, 0}, 2005 * kMs, true}, 2010 * kMs);
  ASSERT_TRUE(cmd);
  EXPECT_EQ(*cmd, (HeadAngles{0.2, 0, 0}));
}

// The sim head driven at a wandering 7-13 ms loop through every kind of hold and back: targets
// that move it, a released dead-man, a silent link, stale samples and a sample repeated as new.
// Every command, as a hold begins, while it lasts and as the move resumes, keeps within max_rate
// and changes its speed by at most max_accel * dt; each hold comes to rest and stays there.
TEST(HeadController, HoldsAndResumesWithinTheRateAndAccelerationLimits) {
  HeadController c;
  const HeadLimits& lim = c.config().limits;
  auto head = make_head_driver("sim");
  std::mt19937 rng(49);
  std::uniform_real_distribution<double> yaw(-1.5, 1.5), pitch(-0.7, 0.7);
  std::uniform_int_distribution<int> period_ms(7, 13);
  std::int64_t t = 0;
  std::optional<HeadAngles> prev;
  HeadAngles prev_v{};
  double worst_rate = 0, worst_accel = 0;
  int holds_at_rest = 0;
  std::uint32_t repeated_id = 0;
  for (int phase = 0; phase < 60; ++phase) {
    const int kind = phase % 6;  // 0, 2, 4: move; 1 dead-man, 3 silent or stale, 5 repeat
    const HeadAngles goal{yaw(rng), pitch(rng), 0.0};
    std::int64_t still_since = -1;
    for (int i = 0; i < 40; ++i) {
      const std::int64_t dt = period_ms(rng) * kMs;
      t += dt;
      HeadTarget target = fresh(goal);
      if (kind == 1) target.deadman = Deadman::Released;
      if (kind == 3 && phase % 12 == 9) target.sample_age_ns = 150 * kMs;
      if (kind == 5) {
        target.sample_id = i == 0 ? (repeated_id = target.sample_id) : repeated_id;
        target.sample_age_ns = 0;
      }
      if (kind != 3 || phase % 12 == 9) c.set_target(target, t);
      const auto cmd = c.update(head->measured(t), t);
      ASSERT_TRUE(cmd);
      const double dt_s = static_cast<double>(dt) * 1e-9;
      if (prev) {
        for (std::size_t j = 0; j < kHeadJoints; ++j) {
          const double v = ((*cmd)[j] - (*prev)[j]) / dt_s;
          const double rate = std::abs(v) / lim.joint[j].max_rate_rad_s;
          const double accel = std::abs(v - prev_v[j]) / dt_s / lim.joint[j].max_accel_rad_s2;
          EXPECT_LE(rate, 1.0 + 1e-9) << "joint " << j << " phase " << phase << " loop " << i;
          EXPECT_LE(accel, 1.0 + 1e-6)
              << "joint " << j << " phase " << phase << " loop " << i << ": " << prev_v[j] << " -> "
              << v << " rad/s, holding " << head_hold_name(c.hold_reason());
          worst_rate = std::max(worst_rate, rate);
          worst_accel = std::max(worst_accel, accel);
          prev_v[j] = v;
        }
      }
      if (c.holding() && prev && *cmd == *prev && still_since < 0) still_since = i;
      if (still_since >= 0) {
        EXPECT_EQ(*cmd, *prev) << "moved again while holding, phase " << phase;
      }
      if (kind % 2 == 1 && i == 39 && still_since >= 0) ++holds_at_rest;
      prev = cmd;
      head->command(*cmd, t);
    }
  }
  const HeadControlStats& s = c.stats();
  std::printf(
      "HeadController holds: worst speed %.6f x max_rate, worst speed change %.6f x max_accel * "
      "dt; %d of 30 holds at rest; holds: dead-man %llu, link %llu, stale %llu, repeat %llu\n",
      worst_rate, worst_accel, holds_at_rest, static_cast<unsigned long long>(s.deadman_holds),
      static_cast<unsigned long long>(s.link_losses),
      static_cast<unsigned long long>(s.stale_holds),
      static_cast<unsigned long long>(s.repeat_holds));
  EXPECT_EQ(holds_at_rest, 30);
  EXPECT_EQ(s.deadman_holds, 10u);
  EXPECT_GE(s.link_losses, 5u);
  EXPECT_GE(s.stale_holds, 10u);
  EXPECT_EQ(s.repeat_holds, 10u);
}

TEST(HeadDatagram, LayoutIsFixedLittleEndian) {
  HeadDatagram d;
  d.sequence = 0x01020304;
  d.time_ns = 2;
  d.joint_rad = {0.5, -0.25, 0.0};
  const std::vector<std::uint8_t> bytes = encode_head_datagram(d);
  const std::vector<std::uint8_t> expected = {'T',  'H',  'D',  '1',                     // magic
                                              0x04, 0x03, 0x02, 0x01,                    // sequence
                                              0x02, 0,    0,    0,    0, 0, 0,    0,     // time_ns
                                              0,    0,    0,    0,    0, 0, 0xE0, 0x3F,  // 0.5
                                              0,    0,    0,    0,    0, 0, 0xD0, 0xBF,  // -0.25
                                              0,    0,    0,    0,    0, 0, 0,    0};    // 0
  EXPECT_EQ(bytes, expected);
  const auto back = decode_head_datagram(bytes);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->sequence, d.sequence);
  EXPECT_EQ(back->time_ns, 2);
  EXPECT_EQ(back->joint_rad, d.joint_rad);
  auto wrong = bytes;
  wrong[0] = 'X';
  EXPECT_FALSE(decode_head_datagram(wrong));
  EXPECT_FALSE(decode_head_datagram(std::span(bytes).first(39)));
  d.joint_rad[1] = std::nan("");
  EXPECT_FALSE(decode_head_datagram(encode_head_datagram(d)));
}

// A lab's head controller, played by a local UDP socket.
class UdpPeer {
 public:
  UdpPeer()
      : socket_(io_,
                boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0)) {}
  std::uint16_t port() const { return socket_.local_endpoint().port(); }
  // The next datagram from the remote (waits at most 2 s; a failure, not a measurement).
  std::optional<HeadDatagram> receive() {
    socket_.non_blocking(true);
    std::array<std::uint8_t, 2048> buf{};
    for (int i = 0; i < 2000; ++i) {
      boost::system::error_code ec;
      const std::size_t n = socket_.receive_from(boost::asio::buffer(buf), from_, 0, ec);
      if (!ec) return decode_head_datagram(std::span(buf.data(), n));
      std::this_thread::sleep_for(1ms);
    }
    return std::nullopt;
  }
  void send(const std::vector<std::uint8_t>& bytes) {
    socket_.send_to(boost::asio::buffer(bytes), from_);
  }
  void reply(std::uint32_t sequence, const HeadAngles& a) {
    HeadDatagram d;
    d.sequence = sequence;
    d.time_ns = 123;
    d.joint_rad = a;
    send(encode_head_datagram(d));
  }

 private:
  boost::asio::io_context io_;
  boost::asio::ip::udp::socket socket_;
  boost::asio::ip::udp::endpoint from_;
};

// measured() until `done(pose, stats)` says so, for at most 2 s of polling (loopback delivery is
// asynchronous).
template <typename Done>
HeadPose measure_until(HeadDriver& head, std::int64_t now_ns, Done done) {
  HeadPose p;
  for (int i = 0; i < 2000; ++i) {
    p = head.measured(now_ns);
    if (done(p, head.stats())) break;
    std::this_thread::sleep_for(1ms);
  }
  return p;
}

TEST(HeadUdp, SendsClampedTargetsAndReadsPosesBack) {
  UdpPeer peer;
  auto head = make_head_driver("udp:127.0.0.1:" + std::to_string(peer.port()));
  EXPECT_EQ(head->name(), "udp:127.0.0.1:" + std::to_string(peer.port()));
  EXPECT_FALSE(head->measured(0).valid);  // nothing heard yet

  head->command({0.2, 1.5, -0.1}, 1000);
  head->command({0.3, 0.0, 0.0}, 2000);
  const auto first = peer.receive();
  const auto second = peer.receive();
  ASSERT_TRUE(first && second);
  EXPECT_EQ(first->sequence, 0u);
  EXPECT_EQ(second->sequence, 1u);
  EXPECT_EQ(first->time_ns, 1000);
  EXPECT_EQ(first->joint_rad, (HeadAngles{0.2, kPi / 4, -0.1}));  // pitch clamped
  EXPECT_EQ(head->stats().commands, 2u);
  EXPECT_EQ(head->stats().clamped, 1u);

  const std::int64_t t0 = 10 * kMs;
  peer.reply(100, {0.11, 0.22, -0.05});
  HeadPose p =
      measure_until(*head, t0, [](const HeadPose& q, const HeadStats&) { return q.valid; });
  ASSERT_TRUE(p.valid);
  EXPECT_EQ(p.joint_rad, (HeadAngles{0.11, 0.22, -0.05}));
  EXPECT_EQ(p.time_ns, t0);  // this host's clock when taken, not the controller's 123

  // A reordered older reply and a malformed datagram are counted and change nothing.
  peer.reply(99, {9, 9, 9});
  peer.send({1, 2, 3});
  p = measure_until(*head, t0 + kMs, [](const HeadPose&, const HeadStats& s) {
    return s.stale == 1 && s.bad_packets == 1;
  });
  EXPECT_EQ(head->stats().stale, 1u);
  EXPECT_EQ(head->stats().bad_packets, 1u);
  EXPECT_EQ(p.joint_rad, (HeadAngles{0.11, 0.22, -0.05}));
  EXPECT_TRUE(p.valid);

  // A controller that restarted its count (far behind) is believed.
  peer.reply(0, {0.01, 0.02, 0.03});
  p = measure_until(*head, t0 + 2 * kMs,
                    [](const HeadPose& q, const HeadStats&) { return q.joint_rad[0] == 0.01; });
  EXPECT_EQ(p.joint_rad, (HeadAngles{0.01, 0.02, 0.03}));

  // Half a second without a reply: no longer valid.
  EXPECT_TRUE(head->measured(t0 + 2 * kMs + 500 * kMs).valid);
  EXPECT_FALSE(head->measured(t0 + 2 * kMs + 501 * kMs).valid);
}

TEST(HeadUdp, AnUnresolvableHostIsARuntimeError) {
  EXPECT_THROW(make_head_driver("udp:no-such-host.invalid:9100"), std::runtime_error);
  EXPECT_NE(message_of([] {
              make_head_driver("udp:no-such-host.invalid:9100");
            }).find("cannot resolve 'no-such-host.invalid'"),
            std::string::npos);
}

}  // namespace
}  // namespace telex::remote
