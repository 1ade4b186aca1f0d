// SPDX-License-Identifier: MIT
// The bag reader on damaged files: a truncated recording, positions and lengths pointing nowhere,
// a chunk claiming a huge size, and every byte of a small bag flipped in turn. Each ends in an
// error naming the file (never a crash or a huge allocation: Debian's rosbag_storage alone
// overflows its heap on some of these, which libFuzzer found).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "process.h"
#include "telex/bag/bag.h"

namespace telex::bag {
namespace {

std::filesystem::path temp(const std::string& name) { return ::telex::test::scratch_file(name); }

std::vector<char> read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_all(const std::filesystem::path& p, const std::vector<char>& b) {
  std::ofstream(p, std::ios::binary).write(b.data(), static_cast<std::streamsize>(b.size()));
}

// A small valid bag: two topics, uncompressed or LZ4.
std::vector<char> good_bag(Compression c) {
  const auto p = temp(c == Compression::None ? "good_none.bag" : "good_lz4.bag");
  {
    Writer w(p.string(), c);
    for (int i = 0; i < 3; ++i) {
      w.depth_mm("/d", "/camera_info", 1'700'000'000'000'000'000 + i * 1000,
                 static_cast<std::uint32_t>(i), "c", cv::Mat1w(3, 4, std::uint16_t(700 + i)),
                 {5, 5, 1.5, 1, 4, 3});
      w.wrench("/w", 1'700'000'000'000'000'000 + i * 1000 + 1, "c", {1, 2, 3}, {0, 0, 0});
    }
  }
  return read_all(p);
}

// Reads every message; returns the error text, or "" when the file read to its end.
std::string read_error(const std::vector<char>& bytes, const std::string& name) {
  const auto p = temp(name);
  write_all(p, bytes);
  try {
    Reader r(p.string());
    Message m;
    while (r.next(m)) {
    }
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

// Overwrites the value of the header field `name` (its first occurrence) with `value`.
void set_field(std::vector<char>& b, const std::string& name, const std::vector<char>& value) {
  const std::string key = name + "=";
  const auto it = std::search(b.begin(), b.end(), key.begin(), key.end());
  ASSERT_NE(it, b.end()) << name;
  std::copy(value.begin(), value.end(), it + static_cast<std::ptrdiff_t>(key.size()));
}

TEST(BagCheck, AValidBagReadsToItsEnd) {
  for (const auto c : {Compression::None, Compression::Lz4}) {
    const auto b = good_bag(c);
    EXPECT_EQ(read_error(b, "valid.bag"), "");
    EXPECT_NO_THROW(
        check_bag_file(temp(c == Compression::None ? "good_none.bag" : "good_lz4.bag").string()));
  }
}

TEST(BagCheck, ATruncatedRecordingIsAnErrorWhereverItIsCut) {
  for (const auto c : {Compression::None, Compression::Lz4}) {
    const auto b = good_bag(c);
    for (std::size_t n = 0; n < b.size(); n += 61) {
      const std::vector<char> cut(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(n));
      const std::string e = read_error(cut, "cut.bag");
      EXPECT_NE(e.find("cannot read bag " + temp("cut.bag").string()), std::string::npos)
          << "cut at " << n << ": " << e;
    }
  }
}

TEST(BagCheck, PositionsAndSizesThatPointNowhereAreNamed) {
  auto b = good_bag(Compression::None);
  set_field(b, "index_pos", {1, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_NE(read_error(b, "index.bag").find("the index position 1 is not the start of a record"),
            std::string::npos);

  b = good_bag(Compression::None);
  set_field(b, "index_pos", {0, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_NE(read_error(b, "unindexed.bag").find("no index"), std::string::npos);

  b = good_bag(Compression::None);
  set_field(b, "chunk_pos", {'\x0d', 0, 0, 0, 0, 0, 0, 0});
  EXPECT_NE(read_error(b, "chunkpos.bag").find("is not the start of a chunk"), std::string::npos);

  b = good_bag(Compression::Lz4);
  set_field(b, "size", {0, 0, 0, '\x40'});  // 1 GiB unpacked
  EXPECT_NE(read_error(b, "size.bag").find("bytes unpacked"), std::string::npos);

  b = good_bag(Compression::Lz4);
  set_field(b, "compression", {'z', 'i', 'p'});
  EXPECT_NE(read_error(b, "zip.bag").find("unknown compression 'zip'"), std::string::npos);

  b = good_bag(Compression::None);
  std::memcpy(b.data(), "#ROSBAG V1.2\n", 13);
  EXPECT_NE(read_error(b, "v12.bag").find("not a ROS bag of format 2.0"), std::string::npos);
}

// Overwrites the 32-bit length that follows the n-th occurrence of `text` plus `gap` bytes.
void set_length_after(std::vector<char>& b, const std::string& text, int n, std::size_t gap,
                      std::uint32_t value) {
  auto it = b.begin();
  for (int i = 0; i <= n; ++i) {
    if (i > 0) ++it;
    it = std::search(it, b.end(), text.begin(), text.end());
    ASSERT_NE(it, b.end()) << text << " #" << n;
  }
  std::memcpy(&*(it + static_cast<std::ptrdiff_t>(text.size() + gap)), &value, 4);
}

TEST(BagCheck, AnArrayLongerThanItsMessageIsAnErrorNotAnAllocation) {
  // ROS's deserialiser resizes to the claimed length first: 2.4 G doubles would be 19.7 GB.
  auto b = good_bag(Compression::None);
  set_length_after(b, std::string("\x09\0\0\0plumb_bob", 13), 1, 0,
                   0x92E0'0000u);  // the second CameraInfo's D
  std::string e = read_error(b, "distortion.bag");
  EXPECT_NE(e.find("cannot decode a message of " + temp("distortion.bag").string() +
                   " /camera_info: D claims 2464153600 elements of 8 bytes"),
            std::string::npos)
      << e;

  b = good_bag(Compression::None);
  set_length_after(b,
                   std::string("\x05\0\0\0"
                               "16UC1",
                               9),
                   2, 5, 0xFFFF'FFF0u);  // the third image's data, after the step
  e = read_error(b, "data.bag");
  EXPECT_NE(e.find(" /d: data claims 4294967280 elements of 1 bytes, the message has 24 left"),
            std::string::npos)
      << e;

  b = good_bag(Compression::None);
  set_length_after(b,
                   std::string("\x05\0\0\0"
                               "16UC1",
                               9),
                   0, 5, 0xFFFF'FFF0u);  // the first image: read when the bag opens
  e = read_error(b, "first.bag");
  EXPECT_NE(e.find("cannot read bag " + temp("first.bag").string()), std::string::npos) << e;
  EXPECT_NE(e.find("data claims"), std::string::npos) << e;
}

TEST(BagCheck, EveryByteFlippedReadsOrFailsCleanly) {
  const auto b = good_bag(Compression::None);
  int failed = 0;
  for (std::size_t i = 0; i < b.size(); i += 23) {
    auto flipped = b;
    flipped[i] = static_cast<char>(flipped[i] ^ 0xA5);
    const std::string e = read_error(flipped, "flip.bag");
    if (!e.empty()) {
      ++failed;
      EXPECT_NE(e.find(temp("flip.bag").string()), std::string::npos) << "byte " << i << ": " << e;
    }
  }
  // Flips in padding and message values read; flips in lengths and positions must not.
  EXPECT_GT(failed, 30);
}

}  // namespace
}  // namespace telex::bag
