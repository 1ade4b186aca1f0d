// SPDX-License-Identifier: MIT
// "zip" depth codec: value table, then hole runs + MED residuals packed in bytes, deflated (zlib).
#include <zlib.h>

#include <algorithm>
#include <array>
#include <stdexcept>

#include "byte_io.h"
#include "depth_transform.h"

namespace telex::proto::detail {
namespace {

constexpr std::uint8_t kFlagTable = 0x01;
constexpr int kBitsShift = 1;  // bits 1-2: log2 of the packed symbol width (1..3)

// One deflate state per thread, reset between calls: deflateInit costs far more than a tile.
struct Deflater {
  z_stream zs{};
  int level = -1;
  ~Deflater() {
    if (level >= 0) deflateEnd(&zs);
  }
  z_stream& get(int want) {
    if (level != want) {
      if (level >= 0) deflateEnd(&zs);
      zs = z_stream{};
      // Level 0 selects Huffman-only deflate: on packed residuals LZ77 matching costs time and
      // gains nothing (docs/BENCHMARKS.md "## Codecs").
      const int strategy = want == 0 ? Z_HUFFMAN_ONLY : Z_DEFAULT_STRATEGY;
      if (deflateInit2(&zs, want == 0 ? 1 : want, Z_DEFLATED, -15, 8, strategy) != Z_OK)
        throw std::runtime_error("zip codec: deflateInit2 failed");
      level = want;
    } else {
      deflateReset(&zs);
    }
    return zs;
  }
};

struct Inflater {
  z_stream zs{};
  bool ready = false;
  ~Inflater() {
    if (ready) inflateEnd(&zs);
  }
  z_stream* get() {
    if (!ready) {
      zs = z_stream{};
      if (inflateInit2(&zs, -15) != Z_OK) return nullptr;
      ready = true;
    } else {
      inflateReset(&zs);
    }
    return &zs;
  }
};

struct ZipScratch {
  std::vector<std::uint8_t> body;
  std::vector<std::uint8_t> packed2;
  std::vector<std::uint8_t> over2;
  std::vector<std::uint32_t> residuals;
  std::vector<std::int32_t> rows;
  std::vector<std::uint32_t> runs;
  std::vector<std::uint16_t> table;
};

ZipScratch& scratch() {
  thread_local ZipScratch s;
  return s;
}

}  // namespace

namespace {

// Symbols of `bits` (2, 4 or 8) packed low bits first; a saturated symbol (all ones) is followed
// in the overflow stream by a varint of the excess. Packing several residuals per byte lets
// deflate's byte-wise Huffman code them jointly, below its one-bit-per-symbol floor.
std::size_t varint_len(std::uint32_t v) {
  return v < (1u << 7) ? 1 : v < (1u << 14) ? 2 : v < (1u << 21) ? 3 : v < (1u << 28) ? 4 : 5;
}

template <int Bits>
void pack(const std::vector<std::uint32_t>& z, std::uint8_t* out) {
  constexpr std::uint32_t kSat = (1u << Bits) - 1;
  constexpr int kPer = 8 / Bits;
  const std::size_t n = z.size();
  std::size_t i = 0;
  for (; i + kPer <= n; i += kPer) {
    std::uint32_t byte = 0;
    for (int j = 0; j < kPer; ++j) byte |= std::min(z[i + j], kSat) << (Bits * j);
    *out++ = static_cast<std::uint8_t>(byte);
  }
  if (i < n) {
    std::uint32_t byte = 0;
    for (int j = 0; i + j < n; ++j) byte |= std::min(z[i + j], kSat) << (Bits * j);
    *out = static_cast<std::uint8_t>(byte);
  }
}

}  // namespace

std::vector<std::uint8_t> encode_zip(const cv::Mat1w& img, int level) {
  ZipScratch& s = scratch();
  const Analysis& a = analyse(img);
  s.runs.clear();
  // Speculate on 2-bit symbols (what structured-light depth picks): pack them during the
  // prediction pass itself and only tally what 4- and 8-bit packing would cost.
  s.packed2.resize((a.n_valid * 2 + 7) / 8 + 1);
  s.over2.clear();
  std::uint8_t* pk = s.packed2.data();
  std::uint32_t acc = 0;
  int filled = 0;
  std::size_t over4 = 0, over8 = 0;
  predict(
      img, a.index_of, s.rows,
      [&](std::uint32_t z) {
        acc |= std::min(z, 3u) << (2 * filled);
        if (++filled == 4) {
          *pk++ = static_cast<std::uint8_t>(acc);
          acc = 0;
          filled = 0;
        }
        if (z >= 3) {
          put_varint(s.over2, z - 3);
          if (z >= 15) {
            over4 += varint_len(z - 15);
            if (z >= 255) over8 += varint_len(z - 255);
          }
        }
      },
      [&](std::uint32_t r) { s.runs.push_back(r); });
  if (filled) *pk++ = static_cast<std::uint8_t>(acc);
  const std::size_t n = a.n_valid;
  const std::size_t cost2 = (n * 2 + 7) / 8 + s.over2.size();
  const std::size_t cost4 = (n * 4 + 7) / 8 + over4;
  const std::size_t cost8 = n + over8;
  const int bits = cost2 <= cost4 && cost2 <= cost8 ? 2 : cost4 <= cost8 ? 4 : 8;

  std::vector<std::uint8_t>& body = s.body;
  body.clear();
  for (std::uint32_t r : s.runs) put_varint(body, r);
  if (bits == 2) {
    body.insert(body.end(), s.packed2.begin(), s.packed2.begin() + (n * 2 + 7) / 8);
    body.insert(body.end(), s.over2.begin(), s.over2.end());
  } else {
    // Noise-like tiles: run the prediction again into a residual buffer for the wider packing.
    s.residuals.resize(n);
    std::uint32_t* res = s.residuals.data();
    predict(
        img, a.index_of, s.rows, [&](std::uint32_t z) { *res++ = z; }, [](std::uint32_t) {});
    const std::uint32_t sat = (1u << bits) - 1;
    const std::size_t base = body.size();
    body.resize(base + (n * bits + 7) / 8);
    if (bits == 4) pack<4>(s.residuals, body.data() + base);
    if (bits == 8) pack<8>(s.residuals, body.data() + base);
    for (std::uint32_t z : s.residuals)
      if (z >= sat) put_varint(body, z - sat);
  }

  thread_local Deflater deflater;
  z_stream& zs = deflater.get(level);
  // Header: flags, varint body length, the value table (its own bit stream: deflate's byte-wise
  // Huffman code, shared with the packed residuals, would spend more on it); then raw deflate
  // (RFC 1951). The message CRC32C already guards the bytes, so zlib's wrapper and Adler-32
  // would be 6 bytes per tile for nothing.
  std::vector<std::uint8_t> out;
  out.push_back(0);
  put_varint(out, static_cast<std::uint32_t>(body.size()));
  if (a.use_table) put_table(out, a.table);
  const std::size_t header = out.size();
  out.resize(header + deflateBound(&zs, body.size()));
  const int bits_code = bits == 2 ? 1 : bits == 4 ? 2 : 3;
  out[0] = static_cast<std::uint8_t>((a.use_table ? kFlagTable : 0) | (bits_code << kBitsShift));
  zs.next_in = body.data();
  zs.avail_in = static_cast<uInt>(body.size());
  zs.next_out = out.data() + header;
  zs.avail_out = static_cast<uInt>(out.size() - header);
  if (deflate(&zs, Z_FINISH) != Z_STREAM_END) throw std::runtime_error("zip codec: deflate failed");
  out.resize(header + zs.total_out);
  return out;
}

namespace {

template <int Bits>
DecodeStatus unpack(ZipScratch& s, std::span<const std::uint8_t> body, const std::uint8_t* packed,
                    std::size_t over, int w, int h, bool use_table, cv::Mat1w& out) {
  constexpr std::uint32_t kSat = (1u << Bits) - 1;
  constexpr int kPer = 8 / Bits;
  std::size_t i = 0;
  bool short_overflow = false;
  auto next = [&](std::uint32_t& z) {
    z = (packed[i / kPer] >> (Bits * (i % kPer))) & kSat;
    ++i;
    if (z == kSat) {
      std::uint32_t e = 0;
      if (!get_varint(body, over, e)) {
        short_overflow = true;
        return false;
      }
      z = kSat + e;  // wraps only on a corrupt stream, which reconstruct() rejects by range
    }
    return true;
  };
  const DecodeStatus st =
      reconstruct(s.runs, use_table ? &s.table : nullptr, w, h, s.rows, next, out);
  if (st != DecodeStatus::Ok) return short_overflow ? DecodeStatus::Truncated : st;
  return over == body.size() ? DecodeStatus::Ok : DecodeStatus::Corrupt;
}

}  // namespace

DecodeStatus decode_zip(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out) {
  if (bytes.empty()) return DecodeStatus::Truncated;
  const std::uint8_t flags = bytes[0];
  if (flags & ~0x07u) return DecodeStatus::Corrupt;
  const int bits_code = (flags >> kBitsShift) & 3;
  if (bits_code == 0) return DecodeStatus::Corrupt;
  const int bits = 1 << bits_code;
  const bool use_table = flags & kFlagTable;
  std::size_t header = 1;
  std::uint32_t body_len = 0;
  if (!get_varint(bytes, header, body_len)) return DecodeStatus::Truncated;
  ZipScratch& s = scratch();
  if (use_table) {
    const DecodeStatus t = get_table(bytes, header, s.table);
    if (t != DecodeStatus::Ok) return t;
  }
  const std::size_t total = static_cast<std::size_t>(w) * h;
  // Largest body a w x h tile can need: a 5-byte varint per run (at most w*h + 1 runs), one byte
  // of packed symbols and a 5-byte overflow varint per pixel.
  const std::size_t bound = total * 5 + 5 + total + total * 5;
  if (body_len > bound) return DecodeStatus::DecompressionBomb;

  s.body.resize(body_len);
  thread_local Inflater inflater;
  z_stream* zs = inflater.get();
  if (!zs) return DecodeStatus::Corrupt;
  zs->next_in = const_cast<Bytef*>(bytes.data() + header);
  zs->avail_in = static_cast<uInt>(bytes.size() - header);
  zs->next_out = s.body.data();
  zs->avail_out = body_len;
  const int ret = inflate(zs, Z_FINISH);
  if (ret == Z_STREAM_END) {
    if (zs->total_out != body_len) return DecodeStatus::Truncated;
    if (zs->avail_in != 0) return DecodeStatus::Corrupt;
  } else if (ret == Z_BUF_ERROR && zs->avail_out == 0) {
    return DecodeStatus::DecompressionBomb;  // more output than the claimed body length
  } else if (ret == Z_BUF_ERROR) {
    return DecodeStatus::Truncated;
  } else {
    return DecodeStatus::Corrupt;
  }

  const std::span<const std::uint8_t> body(s.body);
  std::size_t pos = 0;
  s.runs.clear();
  std::size_t covered = 0;
  while (covered < total) {
    std::uint32_t r = 0;
    if (!get_varint(body, pos, r)) return DecodeStatus::Truncated;
    if (r > total - covered) return DecodeStatus::Corrupt;
    s.runs.push_back(r);
    covered += r;
  }
  if (!runs_valid(s.runs, total)) return DecodeStatus::Corrupt;
  std::size_t n_valid = 0;
  for (std::size_t i = 0; i < s.runs.size(); i += 2) n_valid += s.runs[i];
  const std::size_t packed_len = (n_valid * bits + 7) / 8;
  if (body.size() - pos < packed_len) return DecodeStatus::Truncated;
  const std::uint8_t* packed = body.data() + pos;
  const std::size_t over = pos + packed_len;
  switch (bits) {
    case 2:
      return unpack<2>(s, body, packed, over, w, h, use_table, out);
    case 4:
      return unpack<4>(s, body, packed, over, w, h, use_table, out);
    default:
      return unpack<8>(s, body, packed, over, w, h, use_table, out);
  }
}

}  // namespace telex::proto::detail
