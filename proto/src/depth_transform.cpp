// SPDX-License-Identifier: MIT
// Hole runs and distinct-value tables for the predictive depth codecs.
#include "depth_transform.h"

#include <algorithm>

namespace telex::proto::detail {
namespace {

struct Scratch {
  std::vector<std::uint8_t> seen = std::vector<std::uint8_t>(65536, 0);
  std::vector<std::uint16_t> index_of = std::vector<std::uint16_t>(65536, 0);
  Analysis analysis;
};

}  // namespace

Analysis& analyse(const cv::Mat1w& img) {
  thread_local Scratch s;
  Analysis& a = s.analysis;
  a.table.clear();
  a.n_valid = 0;
  // A structured-light sensor reports few distinct depths; past a quarter of the pixels a table
  // costs more than it saves, so collection stops there (checked per row, off the inner loop).
  const std::size_t total = static_cast<std::size_t>(img.rows) * img.cols;
  const std::size_t table_cap = std::max<std::size_t>(64, total / 4);
  bool collecting = true;
  s.seen[0] = 1;  // holes never enter the table
  for (int y = 0; y < img.rows; ++y) {
    const std::uint16_t* row = img[y];
    std::size_t valid = 0;
    if (collecting) {
      for (int x = 0; x < img.cols; ++x) {
        const std::uint16_t v = row[x];
        valid += v != 0;
        if (!s.seen[v]) {
          s.seen[v] = 1;
          a.table.push_back(v);
        }
      }
      collecting = a.table.size() <= table_cap;
    } else {
      for (int x = 0; x < img.cols; ++x) valid += row[x] != 0;
    }
    a.n_valid += valid;
  }
  s.seen[0] = 0;
  for (std::uint16_t v : a.table) s.seen[v] = 0;
  a.use_table =
      collecting && !a.table.empty() && a.table.size() <= std::max<std::size_t>(16, a.n_valid / 4);
  if (a.use_table) {
    std::sort(a.table.begin(), a.table.end());
    for (std::size_t i = 0; i < a.table.size(); ++i)
      s.index_of[a.table[i]] = static_cast<std::uint16_t>(i);
    a.index_of = s.index_of.data();
  } else {
    a.table.clear();
    a.index_of = nullptr;
  }
  return a;
}

void put_varint(std::vector<std::uint8_t>& out, std::uint32_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<std::uint8_t>(v | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<std::uint8_t>(v));
}

bool get_varint(std::span<const std::uint8_t> in, std::size_t& pos, std::uint32_t& v) {
  v = 0;
  for (int i = 0; i < 5; ++i) {
    if (pos >= in.size()) return false;
    const std::uint8_t b = in[pos++];
    if (i == 4 && b > 0x0F) return false;  // beyond 32 bits
    v |= static_cast<std::uint32_t>(b & 0x7F) << (7 * i);
    if (!(b & 0x80)) return true;
  }
  return false;
}

// Gaps between neighbouring depth levels are small (the disparity step in mm) but vary with depth,
// so they travel as Rice codes with the parameter k (0..3) that the encoder finds cheapest for
// this table, in an LSB-first bit stream of their own: a tile's table costs about 3 bits a value.
namespace {

constexpr int kGapEscape = 16;  // unary prefix length that announces a raw 16-bit gap

std::size_t gap_bits(std::uint32_t g, int k) {
  const std::uint32_t q = g >> k;
  return q < kGapEscape ? q + 1 + static_cast<std::size_t>(k) : kGapEscape + 1 + 16;
}

}  // namespace

void put_table(std::vector<std::uint8_t>& out, const std::vector<std::uint16_t>& table) {
  put_varint(out, static_cast<std::uint32_t>(table.size()));
  put_varint(out, table[0]);
  const std::size_t gaps = table.size() - 1;
  if (gaps == 0) return;
  std::size_t cost[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < gaps; ++i) {
    const std::uint32_t g = static_cast<std::uint32_t>(table[i + 1] - table[i] - 1);
    for (int k = 0; k < 4; ++k) cost[k] += gap_bits(g, k);
  }
  const int k = static_cast<int>(std::min_element(cost, cost + 4) - cost);
  const std::size_t base = out.size();
  // 2 + 33 bits per gap at most, plus the writer's 8 bytes of slack.
  out.resize(base + (2 + 33 * gaps + 7) / 8 + 8, 0);
  BitWriter bw(out.data() + base);
  bw.put(static_cast<std::uint64_t>(k), 2);
  for (std::size_t i = 0; i < gaps; ++i) {
    const std::uint32_t g = static_cast<std::uint32_t>(table[i + 1] - table[i] - 1);
    const std::uint32_t q = g >> k;
    if (q < kGapEscape) {
      bw.put((std::uint64_t{1} << q) | (static_cast<std::uint64_t>(g & low_mask(k)) << (q + 1)),
             static_cast<int>(q) + 1 + k);
    } else {
      bw.put((std::uint64_t{1} << kGapEscape) | (static_cast<std::uint64_t>(g) << (kGapEscape + 1)),
             kGapEscape + 1 + 16);
    }
  }
  out.resize(base + bw.finish());
}

DecodeStatus get_table(std::span<const std::uint8_t> in, std::size_t& pos,
                       std::vector<std::uint16_t>& table) {
  std::uint32_t n = 0, v = 0;
  if (!get_varint(in, pos, n) || !get_varint(in, pos, v)) return DecodeStatus::Truncated;
  if (n == 0 || n > 65535 || v == 0 || v > 65535) return DecodeStatus::Corrupt;
  table.clear();
  table.reserve(n);
  table.push_back(static_cast<std::uint16_t>(v));
  if (n == 1) return DecodeStatus::Ok;
  BitReader br(in.subspan(pos));
  const int k = static_cast<int>(br.peek() & 3);
  br.skip(2);
  for (std::uint32_t i = 1; i < n; ++i) {
    const std::uint64_t bits = br.peek();
    const int q = bits == 0 ? 64 : std::countr_zero(bits);
    std::uint32_t g = 0;
    if (q < kGapEscape) {
      g = (static_cast<std::uint32_t>(q) << k) |
          static_cast<std::uint32_t>((bits >> (q + 1)) & low_mask(k));
      br.skip(q + 1 + k);
    } else if (q == kGapEscape) {
      g = static_cast<std::uint32_t>((bits >> (kGapEscape + 1)) & 0xFFFF);
      br.skip(kGapEscape + 1 + 16);
    } else {
      // Past the end every bit reads as zero: a prefix running off the end is a short stream.
      return br.consumed_bits() + kGapEscape + 1 > br.size_bits() ? DecodeStatus::Truncated
                                                                  : DecodeStatus::Corrupt;
    }
    if (br.overrun()) return DecodeStatus::Truncated;
    const std::uint64_t next = static_cast<std::uint64_t>(table.back()) + g + 1;
    if (next > 65535) return DecodeStatus::Corrupt;
    table.push_back(static_cast<std::uint16_t>(next));
  }
  const std::size_t used_bits = br.consumed_bits();
  const std::size_t used = (used_bits + 7) / 8;
  // The final byte's unused high bits are zero: one table, one encoding.
  if (used_bits % 8 != 0 && (in[pos + used - 1] >> (used_bits % 8)) != 0)
    return DecodeStatus::Corrupt;
  pos += used;
  return DecodeStatus::Ok;
}

}  // namespace telex::proto::detail
