// SPDX-License-Identifier: MIT
// Lossless depth codecs (raw, "zip" deflate with prediction, "fast" RVL-like) and the tile grid.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace telex::proto {

// Wire values are fixed (docs/PROTOCOL.md); never renumber.
enum class Codec : std::uint8_t { Raw = 0, Zip = 1, Fast = 2 };
inline constexpr int kCodecCount = 3;

std::string_view codec_name(Codec codec);                 // "raw" | "zip" | "fast"
std::optional<Codec> parse_codec(std::string_view name);  // inverse of codec_name
bool is_valid_codec(std::uint8_t wire_value);

enum class DecodeStatus : std::uint8_t {
  Ok = 0,
  Truncated,          // the bitstream ended before the w*h pixels were produced
  DecompressionBomb,  // the bitstream claims more (or other) output than w*h pixels
  Corrupt,            // inconsistent bitstream (bad flags, index out of table, trailing bytes)
  BadGeometry,        // w or h out of range
  UnknownCodec,
};
std::string_view decode_status_name(DecodeStatus status);

// Zip codec effort: 0 = Huffman-only deflate (no LZ77 matching), 1..9 = zlib levels with the
// default strategy. Any of them decodes with any inflater. The default was chosen by measurement
// (docs/BENCHMARKS.md "## Codecs"): on packed residuals matching costs time and gains nothing.
inline constexpr int kDefaultZipLevel = 0;
// Largest tile/frame side any decoder accepts; bounds every allocation a decoder makes.
inline constexpr int kMaxDepthSide = 4096;

// Encodes any CV_16UC1 matrix (continuous or an ROI view). zip_level 0..9 applies to Codec::Zip.
// Throws std::invalid_argument on an empty matrix or a level out of range (start-up/bad-input
// tier).
std::vector<std::uint8_t> encode_depth(const cv::Mat1w& tile, Codec codec,
                                       int zip_level = kDefaultZipLevel);

// Decodes exactly w*h pixels into `out` (reallocated to h x w when its shape differs). Never
// throws on bad bytes, never writes or allocates beyond w*h pixels plus bounded scratch.
DecodeStatus decode_depth(std::span<const std::uint8_t> bytes, int w, int h, Codec codec,
                          cv::Mat1w& out);

// A frame cut into a grid of tiles (row-major indices); edge tiles are smaller when the frame
// size is not a multiple of the tile size. Every tile is encoded and decodable alone.
struct TileGrid {
  int frame_width = 640;
  int frame_height = 480;
  int tile_width = 80;
  int tile_height = 60;

  int cols() const { return (frame_width + tile_width - 1) / tile_width; }
  int rows() const { return (frame_height + tile_height - 1) / tile_height; }
  int count() const { return cols() * rows(); }
  bool valid() const;
  cv::Rect rect(int index) const;  // pixel rectangle of tile `index` (0 <= index < count())
};

struct EncodedTile {
  std::uint16_t index = 0;
  cv::Rect rect;
  std::vector<std::uint8_t> bytes;
};

// Encodes every tile of `frame` (whose size must match the grid).
std::vector<EncodedTile> encode_tiles(const cv::Mat1w& frame, const TileGrid& grid, Codec codec,
                                      int zip_level = kDefaultZipLevel);

// Decodes one tile into its place in `frame` (which must be grid-sized CV_16UC1).
DecodeStatus decode_tile_into(std::span<const std::uint8_t> bytes, const TileGrid& grid, int index,
                              Codec codec, cv::Mat1w& frame);

// Reference RVL (Wilson 2017), implemented from the paper for comparison only: a peer, not a
// wire codec. Decoding is bounded like the wire codecs.
std::vector<std::uint8_t> rvl_ref_encode(const cv::Mat1w& depth);
DecodeStatus rvl_ref_decode(std::span<const std::uint8_t> bytes, int w, int h, cv::Mat1w& out);

}  // namespace telex::proto
