// SPDX-License-Identifier: MIT
// Lossless depth codecs: raw LE16, "zip" (prediction + deflate), "fast" (prediction + Rice bits).
#include "telex/proto/depth_codec.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <stdexcept>
#include <string>

#include "byte_io.h"
#include "depth_transform.h"

namespace telex::proto {

std::string_view codec_name(Codec codec) {
  switch (codec) {
    case Codec::Raw:
      return "raw";
    case Codec::Zip:
      return "zip";
    case Codec::Fast:
      return "fast";
  }
  return "unknown";
}

std::optional<Codec> parse_codec(std::string_view name) {
  for (int i = 0; i < kCodecCount; ++i) {
    const auto c = static_cast<Codec>(i);
    if (codec_name(c) == name) return c;
  }
  return std::nullopt;
}

bool is_valid_codec(std::uint8_t wire_value) { return wire_value < kCodecCount; }

std::string_view decode_status_name(DecodeStatus status) {
  switch (status) {
    case DecodeStatus::Ok:
      return "ok";
    case DecodeStatus::Truncated:
      return "truncated";
    case DecodeStatus::DecompressionBomb:
      return "decompression bomb";
    case DecodeStatus::Corrupt:
      return "corrupt";
    case DecodeStatus::BadGeometry:
      return "bad geometry";
    case DecodeStatus::UnknownCodec:
      return "unknown codec";
  }
  return "unknown";
}

namespace {

std::vector<std::uint8_t> encode_raw(const cv::Mat1w& tile) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(tile.rows) * tile.cols * 2);
  std::uint8_t* o = out.data();
  for (int y = 0; y < tile.rows; ++y) {
    const std::uint16_t* row = tile[y];
    for (int x = 0; x < tile.cols; ++x) {
      *o++ = static_cast<std::uint8_t>(row[x]);
      *o++ = static_cast<std::uint8_t>(row[x] >> 8);
    }
  }
  return out;
}

DecodeStatus decode_raw(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out) {
  const std::size_t need = static_cast<std::size_t>(w) * h * 2;
  if (bytes.size() < need) return DecodeStatus::Truncated;
  if (bytes.size() > need) return DecodeStatus::DecompressionBomb;
  const std::uint8_t* p = bytes.data();
  for (int y = 0; y < h; ++y) {
    std::uint16_t* row = out[y];
    for (int x = 0; x < w; ++x, p += 2) row[x] = static_cast<std::uint16_t>(p[0] | (p[1] << 8));
  }
  return DecodeStatus::Ok;
}

}  // namespace

std::vector<std::uint8_t> encode_depth(const cv::Mat1w& tile, Codec codec, int zip_level) {
  if (tile.empty()) throw std::invalid_argument("encode_depth: empty depth tile");
  if (tile.cols > kMaxDepthSide || tile.rows > kMaxDepthSide)
    throw std::invalid_argument("encode_depth: depth tile larger than 4096 on a side");
  switch (codec) {
    case Codec::Raw:
      return encode_raw(tile);
    case Codec::Zip:
      if (zip_level < 0 || zip_level > 9)
        throw std::invalid_argument("encode_depth: zip level must be 0..9, got " +
                                    std::to_string(zip_level));
      return detail::encode_zip(tile, zip_level);
    case Codec::Fast:
      return detail::encode_fast(tile);
  }
  throw std::invalid_argument("encode_depth: unknown codec");
}

DecodeStatus decode_depth(std::span<const std::uint8_t> bytes, int w, int h, Codec codec,
                          cv::Mat1w& out) {
  if (w <= 0 || h <= 0 || w > kMaxDepthSide || h > kMaxDepthSide) return DecodeStatus::BadGeometry;
  if (!is_valid_codec(static_cast<std::uint8_t>(codec))) return DecodeStatus::UnknownCodec;
  if (out.rows != h || out.cols != w) out.create(h, w);
  switch (codec) {
    case Codec::Raw:
      return decode_raw(bytes, w, h, out);
    case Codec::Zip:
      return detail::decode_zip(bytes, w, h, out);
    case Codec::Fast:
      return detail::decode_fast(bytes, w, h, out);
  }
  return DecodeStatus::UnknownCodec;
}

bool TileGrid::valid() const {
  return frame_width > 0 && frame_height > 0 && tile_width > 0 && tile_height > 0 &&
         frame_width <= kMaxDepthSide && frame_height <= kMaxDepthSide &&
         tile_width <= frame_width && tile_height <= frame_height && count() <= 65536;
}

cv::Rect TileGrid::rect(int index) const {
  const int cx = index % cols();
  const int cy = index / cols();
  const int x = cx * tile_width;
  const int y = cy * tile_height;
  return {x, y, std::min(tile_width, frame_width - x), std::min(tile_height, frame_height - y)};
}

std::vector<EncodedTile> encode_tiles(const cv::Mat1w& frame, const TileGrid& grid, Codec codec,
                                      int zip_level) {
  if (!grid.valid()) throw std::invalid_argument("encode_tiles: invalid tile grid");
  if (frame.cols != grid.frame_width || frame.rows != grid.frame_height)
    throw std::invalid_argument("encode_tiles: frame size differs from the tile grid");
  std::vector<EncodedTile> tiles;
  tiles.reserve(static_cast<std::size_t>(grid.count()));
  for (int i = 0; i < grid.count(); ++i) {
    const cv::Rect r = grid.rect(i);
    tiles.push_back({static_cast<std::uint16_t>(i), r, encode_depth(frame(r), codec, zip_level)});
  }
  return tiles;
}

DecodeStatus decode_tile_into(std::span<const std::uint8_t> bytes, const TileGrid& grid, int index,
                              Codec codec, cv::Mat1w& frame) {
  if (!grid.valid() || index < 0 || index >= grid.count() || frame.cols != grid.frame_width ||
      frame.rows != grid.frame_height)
    return DecodeStatus::BadGeometry;
  const cv::Rect r = grid.rect(index);
  // Decode into a scratch tile so a corrupt tile never leaves half-written pixels in the frame.
  cv::Mat1w tile;
  const DecodeStatus s = decode_depth(bytes, r.width, r.height, codec, tile);
  if (s == DecodeStatus::Ok) tile.copyTo(frame(r));
  return s;
}

}  // namespace telex::proto
