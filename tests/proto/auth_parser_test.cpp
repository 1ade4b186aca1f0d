// SPDX-License-Identifier: MIT
// Parsers with a pre-shared key: tagged framing at every split point, tag failures, missing and
// unexpected tags, replays, session keys, and tagged UDP datagrams through the reassembler.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "process.h"
#include "proto_samples.h"
#include "telex/proto/auth.h"
#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"

namespace telex::proto {
namespace {

AuthKey key_of(std::uint8_t fill) { return AuthKey(std::vector<std::uint8_t>(32, fill)); }

std::vector<std::uint8_t> sealed_stream(const AuthKey* key, std::uint32_t first_seq = 0) {
  std::vector<std::uint8_t> s;
  std::uint32_t seq = first_seq;
  for (const Message& m : test::sample_messages()) {
    const auto b = encode_stream_sealed(test::sample_header(seq++), m, key);
    s.insert(s.end(), b.begin(), b.end());
  }
  return s;
}

std::vector<Result> feed_all(StreamParser& p, std::span<const std::uint8_t> bytes) {
  std::vector<Result> out;
  while (!bytes.empty()) {
    const std::size_t took = p.feed(bytes);
    bytes = bytes.subspan(took);
    while (auto r = p.next()) out.push_back(std::move(*r));
    if (took == 0) break;
  }
  while (auto r = p.next()) out.push_back(std::move(*r));
  return out;
}

TEST(AuthStreamParser, TaggedMessageIsSixteenBytesLongerAndFlagged) {
  const auto key = key_of(1);
  const Message m = test::sample_messages().front();
  const auto plain = encode_stream(test::sample_header(1), m);
  const auto tagged = encode_stream_sealed(test::sample_header(1), m, &key);
  ASSERT_EQ(tagged.size(), plain.size() + kAuthTagBytes);
  Header h;
  ASSERT_FALSE(decode_header(std::span(tagged).subspan(4, kHeaderSize), h).has_value());
  EXPECT_NE(h.flags & kFlagAuth, 0);
  // The length prefix counts the tag; payload_len does not.
  EXPECT_EQ(tagged[0] | (tagged[1] << 8), static_cast<int>(kHeaderSize + h.payload_len + 16));
}

TEST(AuthStreamParser, SplitAtEveryByteBoundaryYieldsEveryMessageOnce) {
  const auto key = key_of(2);
  const auto stream = sealed_stream(&key);
  const auto expected = test::sample_messages();
  for (std::size_t cut = 0; cut <= stream.size(); ++cut) {
    StreamParser p;
    p.set_key(key);
    std::vector<Result> got;
    for (auto part : {std::span(stream).first(cut), std::span(stream).subspan(cut)}) {
      ASSERT_EQ(p.feed(part), part.size());
      while (auto r = p.next()) got.push_back(std::move(*r));
    }
    ASSERT_EQ(got.size(), expected.size()) << "cut at " << cut;
    for (std::size_t i = 0; i < got.size(); ++i) {
      ASSERT_TRUE(got[i].ok()) << "cut " << cut << " msg " << i << ": "
                               << error_reason_name(got[i].error) << " " << got[i].detail;
      EXPECT_EQ(got[i].envelope->message, expected[i]);
    }
    EXPECT_EQ(p.drops().total(), 0u);
    EXPECT_EQ(p.buffered(), 0u);
  }
}

TEST(AuthStreamParser, OneByteAtATimeWorksToo) {
  const auto key = key_of(3);
  const auto stream = sealed_stream(&key);
  StreamParser p;
  p.set_key(key);
  std::size_t ok = 0;
  for (std::uint8_t b : stream) {
    ASSERT_EQ(p.feed({&b, 1}), 1u);
    while (auto r = p.next()) ok += r->ok() ? 1 : 0;
  }
  EXPECT_EQ(ok, test::sample_messages().size());
}

// Every byte of one message's header (except magic and payload_len, which the framing checks
// first), payload and tag: the message is dropped as AuthFailed, its neighbours survive and the
// parser keeps going.
TEST(AuthStreamParser, AnyChangedByteDropsOnlyThatMessage) {
  const auto key = key_of(4);
  const auto msgs = test::sample_messages();
  const auto first = encode_stream_sealed(test::sample_header(0), msgs[0], &key);
  const auto victim = encode_stream_sealed(test::sample_header(1), msgs[1], &key);
  const auto last = encode_stream_sealed(test::sample_header(2), msgs[2], &key);
  for (std::size_t i = 4; i < victim.size(); ++i) {
    const std::size_t in_header = i - 4;
    if (in_header < 4 || (in_header >= 28 && in_header < 32)) continue;
    auto bad = victim;
    bad[i] ^= 0x40;
    std::vector<std::uint8_t> s(first);
    s.insert(s.end(), bad.begin(), bad.end());
    s.insert(s.end(), last.begin(), last.end());
    StreamParser p;
    p.set_key(key);
    const auto got = feed_all(p, s);
    ASSERT_EQ(got.size(), 3u) << "byte " << i;
    EXPECT_TRUE(got[0].ok());
    EXPECT_FALSE(got[1].ok()) << "byte " << i;
    EXPECT_TRUE(got[2].ok()) << "byte " << i;
    EXPECT_FALSE(p.failed());
    // Magic and version bytes fail the tag too: the tag is checked before anything else.
    EXPECT_EQ(p.drops().of(ErrorReason::AuthFailed), 1u) << "byte " << i;
  }
}

TEST(AuthStreamParser, FlippedAuthFlagBreaksTheFramingAndIsFatal) {
  const auto key = key_of(5);
  auto s = encode_stream_sealed(test::sample_header(0), test::sample_messages()[0], &key);
  s[4 + 6] ^= static_cast<std::uint8_t>(kFlagAuth);
  StreamParser p;
  p.set_key(key);
  const auto got = feed_all(p, s);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].error, ErrorReason::BadLength);
  EXPECT_TRUE(p.failed());
}

