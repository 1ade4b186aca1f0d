// SPDX-License-Identifier: MIT
// PhotonLatency: motion to photon and capture to photon from stamped frames, on made-up clocks.
#include "telex/local/view/photon_latency.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

#include "telex/local/inputs/natnet_client.h"

namespace telex::local {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(PhotonLatency, NothingRecordedReportsNoSamples) {
  PhotonLatency p;
  EXPECT_EQ(p.motion().samples, 0u);
  EXPECT_EQ(p.capture().samples, 0u);
  EXPECT_FALSE(p.recent().motion_ms.has_value());
  EXPECT_FALSE(p.recent().capture_ms.has_value());
}

// The remote's clock runs 5 s ahead of the station's: the capture time comes back through the
// offset, the motion time (already on the station's clock) does not.
TEST(PhotonLatency, CaptureGoesThroughTheClockOffsetAndMotionDoesNot) {
  PhotonLatency p;
  const std::int64_t offset_ns = 5'000 * kMs;  // remote - station
  const std::int64_t photon_ns = 100'000 * kMs;
  p.record({photon_ns - 12 * kMs, photon_ns + offset_ns - 70 * kMs}, photon_ns, offset_ns);
  const auto m = p.motion(), c = p.capture();
  EXPECT_EQ(m.samples, 1u);
  EXPECT_DOUBLE_EQ(m.median_ms, 12.0);
  EXPECT_EQ(c.samples, 1u);
  EXPECT_DOUBLE_EQ(c.median_ms, 70.0);
  EXPECT_DOUBLE_EQ(*p.recent().motion_ms, 12.0);
  EXPECT_DOUBLE_EQ(*p.recent().capture_ms, 70.0);
}

// A frame drawn without video (or without a tracked body) counts in the other figure only.
TEST(PhotonLatency, AnUnstampedPartIsNotASample) {
  PhotonLatency p;
  p.record({10 * kMs, 0}, 30 * kMs, 0);
  p.record({0, 5 * kMs}, 40 * kMs, 0);
  EXPECT_EQ(p.motion().samples, 1u);
  EXPECT_DOUBLE_EQ(p.motion().median_ms, 20.0);
  EXPECT_EQ(p.capture().samples, 1u);
  EXPECT_DOUBLE_EQ(p.capture().median_ms, 35.0);
}

// The run's figures keep every sample; the status line's median follows the newest kRecent.
TEST(PhotonLatency, TheRecentMedianForgetsWhatTheRunKeeps) {
  PhotonLatency p;
  std::int64_t photon_ns = 1'000 * kMs;
  for (std::size_t i = 0; i < PhotonLatency::kRecent; ++i, photon_ns += 10 * kMs)
    p.record({photon_ns - 100 * kMs, 0}, photon_ns, 0);
  for (std::size_t i = 0; i < PhotonLatency::kRecent; ++i, photon_ns += 10 * kMs)
    p.record({photon_ns - 10 * kMs, 0}, photon_ns, 0);
  EXPECT_DOUBLE_EQ(*p.recent().motion_ms, 10.0);
  const auto m = p.motion();
  EXPECT_EQ(m.samples, 2 * PhotonLatency::kRecent);
  EXPECT_DOUBLE_EQ(m.median_ms, 55.0);  // half at 10 ms, half at 100 ms: interpolated
  EXPECT_DOUBLE_EQ(m.p99_ms, 100.0);
}

// The status line's part stays short (it wraps on the view) and says only what is known.
TEST(PhotonLatency, TheStatusTextSaysWhatIsKnown) {
  EXPECT_EQ(photon_status({}), "");
  EXPECT_EQ(photon_status({22.6, 61.2}), " | to photon: motion 23 ms, video 61 ms");
  EXPECT_EQ(photon_status({22.6, std::nullopt}), " | to photon: motion 23 ms");
  EXPECT_EQ(photon_status({std::nullopt, 61.2}), " | to photon: video 61 ms");
  // --view png hands its frames to files once a status line: said so, not as a display's.
  EXPECT_EQ(photon_status({22.6, 61.2}, true), " | to the PNGs: motion 23 ms, video 61 ms");
  EXPECT_EQ(photon_status({}, true), "");
}

// The start of motion to photon with NatNet: the latency the frame reports, in each layout.
TEST(NatNetReportedLatency, StampsOverTheServerClockFrom3AndSoftwareLatencyBefore) {
  natnet::Frame f;
  f.stamp_mid_exposure = 1'000'000;
  f.stamp_transmit = 1'000'000 + 45'000;  // 4.5 ms at 10 MHz
  EXPECT_EQ(natnet_reported_latency_ns(f, {4, 1}, 10'000'000), 4'500'000);
  EXPECT_EQ(natnet_reported_latency_ns(f, {3, 0}, 10'000'000), 4'500'000);
  EXPECT_EQ(natnet_reported_latency_ns(f, {3, 1}, 0), 0) << "no SERVERINFO clock rate yet";
  f.software_latency_s = 0.006f;
  EXPECT_EQ(natnet_reported_latency_ns(f, {2, 11}, 10'000'000), 6'000'000);
}

TEST(NatNetReportedLatency, StampsThatAreNoLatencyGiveNone) {
  natnet::Frame f;
  f.stamp_mid_exposure = 0;  // unset
  f.stamp_transmit = 50'000;
  EXPECT_EQ(natnet_reported_latency_ns(f, {4, 1}, 10'000'000), 0);
  f.stamp_mid_exposure = 60'000;  // after the transmission
  EXPECT_EQ(natnet_reported_latency_ns(f, {4, 1}, 10'000'000), 0);
  f.stamp_mid_exposure = 1;
  f.stamp_transmit = 20'000'001;  // 2 s: a clock that restarted, not a latency
  EXPECT_EQ(natnet_reported_latency_ns(f, {4, 1}, 10'000'000), 0);
  f.software_latency_s = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(natnet_reported_latency_ns(f, {2, 11}, 10'000'000), 0);
  f.software_latency_s = -0.001f;
  EXPECT_EQ(natnet_reported_latency_ns(f, {2, 11}, 10'000'000), 0);
}

}  // namespace
}  // namespace telex::local
