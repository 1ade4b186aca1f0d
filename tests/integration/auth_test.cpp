// SPDX-License-Identifier: MIT
// Tests for message authentication: RFC 4231 vector, tampering, wrong keys, key files, replays.
#include "telex/proto/auth.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>

#include "process.h"
#include "telex/proto/messages.h"

namespace telex::proto {
namespace {

std::vector<std::uint8_t> bytes_of(std::string_view s) { return {s.begin(), s.end()}; }

AuthKey key_of(std::uint8_t fill, std::size_t n = 32) {
  return AuthKey(std::vector<std::uint8_t>(n, fill));
}

std::vector<std::uint8_t> sample_message(std::uint32_t seq) {
  Header h;
  h.session_id = 0xC0FFEE;
  h.seq = seq;
  h.frame_id = 7;
  h.capture_ns = 123456789;
  DepthTile t;
  t.tile_index = 3;
  t.x = 80;
  t.y = 0;
  t.w = 80;
  t.h = 60;
  t.codec = Codec::Raw;
  t.payload.assign(80 * 60 * 2, 0x5A);
  return encode(h, t);
}

TEST(Auth, MatchesRfc4231TestCase1Truncated) {
  // RFC 4231 4.2: key = 20 x 0x0b, data = "Hi There".
  const AuthKey key(std::vector<std::uint8_t>(20, 0x0b));
  const auto tag = compute_tag(bytes_of("Hi There"), key);
  const std::array<std::uint8_t, 16> expected{0xb0, 0x34, 0x4c, 0x61, 0xd8, 0xdb, 0x38, 0x53,
                                              0x5c, 0xa8, 0xaf, 0xce, 0xaf, 0x0b, 0xf1, 0x2b};
  EXPECT_EQ(tag, expected);
}

TEST(Auth, RoundTripStripsExactlyTheTag) {
  const auto key = key_of(0x11);
  const auto msg = sample_message(1);
  auto tagged = msg;
  append_tag(tagged, key);
  ASSERT_EQ(tagged.size(), msg.size() + kAuthTagBytes);
  const auto body = verify_and_strip(tagged, key);
  ASSERT_TRUE(body.has_value());
  EXPECT_TRUE(std::equal(body->begin(), body->end(), msg.begin(), msg.end()));
  // The stripped bytes still decode as the original message.
  EXPECT_TRUE(decode(*body).ok());
}

TEST(Auth, FlippingAnyBitOfHeaderPayloadOrTagFails) {
  const auto key = key_of(0x22);
  auto tagged = sample_message(2);
  tagged.resize(kHeaderSize + 40);  // keep the exhaustive loop small; coverage is the point
  append_tag(tagged, key);
  for (std::size_t i = 0; i < tagged.size(); ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      auto bad = tagged;
      bad[i] ^= static_cast<std::uint8_t>(1u << bit);
      EXPECT_FALSE(verify_and_strip(bad, key).has_value()) << "byte " << i << " bit " << bit;
    }
  }
  EXPECT_TRUE(verify_and_strip(tagged, key).has_value());
}

TEST(Auth, TruncatedExtendedAndTagMovedFail) {
  const auto key = key_of(0x23);
  auto tagged = sample_message(3);
  append_tag(tagged, key);
  for (std::size_t cut :
       {std::size_t{1}, std::size_t{15}, std::size_t{16}, tagged.size() - 1, tagged.size()}) {
    const std::span<const std::uint8_t> s(tagged.data(), tagged.size() - cut);
    EXPECT_FALSE(verify_and_strip(s, key).has_value()) << "cut " << cut;
  }
  auto longer = tagged;
  longer.push_back(0);
  EXPECT_FALSE(verify_and_strip(longer, key).has_value());
  EXPECT_FALSE(verify_and_strip({}, key).has_value());
}

TEST(Auth, WrongKeyFailsIncludingOneBitDifferentKey) {
  const auto key = key_of(0x33);
  auto tagged = sample_message(4);
  append_tag(tagged, key);
  EXPECT_FALSE(verify_and_strip(tagged, key_of(0x34)).has_value());
  std::vector<std::uint8_t> k(32, 0x33);
  k[31] ^= 0x80;
  EXPECT_FALSE(verify_and_strip(tagged, AuthKey(k)).has_value());
  // A key that is a prefix of the real one is a different key.
  EXPECT_FALSE(verify_and_strip(tagged, key_of(0x33, 31)).has_value());
}

TEST(Auth, RandomForgeriesNeverVerify) {
  const auto key = key_of(0x44);
  std::mt19937 rng(42);
  std::size_t accepted = 0;
  for (int i = 0; i < 2000; ++i) {
    std::vector<std::uint8_t> m(kHeaderSize + 16 + rng() % 200);
    for (auto& b : m) b = static_cast<std::uint8_t>(rng());
    accepted += verify_and_strip(m, key).has_value();
  }
  EXPECT_EQ(accepted, 0u);
}

TEST(Auth, KeyLengthBounds) {
  EXPECT_THROW(AuthKey(std::vector<std::uint8_t>(15, 1)), std::invalid_argument);
  EXPECT_NO_THROW(AuthKey(std::vector<std::uint8_t>(16, 1)));
  EXPECT_THROW(AuthKey(std::vector<std::uint8_t>(kMaxKeyBytes + 1, 1)), std::invalid_argument);
}

class KeyFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::telex::test::scratch_dir("auth");
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path write(const std::string& name, const std::string& content) {
    const auto p = dir_ / name;
    std::ofstream(p, std::ios::binary) << content;
    return p;
  }
  std::filesystem::path dir_;
};

