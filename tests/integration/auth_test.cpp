// SPDX-License-Identifier: MIT
// Tests for pre-shared key files (length bounds, loading, errors) and the datagrams' replay window.
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
#include "telex/proto/seal.h"

namespace telex::proto {
namespace {

TEST(Auth, KeyLengthBounds) {
  // 16 bytes (a typed password) no longer: a key has the suite's 32 (issue 49).
  EXPECT_THROW(AuthKey(std::vector<std::uint8_t>(16, 1)), std::invalid_argument);
  EXPECT_THROW(AuthKey(std::vector<std::uint8_t>(31, 1)), std::invalid_argument);
  EXPECT_NO_THROW(AuthKey(std::vector<std::uint8_t>(32, 1)));
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
    EXPECT_NE(what.find("at least 32"), std::string::npos) << what;
  }
  EXPECT_THROW(load_key_file(write("empty.key", "")), std::invalid_argument);
  EXPECT_THROW(load_key_file(dir_), std::exception);  // a directory is not a key
}

using Verdict = ReplayWindow::Verdict;

// `telex keygen`'s writer: 32 random bytes, mode 0600, loadable, never over an existing file.
TEST_F(KeyFile, NewKeyFileIsRandomPrivateAndNeverOverwritten) {
  const auto a = dir_ / "a.key";
  const auto b = dir_ / "b.key";
  write_new_key_file(a);
  write_new_key_file(b);
  EXPECT_EQ(std::filesystem::file_size(a), kMinKeyBytes);
  EXPECT_EQ(std::filesystem::status(a).permissions(),
            std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  EXPECT_NO_THROW(check_key_file_permissions(a));
  const auto ka = load_key_file(a);
  EXPECT_FALSE(std::ranges::equal(ka.bytes(), load_key_file(b).bytes()));
  try {
    write_new_key_file(a);
    FAIL() << "an existing key was overwritten";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("never overwritten"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(std::ranges::equal(load_key_file(a).bytes(), ka.bytes()));
  // A typed 16-character password is refused, naming the way to a proper key.
  try {
    load_key_file(write("short.key", "correct-horse-16"));
    FAIL() << "a 16-byte key was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("telex keygen"), std::string::npos) << e.what();
  }
}

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
}  // namespace
}  // namespace telex::proto
