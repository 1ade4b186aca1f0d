// SPDX-License-Identifier: MIT
// The remote's cache of sent tiles that answers TileNack (docs/PROTOCOL.md 2.5).
#include "telex/remote/repair_cache.h"

#include <gtest/gtest.h>

namespace telex::remote {
namespace {

cv::Mat1w level(std::uint16_t mm) { return cv::Mat1w(30, 40, mm); }

std::vector<proto::EncodedTile> encoded(const cv::Mat1w& frame) {
  return proto::encode_tiles(frame, proto::TileGrid{40, 30, 20, 15}, proto::Codec::Zip);
}

TEST(RepairCache, AnswersWithTheNewestCopyFromTheAskedFrameOnAndCountsWhatIsGone) {
  RepairCache cache(3);
  const auto t1000 = encoded(level(1000)), t1200 = encoded(level(1200));
  cache.add(10, 100, proto::Codec::Zip, {t1000[0], t1000[1], t1000[2], t1000[3]});
  cache.add(11, 110, proto::Codec::Zip, {t1200[1]});
  cache.add(11, 110, proto::Codec::Zip, {t1200[2]});  // the rest of frame 11 joins its entry
  cache.add(12, 120, proto::Codec::Zip, {t1000[3]});
  EXPECT_EQ(cache.frames(), 3u);
  const auto a = cache.answer(proto::TileNack{10, {0, 1, 3}});
  ASSERT_EQ(a.resend.size(), 3u);
  EXPECT_EQ(a.resend[0].frame_id, 10u);  // tile 0 changed only in frame 10
  EXPECT_EQ(a.resend[1].frame_id, 11u);  // tile 1's newest copy
  EXPECT_EQ(a.resend[1].capture_ns, 110);
  EXPECT_EQ(a.resend[1].tile->bytes, t1200[1].bytes);
  EXPECT_EQ(a.resend[2].frame_id, 12u);
  EXPECT_TRUE(a.unavailable.empty());
  // Frame 13 evicts frame 10: tile 0 from frame 10 on is gone; from 11 on tile 0 was never sent.
  cache.add(13, 130, proto::Codec::Zip, {t1000[1]});
  auto b = cache.answer(proto::TileNack{10, {0, 2}});
  EXPECT_EQ(b.unavailable, std::vector<std::uint16_t>{0});
  ASSERT_EQ(b.resend.size(), 1u);
  EXPECT_EQ(b.resend[0].frame_id, 11u);
  // Frame ids wrap (RFC 1982): 0xFFFFFFFF is before 0.
  RepairCache wrap(4);
  wrap.add(0xFFFFFFFFu, 1, proto::Codec::Zip, {t1000[0]});
  wrap.add(0, 2, proto::Codec::Zip, {t1200[0]});
  auto c = wrap.answer(proto::TileNack{0xFFFFFFFFu, {0}});
  ASSERT_EQ(c.resend.size(), 1u);
  EXPECT_EQ(c.resend[0].frame_id, 0u);
}

TEST(RepairLimiter, ATileIsResentOncePerDedupIntervalAndFrame) {
  RepairLimiter lim({.dedup_ns = 10'000'000, .bytes_per_s = 1e9, .burst_bytes = 1e9});
  using V = RepairLimiter::Verdict;
  EXPECT_EQ(lim.admit(5, 100, 1000, 0), V::Send);
  EXPECT_EQ(lim.admit(5, 100, 1000, 9'999'999), V::Duplicate);  // a storm of the same NACK
  EXPECT_EQ(lim.admit(6, 100, 1000, 9'999'999), V::Send);       // another tile
  EXPECT_EQ(lim.admit(5, 101, 1000, 9'999'999), V::Send);       // a newer copy of the tile
  EXPECT_EQ(lim.admit(5, 101, 1000, 25'000'000), V::Send);      // the station's retry, 25 ms on
  EXPECT_EQ(lim.admit(4095, 7, 10, 0), V::Send);                // the largest tile index
}

TEST(RepairLimiter, ResentBytesStayWithinBurstPlusRateTimesTime) {
  const RepairLimiter::Config cfg{.dedup_ns = 0, .bytes_per_s = 1e6, .burst_bytes = 100'000};
  RepairLimiter lim(cfg);
  // A NACK storm: 2000 tiles of 1 kB asked every millisecond for one second (2 GB/s asked).
  std::uint64_t sent = 0, over = 0;
  for (std::int64_t ms = 0; ms <= 1000; ++ms)
    for (std::uint16_t t = 0; t < 2000; ++t) {
      if (lim.admit(t, static_cast<std::uint32_t>(ms), 1000, ms * 1'000'000) ==
          RepairLimiter::Verdict::Send)
        ++sent;
      else
        ++over;
    }
  const double bound = cfg.burst_bytes + cfg.bytes_per_s * 1.0;
  EXPECT_LE(static_cast<double>(sent) * 1000.0, bound);
  EXPECT_GE(static_cast<double>(sent) * 1000.0, 0.99 * bound - 1000.0);  // the budget is used
  EXPECT_GT(over, 0u);
}

}  // namespace
}  // namespace telex::remote