TEST_F(KeyFile, LoadsRawBytesAndDropsOneTrailingNewline) {
  const std::string hex = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
  const auto with_nl = load_key_file(write("a", hex + "\n"));
  const auto without = load_key_file(write("b", hex));
  const auto crlf = load_key_file(write("c", hex + "\r\n"));
  EXPECT_EQ(with_nl.bytes().size(), 64u);
  EXPECT_TRUE(std::ranges::equal(with_nl.bytes(), without.bytes()));
  EXPECT_TRUE(std::ranges::equal(crlf.bytes(), without.bytes()));
  std::string binary(32, '\0');
  for (int i = 0; i < 32; ++i) binary[i] = static_cast<char>(i * 7);
  EXPECT_EQ(load_key_file(write("d", binary)).bytes().size(), 32u);
}

TEST_F(KeyFile, ErrorsNameTheFile) {
  try {
    load_key_file(dir_ / "missing.key");
    FAIL() << "no throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.key"), std::string::npos) << e.what();
  }
  const auto short_key = write("short.key", "tooshort\n");
  try {
    load_key_file(short_key);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("short.key"), std::string::npos) << what;
    EXPECT_NE(what.find("at least 16"), std::string::npos) << what;
  }
  EXPECT_THROW(load_key_file(write("empty.key", "")), std::invalid_argument);
  EXPECT_THROW(load_key_file(dir_), std::exception);  // a directory is not a key
}

using Verdict = ReplayWindow::Verdict;

TEST(ReplayWindow, RejectsExactReplays) {
  ReplayWindow w;
  for (std::uint64_t s = 100; s < 200; ++s) EXPECT_EQ(w.check_and_update(s), Verdict::Accepted);
  for (std::uint64_t s = 100; s < 200; ++s) EXPECT_EQ(w.check_and_update(s), Verdict::Replayed);
  EXPECT_EQ(w.highest(), 199u);
}

TEST(ReplayWindow, AcceptsReorderingWithinTheWindowOnce) {
  ReplayWindow w;
  // Deliver 0..4095 in a seeded shuffle within blocks of 512 (well inside the window).
  std::mt19937 rng(7);
  std::vector<std::uint64_t> order;
  for (std::uint64_t base = 0; base < 4096; base += 512) {
    std::vector<std::uint64_t> block(512);
    for (std::uint64_t i = 0; i < 512; ++i) block[i] = base + i;
    std::shuffle(block.begin(), block.end(), rng);
    order.insert(order.end(), block.begin(), block.end());
  }
  for (auto s : order) EXPECT_EQ(w.check_and_update(s), Verdict::Accepted) << s;
  for (auto s : order) EXPECT_NE(w.check_and_update(s), Verdict::Accepted) << s;
}