TEST(AuthStreamParser, MissingTagWrongKeyAndUnexpectedTagAreNamedAndNotFatal) {
  const auto key = key_of(6), other = key_of(7);
  const Message m = test::sample_messages()[0];
  {
    StreamParser p;  // keyed, plain message
    p.set_key(key);
    const auto got = feed_all(p, encode_stream(test::sample_header(0), m));
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(got[0].error, ErrorReason::AuthFailed);
    EXPECT_STREQ(got[0].detail, "message has no tag");
    EXPECT_FALSE(p.failed());
  }
  {
    StreamParser p;  // keyed, other key
    p.set_key(key);
    const auto got = feed_all(p, encode_stream_sealed(test::sample_header(0), m, &other));
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(got[0].error, ErrorReason::AuthFailed);
    EXPECT_STREQ(got[0].detail, "tag does not verify");
  }
  {
    StreamParser p;  // no key, tagged message
    auto s = encode_stream_sealed(test::sample_header(0), m, &key);
    const auto plain = encode_stream(test::sample_header(1), m);
    s.insert(s.end(), plain.begin(), plain.end());
    const auto got = feed_all(p, s);
    ASSERT_EQ(got.size(), 2u);
    EXPECT_EQ(got[0].error, ErrorReason::UnexpectedTag);
    EXPECT_TRUE(got[1].ok());
    EXPECT_EQ(p.drops().of(ErrorReason::UnexpectedTag), 1u);
  }
}

