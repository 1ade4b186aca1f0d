// SPDX-License-Identifier: MIT
// --record-hmd-poses' pairing: the NatNet head body interpolated to the headset's moments, ten a
// second, and what cannot be paired counted rather than written.
#include "telex/local/inputs/hmd_pose_pairer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/gtc/quaternion.hpp>
#include <vector>

namespace telex::local {
namespace {

constexpr std::int64_t kMs = 1'000'000;

// A head turning at 60 deg/s about a tilted axis and moving at 0.2 m/s: a pose for every moment.
Pose head_at(std::int64_t t_ns) {
  const double t_s = static_cast<double>(t_ns) * 1e-9;
  return {{0.2 * t_s, 1.6, -0.1 * t_s},
          glm::angleAxis(t_s * M_PI / 3.0, glm::normalize(glm::dvec3(0.2, 1.0, 0.3)))};
}

double angle_between_deg(const glm::dquat& a, const glm::dquat& b) {
  return 2.0 * std::acos(std::min(1.0, std::abs(glm::dot(a, b)))) * 180.0 / M_PI;
}

TEST(HmdPosePairer, InterpolatesNatNetToTheHeadsetsMomentsTenASecond) {
  HmdPosePairer pairer;
  std::vector<HmdPoseRow> rows;
  // NatNet at 120 Hz from 1 s, the headset at 90 Hz from 1.005 s, for 3 s, interleaved as they
  // arrive (the headset's display time is a frame ahead of its arrival).
  std::int64_t natnet_ns = 1000 * kMs, hmd_ns = 1005 * kMs;
  const std::int64_t natnet_step = 8'333'333, hmd_step = 11'111'111;
  while (natnet_ns < 4000 * kMs) {
    if (hmd_ns - 2 * hmd_step < natnet_ns) {
      pairer.add_hmd(hmd_ns, Pose{{0.0, 0.0, 0.0}, head_at(hmd_ns).q});
      hmd_ns += hmd_step;
    } else {
      pairer.add_natnet(natnet_ns, head_at(natnet_ns));
      natnet_ns += natnet_step;
    }
    HmdPoseRow r;
    while (pairer.pop(r)) rows.push_back(r);
  }
  ASSERT_GE(rows.size(), 29u);
  EXPECT_LE(rows.size(), 31u);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Pose truth = head_at(rows[i].t_ns);
    EXPECT_LT(glm::length(rows[i].X_NatNetHead.p_m - truth.p_m), 1e-9) << i;
    // Slerp between frames of a steady turn is the turn itself (to acos's resolution near 1).
    EXPECT_LT(angle_between_deg(rows[i].X_NatNetHead.q, truth.q), 1e-5) << i;
    EXPECT_LT(angle_between_deg(rows[i].X_StageView.q, truth.q), 1e-5) << i;
    if (i > 0) {
      // Ten a second on average: each the first 90 Hz frame at or after a 100 ms tick.
      EXPECT_GT(rows[i].t_ns - rows[i - 1].t_ns, 88 * kMs);
      EXPECT_LT(rows[i].t_ns - rows[i - 1].t_ns, 112 * kMs);
    }
  }
  const HmdPosePairerStats s = pairer.stats();
  EXPECT_EQ(s.rows, rows.size());
  EXPECT_EQ(s.unpaired, 0u);
  EXPECT_LE(s.hmd_taken - rows.size(), 1u) << "the last one may wait for NatNet";
}

TEST(HmdPosePairer, WaitsForNatNetAndCountsWhatItCannotPair) {
  HmdPosePairer pairer;
  HmdPoseRow r;
  pairer.add_hmd(-5 * kMs, head_at(-5 * kMs));
  EXPECT_EQ(pairer.stats().hmd_taken, 0u) << "taken before NatNet's first frame";
  pairer.add_natnet(0, head_at(0));
  pairer.add_hmd(5 * kMs, head_at(5 * kMs));
  EXPECT_FALSE(pairer.pop(r)) << "paired before NatNet passed the moment";
  pairer.add_natnet(10 * kMs, head_at(10 * kMs));
  ASSERT_TRUE(pairer.pop(r));
  EXPECT_EQ(r.t_ns, 5 * kMs);
  EXPECT_LT(glm::length(r.X_NatNetHead.p_m - head_at(5 * kMs).p_m), 1e-9);

  // A hole of 60 ms in NatNet around the next moment: neither frame within 25 ms of it.
  pairer.add_hmd(110 * kMs, head_at(110 * kMs));
  pairer.add_natnet(80 * kMs, head_at(80 * kMs));
  pairer.add_natnet(140 * kMs, head_at(140 * kMs));
  EXPECT_FALSE(pairer.pop(r));
  EXPECT_EQ(pairer.stats().unpaired, 1u);
  // Faster than ten a second: not taken.
  pairer.add_hmd(150 * kMs, head_at(150 * kMs));
  EXPECT_EQ(pairer.stats().hmd_taken, 2u);
  // A NatNet frame older than the newest is ignored.
  pairer.add_natnet(120 * kMs, head_at(120 * kMs));
  EXPECT_EQ(pairer.stats().natnet_frames, 4u);

  // NatNet stops: the headset's moments wait, then, a second of the headset later, are dropped.
  for (std::int64_t t = 220 * kMs; t <= 1300 * kMs; t += 100 * kMs) {
    pairer.add_hmd(t, head_at(t));
    EXPECT_FALSE(pairer.pop(r));
  }
  EXPECT_GE(pairer.stats().unpaired, 2u);
  EXPECT_EQ(pairer.stats().rows, 1u);
}

}  // namespace
}  // namespace telex::local