TEST(ReplayWindow, TooOldAndEdgeOfWindow) {
  ReplayWindow w;
  EXPECT_EQ(w.check_and_update(5000), Verdict::Accepted);
  const std::uint64_t edge = 5000 - (ReplayWindow::kWindow - 1);
  EXPECT_EQ(w.check_and_update(edge), Verdict::Accepted);  // the oldest slot still inside
  EXPECT_EQ(w.check_and_update(edge), Verdict::Replayed);
  EXPECT_EQ(w.check_and_update(edge - 1), Verdict::TooOld);
  EXPECT_EQ(w.check_and_update(0), Verdict::TooOld);
}

TEST(ReplayWindow, SlidingForgetsOnlyWhatLeftTheWindow) {
  ReplayWindow w;
  EXPECT_EQ(w.check_and_update(10), Verdict::Accepted);
  EXPECT_EQ(w.check_and_update(12), Verdict::Accepted);
  // Jump by less than the window: 10 and 12 are still remembered, 11 still fresh.
  EXPECT_EQ(w.check_and_update(10 + ReplayWindow::kWindow - 1), Verdict::Accepted);
  EXPECT_EQ(w.check_and_update(10), Verdict::Replayed);
  EXPECT_EQ(w.check_and_update(12), Verdict::Replayed);
  EXPECT_EQ(w.check_and_update(11), Verdict::Accepted);
  // A slot reused by the ring after sliding is fresh for its new sequence number.
  const std::uint64_t reuse = 12 + ReplayWindow::kWindow;
  EXPECT_EQ(w.check_and_update(reuse), Verdict::Accepted);
  EXPECT_EQ(w.check_and_update(12), Verdict::TooOld);
  EXPECT_EQ(w.check_and_update(reuse), Verdict::Replayed);
  // A jump beyond the window forgets everything older.
  EXPECT_EQ(w.check_and_update(1'000'000), Verdict::Accepted);
  EXPECT_EQ(w.check_and_update(999'999), Verdict::Accepted);
  EXPECT_EQ(w.check_and_update(reuse), Verdict::TooOld);
}

TEST(ReplayWindow, MatchesASetBasedModel) {
  // Brute-force model: accepted iff never seen and within kWindow of the highest seen so far.
  ReplayWindow w;
  std::set<std::uint64_t> seen;
  std::uint64_t highest = 0;
  std::mt19937_64 rng(99);
  for (int i = 0; i < 20000; ++i) {
    const std::uint64_t base = static_cast<std::uint64_t>(i) * 3;
    const std::uint64_t s = base + rng() % 1500 - std::min<std::uint64_t>(base, 750);
    Verdict expected;
    if (!seen.empty() && s + ReplayWindow::kWindow <= highest)
      expected = Verdict::TooOld;
    else if (seen.count(s))
      expected = Verdict::Replayed;
    else
      expected = Verdict::Accepted;
    ASSERT_EQ(w.check_and_update(s), expected) << "i " << i << " seq " << s;
    if (expected == Verdict::Accepted) {
      seen.insert(s);
      highest = std::max(highest, s);
    }
  }
}

TEST(ExtendSeq, FollowsTheU32Wrap) {
  EXPECT_EQ(extend_seq(5, 3), 5u);
  EXPECT_EQ(extend_seq(2, 3), 2u);
  EXPECT_EQ(extend_seq(0x00000002u, 0xFFFFFFF0u), 0x100000002ull);    // wrapped forward
  EXPECT_EQ(extend_seq(0xFFFFFFF0u, 0x100000002ull), 0xFFFFFFF0ull);  // late, before the wrap
  EXPECT_EQ(extend_seq(0x10u, 0x100000002ull), 0x100000010ull);
}

}  // namespace
}  // namespace telex::proto
