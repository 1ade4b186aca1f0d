// SPDX-License-Identifier: MIT
// "zip" depth codec: hole runs + value table + MED residual byte planes, then deflate (zlib).
#include <zlib.h>

#include <algorithm>
#include <stdexcept>

#include "byte_io.h"
#include "depth_transform.h"

namespace telex::proto::detail {
namespace {

constexpr std::uint8_t kFlagTable = 0x01;
constexpr int kPlanesShift = 1;  // bits 1-2: byte planes - 1
constexpr std::size_t kZipHeader = 5;

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
      if (deflateInit2(&zs, want, Z_DEFLATED, 15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
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
      if (inflateInit(&zs) != Z_OK) return nullptr;
      ready = true;
    } else {
      inflateReset(&zs);
    }
    return &zs;
  }
};

struct ZipScratch {
  std::vector<std::uint8_t> body;
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

std::vector<std::uint8_t> encode_zip(const cv::Mat1w& img, int level) {
  ZipScratch& s = scratch();
  const Analysis& a = analyse(img);
  s.residuals.clear();
  s.residuals.reserve(a.n_valid);
  std::uint32_t zmax = 0;
  predict(img, a.index_of, s.rows, [&](std::uint32_t z) {
    s.residuals.push_back(z);
    zmax |= z;
  });
  const int planes = zmax < 0x100 ? 1 : zmax < 0x10000 ? 2 : 3;

  std::vector<std::uint8_t>& body = s.body;
  body.clear();
  for (std::uint32_t r : a.runs) put_varint(body, r);
  if (a.use_table) put_table(body, a.table);
  const std::size_t base = body.size();
  body.resize(base + a.n_valid * static_cast<std::size_t>(planes));
  // Byte planes: deflate sees long runs of small low bytes, and the high planes are mostly zero.
  for (int p = 0; p < planes; ++p) {
    std::uint8_t* o = body.data() + base + a.n_valid * static_cast<std::size_t>(p);
    const int shift = 8 * p;
    for (std::size_t i = 0; i < a.n_valid; ++i)
      o[i] = static_cast<std::uint8_t>(s.residuals[i] >> shift);
  }

  thread_local Deflater deflater;
  z_stream& zs = deflater.get(level);
  std::vector<std::uint8_t> out(kZipHeader + deflateBound(&zs, body.size()));
  out[0] =
      static_cast<std::uint8_t>((a.use_table ? kFlagTable : 0) | ((planes - 1) << kPlanesShift));
  const auto body_len = static_cast<std::uint32_t>(body.size());
  for (int i = 0; i < 4; ++i) out[1 + i] = static_cast<std::uint8_t>(body_len >> (8 * i));
  zs.next_in = body.data();
  zs.avail_in = static_cast<uInt>(body.size());
  zs.next_out = out.data() + kZipHeader;
  zs.avail_out = static_cast<uInt>(out.size() - kZipHeader);
  if (deflate(&zs, Z_FINISH) != Z_STREAM_END) throw std::runtime_error("zip codec: deflate failed");
  out.resize(kZipHeader + zs.total_out);
  return out;
}

DecodeStatus decode_zip(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out) {
  if (bytes.size() < kZipHeader) return DecodeStatus::Truncated;
  const std::uint8_t flags = bytes[0];
  if (flags & ~0x07u) return DecodeStatus::Corrupt;
  const int planes = ((flags >> kPlanesShift) & 3) + 1;
  if (planes > 3) return DecodeStatus::Corrupt;
  const bool use_table = flags & kFlagTable;
  const std::uint32_t body_len = load_u32(bytes.data() + 1);
  const std::size_t total = static_cast<std::size_t>(w) * h;
  // Largest body a w x h tile can need: a 5-byte varint per run, a full table, three planes.
  const std::size_t bound = total * 5 + 5 + 65536 * 3 + 10 + total * 3;
  if (body_len > bound) return DecodeStatus::DecompressionBomb;

  ZipScratch& s = scratch();
  s.body.resize(body_len);
  thread_local Inflater inflater;
  z_stream* zs = inflater.get();
  if (!zs) return DecodeStatus::Corrupt;
  zs->next_in = const_cast<Bytef*>(bytes.data() + kZipHeader);
  zs->avail_in = static_cast<uInt>(bytes.size() - kZipHeader);
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
  if (use_table) {
    const DecodeStatus t = get_table(body, pos, s.table);
    if (t != DecodeStatus::Ok) return t;
  }
  const std::size_t need = n_valid * static_cast<std::size_t>(planes);
  if (body.size() - pos < need) return DecodeStatus::Truncated;
  if (body.size() - pos > need) return DecodeStatus::Corrupt;
  const std::uint8_t* p0 = body.data() + pos;
  std::size_t i = 0;
  auto next = [&](std::uint32_t& z) {
    z = p0[i];
    if (planes > 1) z |= static_cast<std::uint32_t>(p0[n_valid + i]) << 8;
    if (planes > 2) z |= static_cast<std::uint32_t>(p0[2 * n_valid + i]) << 16;
    ++i;
    return true;  // the plane length was checked above
  };
  return reconstruct(s.runs, use_table ? &s.table : nullptr, w, h, s.rows, next, out);
}

}  // namespace telex::proto::detail