TEST(AuthStreamParser, ReplayedMessagesAreDroppedAndFreshOnesPass) {
  const auto key = key_of(8);
  const Message m = test::sample_messages()[0];
  std::vector<std::uint8_t> s;
  for (std::uint32_t seq : {10u, 11u, 10u, 13u, 12u, 12u, 11u}) {
    const auto b = encode_stream_sealed(test::sample_header(seq), m, &key);
    s.insert(s.end(), b.begin(), b.end());
  }
  StreamParser p;
  p.set_key(key);
  const auto got = feed_all(p, s);
  ASSERT_EQ(got.size(), 7u);
  const bool expect_ok[] = {true, true, false, true, true, false, false};
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].ok(), expect_ok[i]) << i;
    if (!expect_ok[i]) {
      EXPECT_EQ(got[i].error, ErrorReason::Replayed) << i;
    }
  }
  EXPECT_EQ(p.drops().of(ErrorReason::Replayed), 3u);
  EXPECT_EQ(p.messages(), 4u);
}

TEST(AuthStreamParser, OlderThanTheWindowIsReplayedAndANewKeyStartsAFreshWindow) {
  const auto key = key_of(9);
  const Message m = test::sample_messages()[0];
  StreamParser p;
  p.set_key(key);
  auto got = feed_all(p, encode_stream_sealed(test::sample_header(5000), m, &key));
  ASSERT_TRUE(got.at(0).ok());
  got = feed_all(p, encode_stream_sealed(test::sample_header(5000 - 1024), m, &key));
  EXPECT_EQ(got.at(0).error, ErrorReason::Replayed);
  EXPECT_STREQ(got.at(0).detail, "sequence number older than the replay window");
  p.set_key(key);  // a new session: sequence numbers start again
  got = feed_all(p, encode_stream_sealed(test::sample_header(0), m, &key));
  EXPECT_TRUE(got.at(0).ok());
}

TEST(AuthStreamParser, BoundAppliesToHeaderAndPayloadNotTheTag) {
  const auto key = key_of(10);
  proto::DepthTile t;
  t.w = 8;
  t.h = 8;
  t.codec = Codec::Raw;
  t.payload.assign(8 * 8 * 2, 1);
  const auto plain = encode(test::sample_header(0), t);
  DecodeLimits lim;
  lim.max_message_bytes = plain.size();  // exactly at the bound
  StreamParser p(lim);
  p.set_key(key);
  const auto got = feed_all(p, encode_stream_sealed(test::sample_header(0), t, &key));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_TRUE(got[0].ok()) << error_reason_name(got[0].error);
  EXPECT_EQ(p.capacity(), 4 + plain.size() + kAuthTagBytes);
}

TEST(AuthDatagramParser, TagsMissingTagsReplaysAndUnexpectedTags) {
  const auto key = key_of(11), other = key_of(12);
  const Message m = test::sample_messages()[0];
  DatagramParser d;
  d.set_key(key);
  EXPECT_TRUE(d.parse(encode_sealed(test::sample_header(1), m, &key)).ok());
  EXPECT_EQ(d.parse(encode_sealed(test::sample_header(1), m, &key)).error, ErrorReason::Replayed);
  EXPECT_EQ(d.parse(encode_sealed(test::sample_header(2), m, &other)).error,
            ErrorReason::AuthFailed);
  EXPECT_EQ(d.parse(encode(test::sample_header(3), m)).error, ErrorReason::AuthFailed);
  auto cut = encode_sealed(test::sample_header(4), m, &key);
  cut.pop_back();
  EXPECT_EQ(d.parse(cut).error, ErrorReason::AuthFailed);
  EXPECT_EQ(d.parse(std::vector<std::uint8_t>(10, 0)).error, ErrorReason::Truncated);
  EXPECT_TRUE(d.parse(encode_sealed(test::sample_header(4), m, &key)).ok());
  EXPECT_EQ(d.drops().of(ErrorReason::AuthFailed), 3u);
  EXPECT_EQ(d.drops().of(ErrorReason::Replayed), 1u);
  DatagramParser plain;
  EXPECT_EQ(plain.parse(encode_sealed(test::sample_header(1), m, &key)).error,
            ErrorReason::UnexpectedTag);
}

