// SPDX-License-Identifier: MIT
// "fast" depth codec: RVL's idea (runs of holes, each valid pixel against the previous valid one)
// with a value table and Rice codes in place of nibbles. Built to encode faster than RVL itself.
#include <algorithm>

#include "byte_io.h"
#include "depth_transform.h"

namespace telex::proto::detail {
namespace {

constexpr std::uint8_t kFlagTable = 0x01;
constexpr int kKShift = 1;        // bits 1-4: Rice parameter k (0..15)
constexpr int kEscape = 20;       // unary prefix length that announces a raw 17-bit residual
constexpr int kRawBits = 17;      // a zigzag residual of two 16-bit values fits in 17 bits
constexpr int kMaxRunZeros = 28;  // exp-Golomb prefix bound: 2*28+1 bits fit one peek
// Four unary codes of residuals below this fit one 56-bit put (4 x 14 bits).
constexpr std::uint32_t kQuadLimit = 14;

struct FastScratch {
  std::vector<std::uint8_t> runs_bits;
  std::vector<std::uint8_t> res_bits;
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

// Rice code of z with parameter k: q = z >> k zero bits, a one bit, the k low bits of z; or the
// escape (20 zero bits, a one bit, z in 17 bits) when q >= 20.
inline void put_rice(BitWriter& bw, std::uint32_t z, int k) {
  const std::uint32_t q = z >> k;
  if (q < kEscape) {
    bw.put((std::uint64_t{1} << q) | (static_cast<std::uint64_t>(z & low_mask(k)) << (q + 1)),
           static_cast<int>(q) + 1 + k);
  } else {
    bw.put((std::uint64_t{1} << kEscape) | (static_cast<std::uint64_t>(z) << (kEscape + 1)),
           kEscape + 1 + kRawBits);
  }
}

// True when none of the four u16 lanes of q is zero (the classic has-zero-byte test on lanes).
inline bool no_zero_lane(std::uint64_t q) {
  return ((q - 0x0001000100010001ull) & ~q & 0x8000800080008000ull) == 0;
}

// Without a table the residuals are millimetre steps: k from their mean (the JPEG-LS rule, the
// smallest k with n * 2^k >= sum), measured in a pass of its own. Table tiles use k = 0.
int rice_k_for(const cv::Mat1w& img, std::size_t n_valid) {
  if (n_valid == 0) return 0;
  std::uint64_t sum = 0;
  std::int32_t prev = 0;
  for (int y = 0; y < img.rows; ++y) {
    const std::uint16_t* row = img[y];
    for (int x = 0; x < img.cols; ++x) {
      const std::uint16_t v = row[x];
      if (v == 0) continue;
      sum += zigzag(v - prev);
      prev = v;
    }
  }
  int k = 0;
  while (k < 15 && (static_cast<std::uint64_t>(n_valid) << k) < sum) ++k;
  return k;
}

// The encoder's pixel loop. Runs of four valid pixels (most of a structured-light frame) take a
// branch-free path: one has-zero test, four table look-ups and, for k = 0, one bit-writer put for
// all four unary codes.
template <bool Table>
void encode_pixels(const cv::Mat1w& img, const std::uint16_t* index_of, int k, BitWriter& rw,
                   BitWriter& bw) {
  auto symbol = [&](std::uint16_t v) -> std::int32_t {
    if constexpr (Table) {
      return index_of[v];
    } else {
      return v;
    }
  };
  const int w = img.cols;
  std::int32_t prev = 0;
  bool in_valid = true;
  std::uint32_t len = 0;
  for (int y = 0; y < img.rows; ++y) {
    const std::uint16_t* row = img[y];
    int x = 0;
    while (x < w) {
      if (in_valid && x + 4 <= w) {
        std::uint64_t quad;
        std::memcpy(&quad, row + x, 8);
        if (no_zero_lane(quad)) {
          const std::int32_t s0 = symbol(row[x]), s1 = symbol(row[x + 1]);
          const std::int32_t s2 = symbol(row[x + 2]), s3 = symbol(row[x + 3]);
          const std::uint32_t z0 = zigzag(s0 - prev), z1 = zigzag(s1 - s0);
          const std::uint32_t z2 = zigzag(s2 - s1), z3 = zigzag(s3 - s2);
          prev = s3;
          if (k == 0 && (z0 | z1 | z2 | z3) < kQuadLimit) {
            const std::uint32_t o1 = z0 + 1, o2 = o1 + z1 + 1, o3 = o2 + z2 + 1;
            bw.put((std::uint64_t{1} << z0) | (std::uint64_t{1} << (o1 + z1)) |
                       (std::uint64_t{1} << (o2 + z2)) | (std::uint64_t{1} << (o3 + z3)),
                   static_cast<int>(o3 + z3 + 1));
          } else {
            put_rice(bw, z0, k);
            put_rice(bw, z1, k);
            put_rice(bw, z2, k);
            put_rice(bw, z3, k);
          }
          len += 4;
          x += 4;
          continue;
        }
      }
      const std::uint16_t v = row[x];
      const bool valid = v != 0;
      if (valid != in_valid) {
        put_eg0(rw, len);
        len = 0;
        in_valid = valid;
      }
      ++len;
      if (valid) {
        const std::int32_t s = symbol(v);
        put_rice(bw, zigzag(s - prev), k);
        prev = s;
      }
      ++x;
    }
  }
  put_eg0(rw, len);
}

}  // namespace

std::vector<std::uint8_t> encode_fast(const cv::Mat1w& img) {
  FastScratch& s = scratch();
  const Analysis& a = analyse(img);
  const std::size_t total = static_cast<std::size_t>(img.rows) * img.cols;
  // Worst cases: 7 bytes per run (at most total + 1 runs), 5 bytes per residual, 8 bytes slack.
  if (s.runs_bits.size() < total * 7 + 16) s.runs_bits.resize(total * 7 + 16);
  if (s.res_bits.size() < a.n_valid * 5 + 16) s.res_bits.resize(a.n_valid * 5 + 16);

  const int k = a.use_table ? 0 : rice_k_for(img, a.n_valid);
  BitWriter rw(s.runs_bits.data());
  BitWriter bw(s.res_bits.data());
  if (a.use_table) {
    encode_pixels<true>(img, a.index_of, k, rw, bw);
  } else {
    encode_pixels<false>(img, nullptr, k, rw, bw);
  }
  const std::size_t runs_len = rw.finish();
  const std::size_t res_len = bw.finish();

  std::vector<std::uint8_t> out;
  out.reserve(1 + 4 + runs_len + res_len + (a.use_table ? a.table.size() * 5 + 16 : 0));
  out.push_back(static_cast<std::uint8_t>((a.use_table ? kFlagTable : 0) | (k << kKShift)));
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
  if (flags & 0xE0) return DecodeStatus::Corrupt;
  const bool use_table = flags & kFlagTable;
  const int k = (flags >> kKShift) & 0x0F;
  FastScratch& s = scratch();
  std::size_t pos = 1;
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

  BitReader br(bytes.subspan(pos + runs_len));
  const std::int64_t lo = use_table ? 0 : 1;
  const std::int64_t hi = use_table ? static_cast<std::int64_t>(s.table.size()) - 1 : 65535;
  const std::uint16_t* table = s.table.data();
  std::int64_t prev = 0;
  std::size_t ri = 0;
  std::uint32_t left_in_run = s.runs[0];
  bool valid = true;
  for (int y = 0; y < h; ++y) {
    std::uint16_t* row = out[y];
    int x = 0;
    while (x < w) {
      while (left_in_run == 0) {
        ++ri;
        valid = !valid;
        left_in_run = s.runs[ri];
      }
      const int n = static_cast<int>(std::min<std::uint32_t>(left_in_run, w - x));
      left_in_run -= static_cast<std::uint32_t>(n);
      if (!valid) {
        std::fill_n(row + x, n, std::uint16_t{0});
        x += n;
        continue;
      }
      for (const int end = x + n; x < end; ++x) {
        const std::uint64_t bits = br.peek();
        const int q = bits == 0 ? 64 : std::countr_zero(bits);
        std::uint32_t z = 0;
        if (q < kEscape) {
          z = (static_cast<std::uint32_t>(q) << k) |
              static_cast<std::uint32_t>((bits >> (q + 1)) & low_mask(k));
          br.skip(q + 1 + k);
        } else if (q == kEscape) {
          z = static_cast<std::uint32_t>((bits >> (kEscape + 1)) & low_mask(kRawBits));
          br.skip(kEscape + 1 + kRawBits);
        } else {
          // Past the end bits read as zero: a prefix running off the end is a short stream.
          return br.consumed_bits() + kEscape + 1 > br.size_bits() ? DecodeStatus::Truncated
                                                                   : DecodeStatus::Corrupt;
        }
        if (br.overrun()) return DecodeStatus::Truncated;
        const std::int64_t cur = prev + unzigzag(z);
        if (cur < lo || cur > hi) return DecodeStatus::Corrupt;
        row[x] = use_table ? table[cur] : static_cast<std::uint16_t>(cur);
        prev = cur;
      }
    }
  }
  return br.exactly_consumed() ? DecodeStatus::Ok : DecodeStatus::Corrupt;
}

}  // namespace telex::proto::detail
