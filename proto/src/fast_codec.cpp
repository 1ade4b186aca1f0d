// SPDX-License-Identifier: MIT
// "fast" depth codec: RVL's run idea with a value table, MED prediction and adaptive Rice bits.
#include <algorithm>

#include "byte_io.h"
#include "depth_transform.h"

namespace telex::proto::detail {
namespace {

constexpr std::uint8_t kFlagTable = 0x01;
constexpr int kEscape = 20;   // unary prefix length that announces a raw 17-bit residual
constexpr int kRawBits = 17;  // a zigzag residual of two 16-bit values fits in 17 bits
constexpr int kMeanShift = 5;
constexpr int kMaxRunZeros = 28;  // exp-Golomb prefix bound: 2*28+1 bits fit one peek

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

// Exp-Golomb order 0 of v, LSB-first: z = floor(log2(v+1)) zero bits, a one bit, then the z low
// bits of v + 1.
void put_eg0(BitWriter& bw, std::uint32_t v) {
  const std::uint32_t u = v + 1;
  const int z = static_cast<int>(std::bit_width(u)) - 1;
  bw.put((std::uint64_t{1} << z) | (static_cast<std::uint64_t>(u & low_mask(z)) << (z + 1)),
         2 * z + 1);
}

bool get_eg0(BitReader& br, std::uint32_t& v) {
  const std::uint64_t w = br.peek();
  const int z = w == 0 ? 64 : std::countr_zero(w);
  if (z > kMaxRunZeros) return false;
  const std::uint64_t u = (std::uint64_t{1} << z) | ((w >> (z + 1)) & low_mask(z));
  br.skip(2 * z + 1);
  v = static_cast<std::uint32_t>(u - 1);
  return true;
}

// Rice parameter from an exponential moving average of the residuals (a ~ 16 x mean): a shift
// and a bit_width, identical in encoder and decoder.
struct Rice {
  std::uint32_t a = 16;
  int k() const { return std::min(16, static_cast<int>(std::bit_width(a >> kMeanShift))); }
  void update(std::uint32_t z) { a = a - (a >> 4) + z; }
};

}  // namespace

std::vector<std::uint8_t> encode_fast(const cv::Mat1w& img) {
  FastScratch& s = scratch();
  const Analysis& a = analyse(img);
  const std::size_t total = static_cast<std::size_t>(img.rows) * img.cols;
  // Worst cases: 7 bytes per run (at most total + 1 runs), 5 bytes per residual, 8 bytes slack.
  if (s.runs_bits.size() < total * 7 + 16) s.runs_bits.resize(total * 7 + 16);
  if (s.res_bits.size() < a.n_valid * 5 + 16) s.res_bits.resize(a.n_valid * 5 + 16);

  BitWriter rw(s.runs_bits.data());
  BitWriter bw(s.res_bits.data());
  Rice rice;
  predict(
      img, a.index_of, s.rows,
      [&](std::uint32_t z) {
        const int k = rice.k();
        const std::uint32_t q = z >> k;
        if (q < kEscape) {
          bw.put((std::uint64_t{1} << q) | (static_cast<std::uint64_t>(z & low_mask(k)) << (q + 1)),
                 static_cast<int>(q) + 1 + k);
        } else {
          bw.put((std::uint64_t{1} << kEscape) | (static_cast<std::uint64_t>(z) << (kEscape + 1)),
                 kEscape + 1 + kRawBits);
        }
        rice.update(z);
      },
      [&](std::uint32_t run) { put_eg0(rw, run); });
  const std::size_t runs_len = rw.finish();
  const std::size_t res_len = bw.finish();

  std::vector<std::uint8_t> out;
  out.reserve(1 + 4 + runs_len + res_len + (a.use_table ? a.table.size() * 3 + 10 : 0));
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
    if (!get_eg0(rr, r)) return rr.overrun() ? DecodeStatus::Truncated : DecodeStatus::Corrupt;
    if (rr.overrun()) return DecodeStatus::Truncated;
    if (r > total - covered) return DecodeStatus::Corrupt;
    s.runs.push_back(r);
    covered += r;
  }
  if (!runs_valid(s.runs, total) || !rr.exactly_consumed()) return DecodeStatus::Corrupt;

  const auto res = bytes.subspan(pos + runs_len);
  BitReader br(res);
  Rice rice;
  bool corrupt = false;
  auto next = [&](std::uint32_t& z) {
    const int k = rice.k();
    const std::uint64_t bits = br.peek();
    const int q = bits == 0 ? 64 : std::countr_zero(bits);
    if (q < kEscape) {
      z = (static_cast<std::uint32_t>(q) << k) |
          static_cast<std::uint32_t>((bits >> (q + 1)) & low_mask(k));
      br.skip(q + 1 + k);
    } else if (q == kEscape) {
      z = static_cast<std::uint32_t>((bits >> (kEscape + 1)) & low_mask(kRawBits));
      br.skip(kEscape + 1 + kRawBits);
    } else {
      corrupt = true;
      return false;
    }
    if (br.overrun()) return false;
    rice.update(z);
    return true;
  };
  const DecodeStatus st =
      reconstruct(s.runs, use_table ? &s.table : nullptr, w, h, s.rows, next, out);
  if (st == DecodeStatus::Truncated && corrupt && !br.overrun()) return DecodeStatus::Corrupt;
  if (st != DecodeStatus::Ok) return st;
  return br.exactly_consumed() ? DecodeStatus::Ok : DecodeStatus::Corrupt;
}

}  // namespace telex::proto::detail
