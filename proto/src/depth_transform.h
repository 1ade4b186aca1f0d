// SPDX-License-Identifier: MIT
// Internal: value tables, hole-run checks and bit I/O shared by the zip and fast depth codecs, and
// zip's MED prediction transform (docs/PROTOCOL.md section 6).
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <opencv2/core.hpp>
#include <span>
#include <utility>
#include <vector>

#include "telex/proto/depth_codec.h"

namespace telex::proto::detail {

inline std::uint32_t zigzag(std::int32_t v) {
  return (static_cast<std::uint32_t>(v) << 1) ^ static_cast<std::uint32_t>(v >> 31);
}
inline std::int32_t unzigzag(std::uint32_t z) {
  return static_cast<std::int32_t>(z >> 1) ^ -static_cast<std::int32_t>(z & 1);
}

// LOCO-I median edge detector on the hole-filled symbol image: a left, b up, c up-left. Written
// as median(a, b, a + b - c), which equals it and compiles to branch-free min/max: the branchy
// form mispredicts on every edge.
inline std::int32_t med(std::int32_t a, std::int32_t b, std::int32_t c) {
  const std::int32_t mx = std::max(a, b);
  const std::int32_t mn = std::min(a, b);
  return std::max(mn, std::min(mx, a + b - c));
}

// What one pass over a depth tile learns: its valid pixel count and whether mapping values to
// indices of the sorted distinct-value table pays.
struct Analysis {
  std::size_t n_valid = 0;
  bool use_table = false;
  std::vector<std::uint16_t> table;         // sorted distinct non-zero values (when use_table)
  const std::uint16_t* index_of = nullptr;  // value -> table index (valid for table values only)
};

// Per-thread scratch so encoders allocate nothing per call once warm.
Analysis& analyse(const cv::Mat1w& img);

// Appends LEB128 unsigned varints.
void put_varint(std::vector<std::uint8_t>& out, std::uint32_t v);
// Reads one LEB128 varint of at most 5 bytes; false when short or overlong.
bool get_varint(std::span<const std::uint8_t> in, std::size_t& pos, std::uint32_t& v);

// Table: varint count, varint first value, then (when count > 1) an LSB-first bit stream: 2 bits
// Rice parameter k, then each gap (value - previous - 1) as a Rice code, zero-padded to a byte.
void put_table(std::vector<std::uint8_t>& out, const std::vector<std::uint16_t>& table);
DecodeStatus get_table(std::span<const std::uint8_t> in, std::size_t& pos,
                       std::vector<std::uint16_t>& table);

// Runs the MED prediction over `img` in raster order, calling emit(zigzag residual) for every
// valid pixel and run(length) for each alternating valid / hole run (starting with valid, the
// first possibly empty). A hole takes its prediction as its symbol, so holes never disturb
// their neighbours' predictions. Row -1 is all zeros (so row 0 predicts from the left) and
// column 0 predicts from above. Left and up-left travel in registers: a store-to-load round
// trip through the row buffer would be the loop's critical path.
template <class Emit, class Run>
void predict(const cv::Mat1w& img, const std::uint16_t* index_of, std::vector<std::int32_t>& rows,
             Emit&& emit, Run&& run) {
  const int w = img.cols;
  rows.assign(2 * static_cast<std::size_t>(w), 0);
  std::int32_t* prev = rows.data();
  std::int32_t* cur = rows.data() + w;
  bool in_valid = true;
  std::uint32_t len = 0;
  for (int y = 0; y < img.rows; ++y) {
    const std::uint16_t* row = img[y];
    std::int32_t left = prev[0];  // column 0: MED(b, b, b) = b
    std::int32_t up_left = prev[0];
    for (int x = 0; x < w; ++x) {
      const std::int32_t up = prev[x];
      const std::int32_t pred = med(left, up, up_left);
      up_left = up;
      const std::uint16_t v = row[x];
      const bool valid = v != 0;
      if (valid != in_valid) {
        run(len);
        len = 0;
        in_valid = valid;
      }
      ++len;
      if (valid) {
        const std::int32_t s = index_of ? index_of[v] : v;
        emit(zigzag(s - pred));
        left = s;
      } else {
        left = pred;
      }
      cur[x] = left;
    }
    std::swap(prev, cur);
  }
  run(len);
}

// Inverse of predict(): `runs` (validated to sum to w*h, no empty run after the first) says which
// pixels are valid; next(z) yields the next residual or returns false when the stream ran out.
template <class Next>
DecodeStatus reconstruct(const std::vector<std::uint32_t>& runs,
                         const std::vector<std::uint16_t>* table, int w, int h,
                         std::vector<std::int32_t>& rows, Next&& next, cv::Mat1w& out) {
  rows.assign(2 * static_cast<std::size_t>(w), 0);
  std::int32_t* prev = rows.data();
  std::int32_t* cur = rows.data() + w;
  std::size_t ri = 0;
  std::uint32_t left_in_run = runs[0];
  bool valid = true;
  const std::int64_t n_table = table ? static_cast<std::int64_t>(table->size()) : 0;
  for (int y = 0; y < h; ++y) {
    std::uint16_t* row = out[y];
    std::int32_t left = prev[0];
    std::int32_t up_left = prev[0];
    for (int x = 0; x < w; ++x) {
      while (left_in_run == 0) {
        ++ri;
        valid = !valid;
        left_in_run = runs[ri];
      }
      --left_in_run;
      const std::int32_t up = prev[x];
      const std::int32_t pred = med(left, up, up_left);
      up_left = up;
      if (!valid) {
        left = pred;
        cur[x] = pred;
        row[x] = 0;
        continue;
      }
      std::uint32_t z = 0;
      if (!next(z)) return DecodeStatus::Truncated;
      const std::int64_t s = static_cast<std::int64_t>(pred) + unzigzag(z);
      if (table) {
        if (s < 0 || s >= n_table) return DecodeStatus::Corrupt;
        row[x] = (*table)[static_cast<std::size_t>(s)];
      } else {
        if (s < 1 || s > 65535) return DecodeStatus::Corrupt;
        row[x] = static_cast<std::uint16_t>(s);
      }
      left = static_cast<std::int32_t>(s);
      cur[x] = left;
    }
    std::swap(prev, cur);
  }
  return DecodeStatus::Ok;
}

// Checks decoded hole runs: they must cover exactly `total` pixels and only the first may be 0.
inline bool runs_valid(const std::vector<std::uint32_t>& runs, std::size_t total) {
  std::size_t sum = 0;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (i > 0 && runs[i] == 0) return false;
    sum += runs[i];
  }
  return !runs.empty() && sum == total;
}

