// SPDX-License-Identifier: MIT
// The eyes' bit rate from receiver reports (EyeRate): on a link model with a capacity, a bounded
// queue and depth at a steady rate, the eyes get --video-bitrate on an ample link, step down to
// what the depth leaves when the link is throttled, and step back up when it is freed.
#include "telex/remote/eye_rate.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace telex::remote {
namespace {

struct Link {
  double capacity_bps = 50e6;
  double queue_bytes = 0;
  double max_queue_s = 0.1;
};

// 250 ms of the link (the station's report interval) in 1 ms steps: depth and video offered at
// their rates, delivered at the capacity, the queue's excess dropped; the delay of what arrives is
// a 20 ms base plus the queue's wait.
proto::ReceiverReport run_interval(Link& link, double depth_bps, double video_bps) {
  constexpr int kSteps = 250;
  constexpr double kDt = 1e-3;
  double delivered = 0, dropped = 0, video_delivered = 0;
  double n = 0, st = 0, sd = 0, stt = 0, std_ = 0, last = 0;
  for (int i = 0; i < kSteps; ++i) {
    const double offered = (depth_bps + video_bps) * kDt / 8.0;
    link.queue_bytes += offered;
    const double limit = link.capacity_bps * link.max_queue_s / 8.0;
    if (link.queue_bytes > limit) {
      dropped += link.queue_bytes - limit;
      link.queue_bytes = limit;
    }
    const double out = std::min(link.queue_bytes, link.capacity_bps * kDt / 8.0);
    link.queue_bytes -= out;
    delivered += out;
    video_delivered += out * video_bps / (depth_bps + video_bps);
    const double t = i * kDt;
    const double d_us = 20'000.0 + link.queue_bytes * 8.0 / link.capacity_bps * 1e6;
    ++n;
    st += t;
    sd += d_us;
    stt += t * t;
    std_ += t * d_us;
    last = d_us;
  }
  proto::ReceiverReport r;
  r.interval_us = 250'000;
  r.bytes_received = static_cast<std::uint64_t>(delivered);
  r.video_bytes = static_cast<std::uint64_t>(video_delivered);
  r.datagrams_received = static_cast<std::uint32_t>(delivered / 1200.0);
  r.fragments_lost = static_cast<std::uint32_t>(dropped / 1200.0);
  r.delay_samples = static_cast<std::uint32_t>(n);
  r.delay_mean_us = static_cast<std::int32_t>(sd / n);
  r.delay_last_us = static_cast<std::int32_t>(last);
  r.delay_gradient_us_per_s = static_cast<float>((std_ - st * sd / n) / (stt - st * st / n));
  return r;
}

TEST(EyeRate, StepsDownUnderAThrottledLinkAndBackUpAfter) {
  constexpr double kDepth = 3e6;
  EyeRate rate(4'000'000);
  Link link;
  std::int64_t now = 1'000'000'000;
  auto run = [&](double seconds, std::vector<double>& video) {
    for (int i = 0; i < static_cast<int>(seconds * 4); ++i) {
      const auto r = run_interval(link, kDepth, static_cast<double>(rate.video_bps()));
      now += 250'000'000;
      video.push_back(static_cast<double>(rate.on_report(r, now)));
    }
  };
  std::vector<double> free1, throttled, free2;
  run(10, free1);
  EXPECT_EQ(free1.back(), 4e6) << "an ample link: --video-bitrate";
  link.capacity_bps = 5e6;  // depth takes 3 of it
  run(20, throttled);
  double sum = 0;
  for (std::size_t i = throttled.size() / 2; i < throttled.size(); ++i) sum += throttled[i];
  const double mean_late = sum / static_cast<double>(throttled.size() - throttled.size() / 2);
  // The depth leaves 2 Mbit/s: the eyes saw-tooth around it (back off on loss, creep up).
  EXPECT_LT(mean_late, 2.2e6) << "the eyes get at most what the depth leaves";
  EXPECT_GT(mean_late, 1.4e6) << "and use most of it";
  EXPECT_GE(*std::min_element(throttled.begin(), throttled.end()), 300'000.0);
  link.capacity_bps = 50e6;
  run(30, free2);
  EXPECT_GE(free2.back(), 3.5e6) << "back up once the limit is lifted";
  EXPECT_LE(*std::max_element(free2.begin(), free2.end()), 4e6);
}

// Depth alone at 16 Mbit/s on an ample link (the synthetic scenes' full frames): the first report
// already leaves the eyes their --video-bitrate, not the floor.
TEST(EyeRate, HeavyDepthOnAnAmpleLinkLeavesTheEyesTheirRateFromTheFirstReport) {
  EyeRate rate(4'000'000);
  Link link;
  const auto r = run_interval(link, 16e6, 4e6);
  EXPECT_EQ(rate.on_report(r, 1'250'000'000), 4'000'000);
}

TEST(EyeRate, TheStationsDelayLineBecomesTwoSamplesWithItsSlope) {
  proto::ReceiverReport r;
  r.interval_us = 200'000;
  r.delay_samples = 10;
  r.delay_mean_us = 30'000;
  r.delay_gradient_us_per_s = 50'000.0f;  // 50 ms more delay per second
  r.datagrams_received = 90;
  r.fragments_lost = 10;
  const auto c = EyeRate::to_controller(r, 5'000'000'000);
  EXPECT_EQ(c.interval_ns, 200'000'000);
  EXPECT_EQ(c.packets_expected, 100u);
  EXPECT_EQ(c.packets_lost, 10u);
  ASSERT_EQ(c.delay_samples.size(), 2u);
  const auto& a = c.delay_samples[0];
  const auto& b = c.delay_samples[1];
  const double delay_a = static_cast<double>(a.arrival_ns - a.send_ns);
  const double delay_b = static_cast<double>(b.arrival_ns - b.send_ns);
  EXPECT_NEAR((delay_b - delay_a) / static_cast<double>(b.arrival_ns - a.arrival_ns), 0.05, 1e-6);
  EXPECT_NEAR((delay_a + delay_b) / 2.0, 30e6, 1.0);
  r.delay_samples = 1;
  EXPECT_TRUE(EyeRate::to_controller(r, 5'000'000'000).delay_samples.empty());
}

}  // namespace
}  // namespace telex::remote