TEST(AuthSessionKey, DependsOnBothNoncesAndTheSessionAndDiffersFromThePsk) {
  const auto psk = key_of(13);
  const auto k = derive_session_key(psk, 1, 2, 3);
  EXPECT_EQ(k.bytes().size(), 32u);
  const auto same = derive_session_key(psk, 1, 2, 3);
  EXPECT_TRUE(std::equal(k.bytes().begin(), k.bytes().end(), same.bytes().begin()));
  for (const auto& o : {derive_session_key(psk, 9, 2, 3), derive_session_key(psk, 1, 9, 3),
                        derive_session_key(psk, 1, 2, 9), derive_session_key(key_of(14), 1, 2, 3)})
    EXPECT_FALSE(std::equal(k.bytes().begin(), k.bytes().end(), o.bytes().begin()));
  // A message recorded under one session's key does not verify in another session.
  const auto msg = encode_sealed(test::sample_header(1), test::sample_messages()[0], &k);
  DatagramParser d;
  d.set_key(derive_session_key(psk, 1, 2, 4));
  EXPECT_EQ(d.parse(msg).error, ErrorReason::AuthFailed);
  d.set_key(psk);
  EXPECT_EQ(d.parse(msg).error, ErrorReason::AuthFailed);
}

// The UDP path as the daemons run it: message tag, fragments, a tag per datagram; forged
// fragments are rejected before the reassembler, so they cannot spoil the real message.
TEST(AuthDatagrams, TaggedFragmentsReassembleAndForgedOnesNeverReachTheReassembler) {
  const auto key = key_of(15);
  proto::DepthTile t;
  t.w = 80;
  t.h = 60;
  t.codec = Codec::Raw;
  t.payload.assign(80 * 60 * 2, 7);
  const auto msg = encode_sealed(test::sample_header(1), t, &key);
  auto frags = fragment_message(msg, 1, 1);
  ASSERT_GT(frags.size(), 3u);
  for (auto& f : frags) append_tag(f, key);
  Reassembler r;
  DatagramParser d;
  d.set_key(key);
  std::optional<std::vector<std::uint8_t>> whole;
  std::size_t forged_rejected = 0;
  for (std::size_t i = 0; i < frags.size(); ++i) {
    // A forgery for the same message id and index, first.
    auto forged = frags[i];
    forged[kFragmentHeaderSize + 3] ^= 1;
    if (!verify_and_strip(forged, key)) ++forged_rejected;
    const auto body = verify_and_strip(frags[i], key);
    ASSERT_TRUE(body.has_value()) << i;
    if (auto w = r.push(*body, 0)) whole = std::move(w);
  }
  EXPECT_EQ(forged_rejected, frags.size());
  ASSERT_TRUE(whole.has_value());
  const auto res = d.parse(*whole);
  ASSERT_TRUE(res.ok()) << error_reason_name(res.error);
  EXPECT_EQ(std::get<DepthTile>(res.envelope->message), t);
  EXPECT_LE(frags.front().size(), kMaxDatagramBytes + kAuthTagBytes);
}

TEST(AuthKeyFile, PermissionsOpenToOthersAreRefusedWithTheFix) {
  const auto dir = ::telex::test::scratch_dir("psk_perm");
  std::filesystem::create_directories(dir);
  const auto path = dir / "key";
  { std::ofstream(path, std::ios::binary) << std::string(32, 'k'); }
  std::filesystem::permissions(path, std::filesystem::perms::owner_read |
                                         std::filesystem::perms::owner_write |
                                         std::filesystem::perms::group_read);
  try {
    check_key_file_permissions(path);
    ADD_FAILURE() << "mode 0640 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("chmod 600"), std::string::npos) << e.what();
  }
  std::filesystem::permissions(path, std::filesystem::perms::owner_read);
  EXPECT_NO_THROW(check_key_file_permissions(path));
  EXPECT_THROW(check_key_file_permissions(dir / "absent"), std::runtime_error);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace telex::proto
