// SPDX-License-Identifier: MIT
// Bounded randomised mutation (fixed seed) over the parsers, the reassembler and the decoders:
// nothing crashes, every result is either a clean rejection or a canonical message/image.
#include <gtest/gtest.h>

#include <random>

#include "proto_samples.h"
#include "telex/proto/crc32c.h"
#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"

namespace telex::proto {
namespace {

using Bytes = std::vector<std::uint8_t>;

void mutate(Bytes& b, std::mt19937& rng) {
  const int edits = 1 + static_cast<int>(rng() % 4);
  for (int e = 0; e < edits; ++e) {
    const std::uint32_t op = rng() % 6;
    if (b.empty()) {
      b.push_back(static_cast<std::uint8_t>(rng()));
      continue;
    }
    const std::size_t at = rng() % b.size();
    switch (op) {
      case 0:
        b[at] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
        break;
      case 1:
        b[at] = static_cast<std::uint8_t>(rng());
        break;
      case 2:
        b.insert(b.begin() + static_cast<std::ptrdiff_t>(at), static_cast<std::uint8_t>(rng()));
        break;
      case 3:
        b.erase(b.begin() + static_cast<std::ptrdiff_t>(at));
        break;
      case 4:
        b.resize(at);
        break;
      default:
        b[at] = (rng() & 1) ? 0xFF : 0x00;
        break;
    }
  }
}

// Makes a mutated message pass the CRC so validation behind it is exercised too.
void reseal(Bytes& b) {
  if (b.size() < kHeaderSize) return;
  std::fill(b.begin() + 32, b.begin() + 36, 0);
  const std::uint32_t crc = crc32c(b);
  for (int i = 0; i < 4; ++i) b[32 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
}

constexpr int kMutations = 200'000;

TEST(Mutation, MessagesDatagramsAndStreams) {
  std::mt19937 rng(20260101);
  std::vector<Bytes> seeds;
  for (const Message& m : test::sample_messages())
    seeds.push_back(encode(test::sample_header(), m));
  DecodeLimits lim;
  lim.frame_width = 640;
  lim.frame_height = 480;
  DatagramParser d(lim);
  std::uint64_t accepted = 0;
  for (int i = 0; i < kMutations; ++i) {
    Bytes b = seeds[rng() % seeds.size()];
    mutate(b, rng);
    if (rng() % 4 != 0) reseal(b);
    const Result r = d.parse(b);
    if (r.ok()) {
      ++accepted;
      ASSERT_EQ(encode(r.envelope->header, r.envelope->message), b) << "non-canonical accept";
    } else {
      ASSERT_NE(r.detail, nullptr);
    }
    if (i % 8 == 0) {
      // The same bytes, length-prefixed, through a stream parser split at a random point.
      Bytes s(4);
      const auto n = static_cast<std::uint32_t>(b.size());
      for (int k = 0; k < 4; ++k) s[k] = static_cast<std::uint8_t>(n >> (8 * k));
      s.insert(s.end(), b.begin(), b.end());
      if (rng() % 2) mutate(s, rng);
      StreamParser p(lim);
      const std::size_t cut = rng() % (s.size() + 1);
      std::size_t results = 0;
      for (auto part : {std::span(s).first(cut), std::span(s).subspan(cut)}) {
        (void)p.feed(part);
        ASSERT_LE(p.buffered(), p.capacity());
        while (auto r2 = p.next()) ++results;
      }
      (void)p.finish();
      ASSERT_LE(results, 2u);
    }
  }
  EXPECT_EQ(d.messages() + d.drops().total(), static_cast<std::uint64_t>(kMutations));
  EXPECT_GT(accepted, 0u);           // some mutations leave a valid message
  EXPECT_GT(d.drops().total(), 0u);  // and most do not
}

TEST(Mutation, Reassembler) {
  std::mt19937 rng(7);
  ReassemblerLimits lim;
  lim.max_in_flight = 8;
  lim.max_buffered_bytes = 64 * 1024;
  lim.max_message_bytes = 32 * 1024;
  lim.timeout_ns = 5'000;
  Reassembler r(lim);
  Bytes msg(5000);
  for (std::size_t i = 0; i < msg.size(); ++i) msg[i] = static_cast<std::uint8_t>(i * 7);
  std::uint64_t now = 0;
  for (int i = 0; i < kMutations / 5; ++i) {
    auto frags = fragment_message(msg, static_cast<std::uint32_t>(i % 50),
                                  static_cast<std::uint32_t>(i / 10));
    for (auto& f : frags) {
      if (rng() % 3 == 0) mutate(f, rng);
      now += rng() % 100;
      const auto out = r.push(f, now);
      if (out) {
        ASSERT_EQ(out->size(), msg.size());
      }
      ASSERT_LE(r.in_flight(), lim.max_in_flight);
      ASSERT_LE(r.buffered_bytes(), lim.max_buffered_bytes);
    }
  }
  const auto& c = r.counters();
  EXPECT_GT(c.completed, 0u);
  EXPECT_GT(c.malformed, 0u);
}

TEST(Mutation, DepthDecoders) {
  std::mt19937 rng(99);
  std::vector<std::pair<Codec, Bytes>> seeds;
  cv::Mat1w img(24, 32);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      img(y, x) = (x * 7 + y * 3) % 11 == 0 ? 0 : static_cast<std::uint16_t>(900 + x / 3 + y / 2);
  for (Codec c : {Codec::Raw, Codec::Zip, Codec::Fast}) seeds.emplace_back(c, encode_depth(img, c));
  const Bytes rvl = rvl_ref_encode(img);
  std::uint64_t ok = 0;
  cv::Mat1w out;
  for (int i = 0; i < kMutations / 4; ++i) {
    const auto& [codec, seed] = seeds[rng() % seeds.size()];
    Bytes b = seed;
    mutate(b, rng);
    const DecodeStatus st = decode_depth(b, img.cols, img.rows, codec, out);
    if (st == DecodeStatus::Ok) {
      ++ok;
      ASSERT_EQ(out.rows, img.rows);
      ASSERT_EQ(out.cols, img.cols);
    }
    Bytes rb = rvl;
    mutate(rb, rng);
    (void)rvl_ref_decode(rb, img.cols, img.rows, out);
  }
  EXPECT_GT(ok, 0u);  // raw tiles survive byte flips; the check above still ran
}

}  // namespace
}  // namespace telex::proto
