// SPDX-License-Identifier: MIT
// "fast" depth codec: RVL's run idea with a value table, MED prediction and adaptive Rice bits.
#include <algorithm>

#include "byte_io.h"
#include "depth_transform.h"

namespace telex::proto::detail {
namespace {

constexpr std::uint8_t kFlagTable = 0x01;
constexpr int kEscape = 20;           // unary prefix length that announces a raw 17-bit residual
constexpr int kRawBits = 17;          // a zigzag residual of two 16-bit values fits in 17 bits
constexpr std::uint32_t kReset = 64;  // JPEG-LS style halving keeps k adaptive

struct FastScratch {
  std::vector<std::uint8_t> runs_bits;
  std::vector<std::uint8_t> res_bits;
  std::vector<std::int32_t> rows;
  std::vector<std::uint32_t> runs;
  std::vector<std::uint16_t> table;
};

FastScratch& scratch() {
  thread_local FastScratch s;
  return s;
}

// Exp-Golomb order 0 of v (codes v + 1): floor(log2(v+1)) zeros, then v+1 in binary.
void put_eg0(BitWriter& bw, std::uint32_t v) {
  const std::uint32_t u = v + 1;
  const int len = 32 - std::countl_zero(u);
  if (len > 1) bw.put(0, len - 1);
  bw.put(u, len);
}

bool get_eg0(BitReader& br, std::uint32_t& v) {
  const int z = br.zeros(31);
  if (z > 30) return false;
  // The z + 1 bits after the zeros start with the leading 1: together they are v + 1.
  v = br.get(z + 1) - 1;
  return true;
}

struct Rice {
  std::uint32_t a = 2;
  std::uint32_t n = 1;
  int k() const {
    int k = 0;
    while ((n << k) < a && k < 16) ++k;
    return k;
  }
  void update(std::uint32_t z) {
    a += z;
    if (++n == kReset) {
      a >>= 1;
      n >>= 1;
    }
  }
};

}  // namespace

std::vector<std::uint8_t> encode_fast(const cv::Mat1w& img) {
  FastScratch& s = scratch();
  const Analysis& a = analyse(img);
  const std::size_t total = static_cast<std::size_t>(img.rows) * img.cols;
  if (s.runs_bits.size() < a.runs.size() * 8 + 16) s.runs_bits.resize(a.runs.size() * 8 + 16);
  if (s.res_bits.size() < a.n_valid * 5 + 16) s.res_bits.resize(a.n_valid * 5 + 16);
  (void)total;

  BitWriter rw(s.runs_bits.data());
  for (std::uint32_t r : a.runs) put_eg0(rw, r);
  const std::size_t runs_len = rw.finish();

  BitWriter bw(s.res_bits.data());
  Rice rice;
  predict(img, a.index_of, s.rows, [&](std::uint32_t z) {
    const int k = rice.k();
    const std::uint32_t q = z >> k;
    if (q < kEscape) {
      bw.put(1, static_cast<int>(q) + 1);
      if (k) bw.put(z & ((1u << k) - 1), k);
    } else {
      bw.put(1, kEscape + 1);
      bw.put(z, kRawBits);
    }
    rice.update(z);
  });
  const std::size_t res_len = bw.finish();

  std::vector<std::uint8_t> out;
  out.reserve(1 + 4 + runs_len + res_len + (a.use_table ? a.table.size() * 2 + 8 : 0));
  out.push_back(a.use_table ? kFlagTable : 0);
  if (a.use_table) put_table(out, a.table);
  Writer w(out);
  w.u32(static_cast<std::uint32_t>(runs_len));
  w.bytes({s.runs_bits.data(), runs_len});
  w.bytes({s.res_bits.data(), res_len});
  return out;
}

DecodeStatus decode_fast(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out) {
  if (bytes.empty()) return DecodeStatus::Truncated;
  const std::uint8_t flags = bytes[0];
  if (flags & ~kFlagTable) return DecodeStatus::Corrupt;
  FastScratch& s = scratch();
  std::size_t pos = 1;
  const bool use_table = flags & kFlagTable;
  if (use_table) {
    const DecodeStatus t = get_table(bytes, pos, s.table);
    if (t != DecodeStatus::Ok) return t;
  }
  if (bytes.size() - pos < 4) return DecodeStatus::Truncated;
  const std::uint32_t runs_len = load_u32(bytes.data() + pos);
  pos += 4;
  if (bytes.size() - pos < runs_len) return DecodeStatus::Truncated;
  const std::size_t total = static_cast<std::size_t>(w) * h;

  BitReader rr(bytes.subspan(pos, runs_len));
  s.runs.clear();
  std::size_t covered = 0;
  while (covered < total) {
    std::uint32_t r = 0;
    if (!get_eg0(rr, r) || rr.overrun())
      return rr.overrun() ? DecodeStatus::Truncated : DecodeStatus::Corrupt;
    if (r > total - covered) return DecodeStatus::Corrupt;
    s.runs.push_back(r);
    covered += r;
  }
  if (!runs_valid(s.runs, total)) return DecodeStatus::Corrupt;
  if ((rr.consumed_bits() + 7) / 8 != runs_len) return DecodeStatus::Corrupt;

  const auto res = bytes.subspan(pos + runs_len);
  BitReader br(res);
  Rice rice;
  bool corrupt = false;
  auto next = [&](std::uint32_t& z) {
    const int k = rice.k();
    const int q = br.zeros(kEscape);
    if (q > kEscape || br.overrun()) {
      corrupt = !br.overrun();
      return false;
    }
    br.get(1);
    if (q == kEscape) {
      z = br.get(kRawBits);
    } else {
      z = (static_cast<std::uint32_t>(q) << k) | br.get(k);
    }
    if (br.overrun()) return false;
    rice.update(z);
    return true;
  };
  const DecodeStatus st =
      reconstruct(s.runs, use_table ? &s.table : nullptr, w, h, s.rows, next, out);
  if (st == DecodeStatus::Truncated && corrupt) return DecodeStatus::Corrupt;
  if (st != DecodeStatus::Ok) return st;
  if ((br.consumed_bits() + 7) / 8 != res.size()) return DecodeStatus::Corrupt;
  return DecodeStatus::Ok;
}

}  // namespace telex::proto::detail
