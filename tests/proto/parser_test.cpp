// SPDX-License-Identifier: MIT
// Stream and datagram parsers: every split point, every error reason, bounded buffering.
#include "telex/proto/parser.h"

#include <gtest/gtest.h>

#include "proto_samples.h"
#include "telex/proto/crc32c.h"

namespace telex::proto {
namespace {

std::vector<std::uint8_t> sample_stream() {
  std::vector<std::uint8_t> s;
  std::uint32_t seq = 0;
  for (const Message& m : test::sample_messages()) {
    const auto b = encode_stream(test::sample_header(seq++), m);
    s.insert(s.end(), b.begin(), b.end());
  }
  return s;
}

// Feeds `bytes` in pieces of the given sizes (cycled), draining after each, and collects results.
std::vector<Result> run(StreamParser& p, std::span<const std::uint8_t> bytes,
                        std::vector<std::size_t> pieces) {
  std::vector<Result> out;
  std::size_t pos = 0, k = 0;
  while (pos < bytes.size()) {
    std::size_t n = std::min(pieces[k++ % pieces.size()], bytes.size() - pos);
    while (n > 0) {
      const std::size_t took = p.feed(bytes.subspan(pos, n));
      pos += took;
      n -= took;
      while (auto r = p.next()) out.push_back(std::move(*r));
      if (took == 0) {
        // Drained and still no room: only a failed parser refuses bytes.
        EXPECT_TRUE(p.failed());
        return out;
      }
    }
  }
  while (auto r = p.next()) out.push_back(std::move(*r));
  return out;
}

TEST(StreamParser, SplitAtEveryByteBoundaryYieldsTheSameMessages) {
  const auto stream = sample_stream();
  const auto expected = test::sample_messages();
  for (std::size_t cut = 0; cut <= stream.size(); ++cut) {
    StreamParser p;
    std::vector<Result> got;
    for (auto part : {std::span(stream).first(cut), std::span(stream).subspan(cut)}) {
      ASSERT_EQ(p.feed(part), part.size());
      while (auto r = p.next()) got.push_back(std::move(*r));
    }
    ASSERT_EQ(got.size(), expected.size()) << "cut at " << cut;
    for (std::size_t i = 0; i < got.size(); ++i) {
      ASSERT_TRUE(got[i].ok()) << "cut " << cut << " msg " << i << ": "
                               << error_reason_name(got[i].error);
      EXPECT_EQ(got[i].envelope->message, expected[i]);
      EXPECT_EQ(got[i].envelope->header.seq, i);
    }
    EXPECT_FALSE(p.finish().has_value());
  }
}

TEST(StreamParser, ByteByByteAndOddChunks) {
  const auto stream = sample_stream();
  for (std::vector<std::size_t> pieces :
       {std::vector<std::size_t>{1}, {2, 3, 5, 7}, {13}, {64, 1}, {stream.size()}}) {
    StreamParser p;
    const auto got = run(p, stream, pieces);
    ASSERT_EQ(got.size(), test::sample_messages().size());
    for (const auto& r : got) EXPECT_TRUE(r.ok());
    EXPECT_EQ(p.messages(), got.size());
    EXPECT_EQ(p.drops().total(), 0u);
  }
}

TEST(StreamParser, BufferNeverExceedsItsBound) {
  DecodeLimits lim;
  lim.max_message_bytes = 256;
  StreamParser p(lim);
  EXPECT_EQ(p.capacity(), 4u + 256u);
  // Many small messages in one large feed: feed takes only what fits, the rest after draining.
  std::vector<std::uint8_t> stream;
  for (int i = 0; i < 100; ++i) {
    const auto b = encode_stream(test::sample_header(i), Heartbeat{1, 2, 3, 4});
    stream.insert(stream.end(), b.begin(), b.end());
  }
  std::size_t pos = 0;
  int messages = 0;
  while (pos < stream.size()) {
    pos += p.feed(std::span(stream).subspan(pos));
    EXPECT_LE(p.buffered(), p.capacity());
    while (auto r = p.next()) {
      ASSERT_TRUE(r->ok());
      ++messages;
    }
  }
  EXPECT_EQ(messages, 100);
}

TEST(StreamParser, FramingErrorsAreFatalTheCallerCloses) {
  auto stream = encode_stream(test::sample_header(), Bye{});
  stream[4] = 'Q';  // magic
  const auto good = encode_stream(test::sample_header(), Bye{});
  stream.insert(stream.end(), good.begin(), good.end());
  StreamParser p;
  ASSERT_EQ(p.feed(stream), stream.size());
  auto r = p.next();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->error, ErrorReason::BadMagic);
  EXPECT_TRUE(p.failed());
  EXPECT_FALSE(p.next());
  EXPECT_EQ(p.feed(good), 0u);
  EXPECT_EQ(p.drops().of(ErrorReason::BadMagic), 1u);
}

TEST(StreamParser, LengthPrefixBeyondBoundIsBadLength) {
  DecodeLimits lim;
  lim.max_message_bytes = 100;
  StreamParser p(lim);
  const std::uint8_t huge[] = {0xFF, 0xFF, 0xFF, 0x7F};
  ASSERT_EQ(p.feed(huge), 4u);
  auto r = p.next();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->error, ErrorReason::BadLength);
  EXPECT_TRUE(p.failed());
  // A prefix shorter than a header is as bad.
  StreamParser q;
  const std::uint8_t tiny[] = {3, 0, 0, 0};
  ASSERT_EQ(q.feed(tiny), 4u);
  EXPECT_EQ(q.next()->error, ErrorReason::BadLength);
}