inline void store_le64(std::uint8_t* p, std::uint64_t v) {
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap64(v);
  std::memcpy(p, &v, 8);
}
inline std::uint64_t load_le64(const std::uint8_t* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap64(v);
  return v;
}
inline std::uint64_t low_mask(int bits) { return (std::uint64_t{1} << bits) - 1; }

// LSB-first bit writer: bits fill each byte from its least significant bit. Branch-free: every
// put stores 8 bytes, so the caller's buffer needs 8 bytes of slack beyond the worst case.
class BitWriter {
 public:
  explicit BitWriter(std::uint8_t* out) : out_(out) {}
  void put(std::uint64_t v, int len) {  // len 0..56, v < 2^len
    acc_ |= v << n_;
    n_ += len;
    store_le64(out_ + pos_, acc_);
    pos_ += static_cast<std::size_t>(n_ >> 3);
    acc_ >>= (n_ & ~7);
    n_ &= 7;
  }
  std::size_t finish() { return pos_ + (n_ > 0 ? 1 : 0); }  // the partial byte is already stored

 private:
  std::uint8_t* out_;
  std::size_t pos_ = 0;
  std::uint64_t acc_ = 0;
  int n_ = 0;
};

// LSB-first bit reader that never reads outside its span: bits past the end read as zero and
// the caller checks overrun().
class BitReader {
 public:
  explicit BitReader(std::span<const std::uint8_t> in) : in_(in) {}
  // The next 57 or more bits, first bit in bit 0.
  std::uint64_t peek() const {
    const std::size_t byte = bitpos_ >> 3;
    std::uint64_t w = 0;
    if (byte + 8 <= in_.size()) {
      w = load_le64(in_.data() + byte);
    } else {
      for (std::size_t i = byte; i < in_.size(); ++i)
        w |= static_cast<std::uint64_t>(in_[i]) << (8 * (i - byte));
    }
    return w >> (bitpos_ & 7);
  }
  void skip(int bits) { bitpos_ += static_cast<std::size_t>(bits); }
  bool overrun() const { return bitpos_ > in_.size() * 8; }
  std::size_t consumed_bits() const { return bitpos_; }
  std::size_t size_bits() const { return in_.size() * 8; }
  // Valid only for a reader past its last field: the stream's bytes are all used, none unused.
  bool exactly_consumed() const { return (bitpos_ + 7) / 8 == in_.size(); }

 private:
  std::span<const std::uint8_t> in_;
  std::size_t bitpos_ = 0;
};

std::vector<std::uint8_t> encode_zip(const cv::Mat1w& img, int level);
DecodeStatus decode_zip(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out);
std::vector<std::uint8_t> encode_fast(const cv::Mat1w& img);
DecodeStatus decode_fast(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out);

}  // namespace telex::proto::detail
