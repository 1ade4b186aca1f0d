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

// Gaps between neighbouring depth levels are small (the disparity step in mm), so they travel as
// 4-bit nibbles, two per byte (first in the low half), with 15 escaping to a varint of the excess
// after the nibbles: half the bytes of one varint per gap on a per-tile table.
void put_table(std::vector<std::uint8_t>& out, const std::vector<std::uint16_t>& table) {
  put_varint(out, static_cast<std::uint32_t>(table.size()));
  put_varint(out, table[0]);
  const std::size_t gaps = table.size() - 1;
  const std::size_t base = out.size();
  out.resize(base + (gaps + 1) / 2, 0);
  for (std::size_t i = 0; i < gaps; ++i) {
    const std::uint32_t d = static_cast<std::uint32_t>(table[i + 1] - table[i] - 1);
    out[base + i / 2] |= static_cast<std::uint8_t>(std::min(d, 15u) << (4 * (i % 2)));
  }
  for (std::size_t i = 0; i < gaps; ++i) {
    const std::uint32_t d = static_cast<std::uint32_t>(table[i + 1] - table[i] - 1);
    if (d >= 15) put_varint(out, d - 15);
  }
}

DecodeStatus get_table(std::span<const std::uint8_t> in, std::size_t& pos,
                       std::vector<std::uint16_t>& table) {
  std::uint32_t n = 0, v = 0;
  if (!get_varint(in, pos, n) || !get_varint(in, pos, v)) return DecodeStatus::Truncated;
  if (n == 0 || n > 65535 || v == 0 || v > 65535) return DecodeStatus::Corrupt;
  const std::size_t gaps = n - 1;
  const std::size_t nibble_bytes = (gaps + 1) / 2;
  if (in.size() - pos < nibble_bytes) return DecodeStatus::Truncated;
  const std::uint8_t* nib = in.data() + pos;
  pos += nibble_bytes;
  table.clear();
  table.reserve(n);
  table.push_back(static_cast<std::uint16_t>(v));
  for (std::size_t i = 0; i < gaps; ++i) {
    std::uint32_t d = (nib[i / 2] >> (4 * (i % 2))) & 0x0F;
    if (d == 15) {
      std::uint32_t e = 0;
      if (!get_varint(in, pos, e)) return DecodeStatus::Truncated;
      if (e > 65535) return DecodeStatus::Corrupt;
      d += e;
    }
    const std::uint64_t next = static_cast<std::uint64_t>(table.back()) + d + 1;
    if (next > 65535) return DecodeStatus::Corrupt;
    table.push_back(static_cast<std::uint16_t>(next));
  }
  if (gaps % 2 == 1 && (nib[gaps / 2] >> 4) != 0) return DecodeStatus::Corrupt;
  return DecodeStatus::Ok;
}

}  // namespace telex::proto::detail