TEST(StreamParser, PrefixDisagreeingWithHeaderIsBadLength) {
  auto s = encode_stream(test::sample_header(), Heartbeat{});
  s[0] += 1;  // prefix one larger than the message
  s.push_back(0);
  StreamParser p;
  ASSERT_EQ(p.feed(s), s.size());
  EXPECT_EQ(p.next()->error, ErrorReason::BadLength);
}

TEST(StreamParser, ChecksumErrorIsFatal) {
  auto s = encode_stream(test::sample_header(), Heartbeat{1, 2, 3, 4});
  s.back() ^= 1;
  StreamParser p;
  ASSERT_EQ(p.feed(s), s.size());
  EXPECT_EQ(p.next()->error, ErrorReason::BadChecksum);
  EXPECT_TRUE(p.failed());
}

// Rewrites a field inside a framed message and reseals its CRC, so the content check decides.
std::vector<std::uint8_t> edited(Message m, std::size_t offset, std::uint8_t value) {
  auto s = encode_stream(test::sample_header(), m);
  s[4 + offset] = value;
  for (int i = 0; i < 4; ++i) s[4 + 32 + i] = 0;
  const std::uint32_t crc = crc32c(std::span(s).subspan(4));
  for (int i = 0; i < 4; ++i) s[4 + 32 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  return s;
}

TEST(StreamParser, ContentErrorsSkipTheMessageAndContinue) {
  std::vector<std::pair<std::vector<std::uint8_t>, ErrorReason>> cases = {
      {edited(Bye{}, 4, 9), ErrorReason::BadVersion},
      {edited(Bye{}, 5, 200), ErrorReason::UnknownType},
      {edited(Accept{1, Codec::Zip, Transport::Tcp, 0}, kHeaderSize + 5, 7),
       ErrorReason::BadPayload},
      {encode_stream({}, DepthTile{0, 0, 0, 0, 1, Codec::Zip, {1}}), ErrorReason::BadTileGeometry},
      {encode_stream({}, DepthTile{0, 0, 0, 2000, 2000, Codec::Zip, {1}}),
       ErrorReason::DecompressionBomb},
  };
  for (const auto& [bad, reason] : cases) {
    std::vector<std::uint8_t> s = bad;
    const auto good = encode_stream(test::sample_header(), Bye{3});
    s.insert(s.end(), good.begin(), good.end());
    StreamParser p;
    const auto got = run(p, s, {1});
    ASSERT_EQ(got.size(), 2u) << error_reason_name(reason);
    EXPECT_EQ(got[0].error, reason);
    ASSERT_TRUE(got[1].ok()) << error_reason_name(reason);
    EXPECT_EQ(std::get<Bye>(got[1].envelope->message).reason, 3);
    EXPECT_FALSE(p.failed());
    EXPECT_EQ(p.drops().of(reason), 1u);
  }
}

TEST(StreamParser, FrameSizeChecksTiles) {
  StreamParser p;
  p.set_frame_size(640, 480);
  const auto s = encode_stream({}, DepthTile{0, 600, 0, 80, 60, Codec::Zip, {1}});
  ASSERT_EQ(p.feed(s), s.size());
  EXPECT_EQ(p.next()->error, ErrorReason::BadTileGeometry);
}

TEST(StreamParser, EndOfStreamInsideAMessageIsTruncated) {
  const auto s = encode_stream(test::sample_header(), Heartbeat{});
  StreamParser p;
  ASSERT_EQ(p.feed(std::span(s).first(s.size() - 3)), s.size() - 3);
  EXPECT_FALSE(p.next());
  auto r = p.finish();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->error, ErrorReason::Truncated);
  EXPECT_EQ(p.drops().of(ErrorReason::Truncated), 1u);
}

TEST(DatagramParser, ParsesAndCountsDropsPerReason) {
  DatagramParser d;
  for (const Message& m : test::sample_messages()) {
    const auto b = encode(test::sample_header(), m);
    const Result r = d.parse(b);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r.envelope->message, m);
  }
  auto b = encode(test::sample_header(), Bye{});
  EXPECT_EQ(d.parse(std::span(b).first(10)).error, ErrorReason::Truncated);
  b[0] = 0;
  EXPECT_EQ(d.parse(b).error, ErrorReason::BadMagic);
  b = encode(test::sample_header(), Bye{});
  b.back() ^= 0xFF;
  EXPECT_EQ(d.parse(b).error, ErrorReason::BadChecksum);
  EXPECT_EQ(d.messages(), test::sample_messages().size());
  EXPECT_EQ(d.drops().of(ErrorReason::Truncated), 1u);
  EXPECT_EQ(d.drops().of(ErrorReason::BadMagic), 1u);
  EXPECT_EQ(d.drops().of(ErrorReason::BadChecksum), 1u);
  EXPECT_EQ(d.drops().total(), 3u);
}

}  // namespace
}  // namespace telex::proto
