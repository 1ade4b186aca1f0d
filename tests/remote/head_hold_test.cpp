// SPDX-License-Identifier: MIT
// The head controller's holds (link lost, stale or repeated samples, the dead-man) with the sim
// head: where the head holds, that neither the hold nor the move after it jumps (issue 49), and
// that the command comes to rest and stays there.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include "telex/remote/head.h"

namespace telex::remote {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr std::int64_t kMs = 1'000'000;

// A fresh sample from the operator's head: a new id each call, 2 ms old when sent and when it
// arrived (the operator's clock known), no dead-man.
HeadTarget fresh(const HeadAngles& joint_rad) {
  static std::uint32_t id = 0;
  return {joint_rad, ++id, 2 * kMs, Deadman::NotUsed, 0, 2 * kMs};
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
    return std::optional<HeadTarget>(
        HeadTarget{{1.0, 0.0, 0.0}, ++id, 150 * kMs, Deadman::NotUsed, 0, 150 * kMs});
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
    c.set_target({{0.5, 0.0, 0.0}, id, 0, Deadman::NotUsed, 0, 0}, t);
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

// Issue 49 (8): the station judged a sample's age when it built the command; a command that then
// waited in its send queue arrives old but says it is fresh. The remote takes the larger of that
// age and the one it judges at arrival on the operator's clock: 400 ms old on arrival is stale,
// whatever it was sent with, and its age goes on growing from there.
TEST(HeadController, ATargetThatArrivesOldIsStaleWhateverAgeItWasSentWith) {
  HeadController c;
  const HeadPose at_zero{{0, 0, 0}, 0, true};
  HeadTarget late = fresh({0.5, 0, 0});
  late.arrival_age_ns = 400 * kMs;
  c.set_target(late, 0);
  EXPECT_EQ(c.update(at_zero, 0), (HeadAngles{0, 0, 0}));
  EXPECT_EQ(c.hold_reason(), HeadHold::Stale);
  EXPECT_EQ(c.sample_age_ns(10 * kMs), 410 * kMs);
  EXPECT_EQ(c.stats().stale_holds, 1u);
  // The station's claim wins when it is the older (the operator's clock a little off).
  HeadTarget claims_older = fresh({0.5, 0, 0});
  claims_older.sample_age_ns = 150 * kMs;
  c.set_target(claims_older, 20 * kMs);
  c.update(HeadPose{{0, 0, 0}, 20 * kMs, true}, 20 * kMs);
  EXPECT_EQ(c.hold_reason(), HeadHold::Stale);
  EXPECT_EQ(c.sample_age_ns(20 * kMs), 150 * kMs);
  // Fresh on both counts: it moves.
  c.set_target(fresh({0.5, 0, 0}), 30 * kMs);
  c.update(HeadPose{{0, 0, 0}, 30 * kMs, true}, 30 * kMs);
  const auto cmd = c.update(HeadPose{{0, 0, 0}, 40 * kMs, true}, 40 * kMs);
  EXPECT_FALSE(c.holding());
  EXPECT_GT((*cmd)[0], 0.0);
}

// Before the remote knows the operator's clock (no probe answered yet), a target's age at arrival
// cannot be judged: it is no target yet, the head holds for the link.
TEST(HeadController, ATargetWhoseAgeAtArrivalIsUnknownDoesNotMoveTheHead) {
  HeadController c;
  HeadTarget unjudged = fresh({0.5, 0, 0});
  unjudged.arrival_age_ns.reset();
  for (std::int64_t t = 0; t <= 100 * kMs; t += 10 * kMs) {
    c.set_target(unjudged, t);
    EXPECT_EQ(c.update(HeadPose{{0, 0, 0}, t, true}, t), (HeadAngles{0, 0, 0}));
    EXPECT_EQ(c.hold_reason(), HeadHold::Link);
  }
  EXPECT_EQ(c.stats().link_losses, 0u);  // never had a link to lose
  c.set_target(fresh({0.5, 0, 0}), 110 * kMs);
  c.update(HeadPose{{0, 0, 0}, 110 * kMs, true}, 110 * kMs);
  EXPECT_FALSE(c.holding());
}

}  // namespace
}  // namespace telex::remote
