// SPDX-License-Identifier: MIT
// ReceiverReportBuilder: interval counts, delay mean/last and the delay's slope, and what it
// leaves out (the first call, an empty interval).
#include "telex/local/link/receiver_report.h"

#include <gtest/gtest.h>

namespace telex::local {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(ReceiverReport, FirstTakeOnlyStartsTheInterval) {
  ReceiverReportBuilder b;
  b.add_datagram(1000);
  EXPECT_FALSE(b.take(5 * kMs).has_value());
  EXPECT_FALSE(b.take(5 * kMs).has_value());  // an empty interval
}

TEST(ReceiverReport, CountsAndDelayOverOneInterval) {
  ReceiverReportBuilder b;
  const std::int64_t t0 = 1000 * kMs;
  ASSERT_FALSE(b.take(t0).has_value());
  // Ten messages 25 ms apart whose one-way delay grows 2 ms per message: 80 ms/s.
  for (int i = 0; i < 10; ++i) {
    const std::int64_t arrival = t0 + (i + 1) * 25 * kMs;
    const std::int64_t delay = (20 + 2 * i) * kMs;
    b.add_datagram(1400);
    b.add_datagram(600);
    b.add_message(arrival - delay, arrival, i % 2 == 0 ? 2000 : 0);
  }
  b.add_lost(3);
  b.add_message(0, t0 + 260 * kMs, 0);  // no capture time: no delay sample
  const auto r = b.take(t0 + 250 * kMs);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->interval_us, 250'000u);
  EXPECT_EQ(r->bytes_received, 20'000u);
  EXPECT_EQ(r->video_bytes, 10'000u);
  EXPECT_EQ(r->datagrams_received, 20u);
  EXPECT_EQ(r->fragments_lost, 3u);
  EXPECT_EQ(r->delay_samples, 10u);
  EXPECT_EQ(r->delay_mean_us, 29'000);
  EXPECT_EQ(r->delay_last_us, 38'000);
  EXPECT_NEAR(r->delay_gradient_us_per_s, 80'000.0f, 1.0f);
  // The next interval starts empty.
  const auto next = b.take(t0 + 500 * kMs);
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->bytes_received, 0u);
  EXPECT_EQ(next->delay_samples, 0u);
  EXPECT_EQ(next->delay_mean_us, 0);
  // A report that encodes (no -0.0, bounds kept).
  EXPECT_NO_THROW(proto::encode({}, *next));
  EXPECT_NO_THROW(proto::encode({}, *r));
}

}  // namespace
}  // namespace telex::local
