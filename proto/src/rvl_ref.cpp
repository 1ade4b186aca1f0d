// SPDX-License-Identifier: MIT
// Reference RVL (Wilson 2017) written from the paper's description, as a peer for benchmarks.
#include <cstring>

#include "byte_io.h"
#include "telex/proto/depth_codec.h"

namespace telex::proto {
namespace {

// The paper packs 4-bit nibbles (3 data bits + continue bit) most-significant first into 32-bit
// words written in host order; we fix that order to little-endian words for portability.
class NibbleWriter {
 public:
  explicit NibbleWriter(std::vector<std::uint8_t>& out) : out_(out) {}
  void vle(std::uint32_t value) {
    do {
      std::uint32_t nibble = value & 0x7;
      value >>= 3;
      if (value) nibble |= 0x8;
      word_ = (word_ << 4) | nibble;
      if (++nibbles_ == 8) flush();
    } while (value);
  }
  void finish() {
    if (nibbles_) {
      word_ <<= 4 * (8 - nibbles_);
      flush();
    }
  }

 private:
  void flush() {
    for (int i = 0; i < 4; ++i) out_.push_back(static_cast<std::uint8_t>(word_ >> (8 * i)));
    word_ = 0;
    nibbles_ = 0;
  }
  std::vector<std::uint8_t>& out_;
  std::uint32_t word_ = 0;
  int nibbles_ = 0;
};

class NibbleReader {
 public:
  explicit NibbleReader(std::span<const std::uint8_t> in) : in_(in) {}
  // False when the words ran out or a value exceeds 32 bits.
  bool vle(std::uint32_t& value) {
    value = 0;
    for (int bits = 0; bits < 33; bits += 3) {
      if (nibbles_ == 0) {
        if (pos_ + 4 > in_.size()) return false;
        word_ = detail::load_u32(in_.data() + pos_);
        pos_ += 4;
        nibbles_ = 8;
      }
      const std::uint32_t nibble = word_ >> 28;
      word_ <<= 4;
      --nibbles_;
      value |= (nibble & 0x7) << bits;
      if (!(nibble & 0x8)) return true;
    }
    return false;
  }
  bool at_end() const { return pos_ == in_.size(); }

 private:
  std::span<const std::uint8_t> in_;
  std::size_t pos_ = 0;
  std::uint32_t word_ = 0;
  int nibbles_ = 0;
};

}  // namespace

std::vector<std::uint8_t> rvl_ref_encode(const cv::Mat1w& depth) {
  std::vector<std::uint8_t> out;
  out.reserve(static_cast<std::size_t>(depth.total()) * 2);
  NibbleWriter nw(out);
  cv::Mat1w cont = depth.isContinuous() ? depth : depth.clone();
  const std::uint16_t* in = cont[0];
  const std::uint16_t* end = in + cont.total();
  int previous = 0;
  while (in != end) {
    std::uint32_t zeros = 0, nonzeros = 0;
    for (; in != end && !*in; ++in) ++zeros;
    nw.vle(zeros);
    for (const std::uint16_t* p = in; p != end && *p; ++p) ++nonzeros;
    nw.vle(nonzeros);
    for (std::uint32_t i = 0; i < nonzeros; ++i) {
      const int current = *in++;
      const int delta = current - previous;
      nw.vle(static_cast<std::uint32_t>((delta << 1) ^ (delta >> 31)));
      previous = current;
    }
  }
  nw.finish();
  return out;
}

DecodeStatus rvl_ref_decode(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out) {
  if (w <= 0 || h <= 0 || w > kMaxDepthSide || h > kMaxDepthSide) return DecodeStatus::BadGeometry;
  if (out.rows != h || out.cols != w || !out.isContinuous()) out.create(h, w);
  NibbleReader nr(bytes);
  std::uint16_t* o = out[0];
  const std::size_t total = static_cast<std::size_t>(w) * h;
  std::size_t done = 0;
  int previous = 0;
  while (done < total) {
    std::uint32_t zeros = 0, nonzeros = 0;
    if (!nr.vle(zeros)) return DecodeStatus::Truncated;
    if (zeros > total - done) return DecodeStatus::DecompressionBomb;
    std::memset(o + done, 0, zeros * sizeof(std::uint16_t));
    done += zeros;
    // The encoder always follows a zero run with a non-zero count (0 at the very end).
    if (!nr.vle(nonzeros)) return DecodeStatus::Truncated;
    if (nonzeros > total - done) return DecodeStatus::DecompressionBomb;
    for (std::uint32_t i = 0; i < nonzeros; ++i) {
      std::uint32_t z = 0;
      if (!nr.vle(z)) return DecodeStatus::Truncated;
      const std::int64_t current =
          previous + static_cast<std::int64_t>(static_cast<std::int32_t>(z >> 1) ^
                                               -static_cast<std::int32_t>(z & 1));
      if (current < 1 || current > 65535) return DecodeStatus::Corrupt;
      o[done++] = static_cast<std::uint16_t>(current);
      previous = static_cast<int>(current);
    }
  }
  return nr.at_end() ? DecodeStatus::Ok : DecodeStatus::Corrupt;
}

}  // namespace telex::proto
