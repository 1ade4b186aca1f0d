// SPDX-License-Identifier: MIT
// Internal: the prediction transform shared by the zip and fast depth codecs (docs/PROTOCOL.md).
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
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

// LOCO-I median edge detector on the hole-filled symbol image: a left, b up, c up-left.
inline std::int32_t med(std::int32_t a, std::int32_t b, std::int32_t c) {
  const std::int32_t mx = a > b ? a : b;
  const std::int32_t mn = a > b ? b : a;
  if (c >= mx) return mn;
  if (c <= mn) return mx;
  return a + b - c;
}

// What one pass over a depth tile learns: its hole runs and whether mapping values to indices
// of the sorted distinct-value table pays.
struct Analysis {
  std::vector<std::uint32_t> runs;  // alternating valid / hole run lengths, starting with valid
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

// Table: count, first value, then (delta - 1) for each following value, all varints.
void put_table(std::vector<std::uint8_t>& out, const std::vector<std::uint16_t>& table);
DecodeStatus get_table(std::span<const std::uint8_t> in, std::size_t& pos,
                       std::vector<std::uint16_t>& table);

// Runs the MED prediction over `img` in raster order, calling emit(zigzag residual) for every
// valid pixel. A hole takes its prediction as its symbol, so holes never disturb neighbours.
template <class Emit>
void predict(const cv::Mat1w& img, const std::uint16_t* index_of, std::vector<std::int32_t>& rows,
             Emit&& emit) {
  const int w = img.cols;
  rows.assign(2 * static_cast<std::size_t>(w), 0);
  std::int32_t* prev = rows.data();
  std::int32_t* cur = rows.data() + w;
  for (int y = 0; y < img.rows; ++y) {
    const std::uint16_t* row = img[y];
    for (int x = 0; x < w; ++x) {
      std::int32_t pred;
      if (y == 0) {
        pred = x ? cur[x - 1] : 0;
      } else if (x == 0) {
        pred = prev[0];
      } else {
        pred = med(cur[x - 1], prev[x], prev[x - 1]);
      }
      const std::uint16_t v = row[x];
      if (v == 0) {
        cur[x] = pred;
      } else {
        const std::int32_t s = index_of ? index_of[v] : v;
        emit(zigzag(s - pred));
        cur[x] = s;
      }
    }
    std::swap(prev, cur);
  }
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
  std::uint32_t left = runs[0];
  bool valid = true;
  const std::int64_t n_table = table ? static_cast<std::int64_t>(table->size()) : 0;
  for (int y = 0; y < h; ++y) {
    std::uint16_t* row = out[y];
    for (int x = 0; x < w; ++x) {
      while (left == 0) {
        ++ri;
        valid = !valid;
        left = runs[ri];
      }
      --left;
      std::int32_t pred;
      if (y == 0) {
        pred = x ? cur[x - 1] : 0;
      } else if (x == 0) {
        pred = prev[0];
      } else {
        pred = med(cur[x - 1], prev[x], prev[x - 1]);
      }
      if (!valid) {
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
      cur[x] = static_cast<std::int32_t>(s);
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

// MSB-first bit writer into a caller-sized byte buffer (the caller reserves the worst case).
class BitWriter {
 public:
  explicit BitWriter(std::uint8_t* out) : out_(out) {}
  // len 1..32
  void put(std::uint32_t v, int len) {
    acc_ = (acc_ << len) | v;
    n_ += len;
    if (n_ >= 32) {
      n_ -= 32;
      const auto w = static_cast<std::uint32_t>(acc_ >> n_);
      out_[pos_] = static_cast<std::uint8_t>(w >> 24);
      out_[pos_ + 1] = static_cast<std::uint8_t>(w >> 16);
      out_[pos_ + 2] = static_cast<std::uint8_t>(w >> 8);
      out_[pos_ + 3] = static_cast<std::uint8_t>(w);
      pos_ += 4;
    }
  }
  // Flushes the partial byte (zero padded) and returns the bytes written.
  std::size_t finish() {
    while (n_ >= 8) {
      n_ -= 8;
      out_[pos_++] = static_cast<std::uint8_t>(acc_ >> n_);
    }
    if (n_ > 0) out_[pos_++] = static_cast<std::uint8_t>(acc_ << (8 - n_));
    n_ = 0;
    return pos_;
  }

 private:
  std::uint8_t* out_;
  std::size_t pos_ = 0;
  std::uint64_t acc_ = 0;
  int n_ = 0;
};

// MSB-first bit reader that never reads outside its span: past the end it yields zeros and
// records the overrun, which the caller turns into Truncated.
class BitReader {
 public:
  explicit BitReader(std::span<const std::uint8_t> in) : in_(in) {}
  std::uint32_t get(int len) {  // len 0..32
    if (len == 0) return 0;
    refill();
    const auto v = static_cast<std::uint32_t>(buf_ >> (64 - len));
    buf_ <<= len;
    cnt_ -= len;
    return v;
  }
  // Leading zero bits before the next 1 (consumes them, not the 1); `limit`+1 when more.
  int zeros(int limit) {
    refill();
    int z = buf_ == 0 ? 64 : std::countl_zero(buf_);
    if (z > limit) return limit + 1;
    buf_ <<= z;
    cnt_ -= z;
    return z;
  }
  bool overrun() const { return consumed_bits() > in_.size() * 8; }
  std::size_t consumed_bits() const { return pos_ * 8 - static_cast<std::size_t>(cnt_); }

 private:
  void refill() {
    while (cnt_ <= 56) {
      const std::uint64_t b = pos_ < in_.size() ? in_[pos_] : 0;
      ++pos_;
      buf_ |= b << (56 - cnt_);
      cnt_ += 8;
    }
  }
  std::span<const std::uint8_t> in_;
  std::size_t pos_ = 0;
  std::uint64_t buf_ = 0;
  int cnt_ = 0;
};

std::vector<std::uint8_t> encode_zip(const cv::Mat1w& img, int level);
DecodeStatus decode_zip(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out);
std::vector<std::uint8_t> encode_fast(const cv::Mat1w& img);
DecodeStatus decode_fast(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out);

}  // namespace telex::proto::detail
