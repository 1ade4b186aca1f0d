// SPDX-License-Identifier: MIT
// Depth file loaders: 16-bit PNG (mm or TUM units) and 16-bit PGM raw Kinect disparity.
#include "telex/common/depth_io.h"

#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <vector>

namespace telex {
namespace {

constexpr int kRawInvalid = 2047;
constexpr int kRawNoDepth = 1092;  // 1092.5 - raw <= 0.5: beyond any representable depth

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& problem) {
  throw std::runtime_error("depth file " + file.string() + ": " + problem);
}

std::vector<std::uint8_t> read_all(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) fail(file, "no such file");
  if (!std::filesystem::is_regular_file(file, ec)) fail(file, "not a regular file");
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot be opened for reading");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad()) fail(file, "read error");
  if (bytes.empty()) fail(file, "file is empty (zero size)");
  return bytes;
}

Intrinsics fit_intrinsics(const Intrinsics& k, int width, int height) {
  if (k.width == width && k.height == height) return k;
  return k.scaled(width, height);
}

cv::Mat1w decode_png16(const std::vector<std::uint8_t>& bytes, const std::filesystem::path& file) {
  static constexpr std::array<std::uint8_t, 8> kMagic = {0x89, 'P',  'N',  'G',
                                                         '\r', '\n', 0x1A, '\n'};
  if (bytes.size() < kMagic.size() || std::memcmp(bytes.data(), kMagic.data(), kMagic.size()) != 0)
    fail(file, "wrong magic: not a PNG file");
  // IHDR sits at a fixed place: bit depth at byte 24, colour type at byte 25.
  if (bytes.size() < 33) fail(file, "truncated PNG (no complete IHDR chunk)");
  if (std::memcmp(bytes.data() + 12, "IHDR", 4) != 0)
    fail(file, "corrupt PNG: first chunk is not IHDR");
  const int bit_depth = bytes[24], colour_type = bytes[25];
  if (bit_depth != 16)
    fail(file, "not 16-bit: PNG bit depth is " + std::to_string(bit_depth) +
                   " (depth needs 16-bit greyscale)");
  if (colour_type != 0)
    fail(file, "not a single-channel image: PNG colour type " + std::to_string(colour_type) +
                   " (depth needs 16-bit greyscale)");
  const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8UC1,
                        const_cast<std::uint8_t*>(bytes.data()));
  cv::Mat img = cv::imdecode(encoded, cv::IMREAD_UNCHANGED | cv::IMREAD_ANYDEPTH);
  if (img.empty()) fail(file, "PNG could not be decoded (truncated or corrupt)");
  if (img.type() != CV_16UC1) fail(file, "decoded PNG is not 16-bit single-channel");
  return cv::Mat1w(img);
}

// Skips whitespace and '#' comments, then reads one unsigned decimal header field.
bool pgm_field(std::span<const std::uint8_t> b, std::size_t& pos, long& value) {
  for (;;) {
    while (pos < b.size() && std::isspace(b[pos])) ++pos;
    if (pos < b.size() && b[pos] == '#') {
      while (pos < b.size() && b[pos] != '\n' && b[pos] != '\r') ++pos;
      continue;
    }
    break;
  }
  if (pos >= b.size() || !std::isdigit(b[pos])) return false;
  value = 0;
  while (pos < b.size() && std::isdigit(b[pos])) {
    value = value * 10 + (b[pos] - '0');
    if (value > 1'000'000) return false;
    ++pos;
  }
  return true;
}

}  // namespace

DepthUnits parse_depth_units(std::string_view text) {
  if (text == "mm") return DepthUnits::Millimetres;
  if (text == "tum") return DepthUnits::Tum;
  if (text == "kinect-disparity") return DepthUnits::KinectDisparity;
  throw std::invalid_argument("unknown depth units '" + std::string(text) +
                              "'; valid: mm, tum, kinect-disparity");
}

std::string_view to_string(DepthUnits units) {
  switch (units) {
    case DepthUnits::Millimetres:
      return "mm";
    case DepthUnits::Tum:
      return "tum";
    case DepthUnits::KinectDisparity:
      return "kinect-disparity";
  }
  return "?";
}

Pgm16 parse_pgm16(std::span<const std::uint8_t> b, ByteOrder order, const std::string& name) {
  if (b.size() < 2 || b[0] != 'P' || b[1] != '5')
    fail(name, b.size() >= 2 && b[0] == 'P' && b[1] == '2'
                   ? "ASCII PGM (P2) is not supported; wrong magic, expected binary P5"
                   : "wrong magic: not a binary PGM (expected \"P5\")");
  std::size_t pos = 2;
  long width = 0, height = 0, maxval = 0;
  if (!pgm_field(b, pos, width) || !pgm_field(b, pos, height) || !pgm_field(b, pos, maxval))
    fail(name, "truncated or malformed PGM header");
  if (width <= 0 || height <= 0) fail(name, "PGM has zero size");
  if (maxval <= 255)
    fail(name, "not 16-bit: PGM maxval is " + std::to_string(maxval) + " (needs 256..65535)");
  if (maxval > 65535) fail(name, "PGM maxval " + std::to_string(maxval) + " exceeds 65535");
  if (pos >= b.size() || !std::isspace(b[pos]))
    fail(name, "malformed PGM header (no whitespace after maxval)");
  ++pos;  // exactly one whitespace byte separates the header from the samples
  const std::size_t need = static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 2;
  if (b.size() - pos < need)
    fail(name, "truncated PGM data: " + std::to_string(b.size() - pos) + " bytes for " +
                   std::to_string(width) + "x" + std::to_string(height) + " 16-bit samples (need " +
                   std::to_string(need) + ")");

  const std::uint8_t* data = b.data() + pos;
  const std::size_t n = need / 2;
  if (order == ByteOrder::Auto) {
    bool be_over = false, le_over = false;
    for (std::size_t i = 0; i < n; ++i) {
      const unsigned be = (data[2 * i] << 8) | data[2 * i + 1];
      const unsigned le = (data[2 * i + 1] << 8) | data[2 * i];
      be_over |= be > kRawInvalid;
      le_over |= le > kRawInvalid;
    }
    order = (be_over && !le_over) ? ByteOrder::LittleEndian : ByteOrder::BigEndian;
  }
  Pgm16 out;
  out.byte_order = order;
  out.maxval = static_cast<int>(maxval);
  out.samples.create(static_cast<int>(height), static_cast<int>(width));
  std::uint16_t* dst = out.samples.ptr<std::uint16_t>();
  const int hi = order == ByteOrder::BigEndian ? 0 : 1;
  for (std::size_t i = 0; i < n; ++i)
    dst[i] = static_cast<std::uint16_t>((data[2 * i + hi] << 8) | data[2 * i + 1 - hi]);
  return out;
}

cv::Mat1w tum_to_mm(const cv::Mat1w& tum) {
  cv::Mat1w out(tum.size());
  for (int v = 0; v < tum.rows; ++v) {
    const std::uint16_t* s = tum[v];
    std::uint16_t* d = out[v];
    for (int u = 0; u < tum.cols; ++u) d[u] = static_cast<std::uint16_t>((s[u] + 2u) / 5u);
  }
  return out;
}

cv::Mat1w kinect_disparity_to_mm(const cv::Mat1w& raw) {
  // 2048 possible inputs: one table, computed once.
  static const std::array<std::uint16_t, 2048> table = [] {
    std::array<std::uint16_t, 2048> t{};
    for (int r = 0; r < 2048; ++r) {
      if (r >= kRawNoDepth) continue;  // includes 2047, the sensor's invalid code
      const double mm = std::round(351.3 / (1092.5 - r) * 1000.0);
      t[r] = mm <= 65535.0 ? static_cast<std::uint16_t>(mm) : kNoDepth;
    }
    return t;
  }();
  cv::Mat1w out(raw.size());
  for (int v = 0; v < raw.rows; ++v) {
    const std::uint16_t* s = raw[v];
    std::uint16_t* d = out[v];
    for (int u = 0; u < raw.cols; ++u) d[u] = s[u] < 2048 ? table[s[u]] : kNoDepth;
  }
  return out;
}

cv::Mat1w mm_to_kinect_disparity(const cv::Mat1w& depth_mm) {
  cv::Mat1w out(depth_mm.size());
  for (int v = 0; v < depth_mm.rows; ++v) {
    const std::uint16_t* s = depth_mm[v];
    std::uint16_t* d = out[v];
    for (int u = 0; u < depth_mm.cols; ++u) {
      if (s[u] == kNoDepth) {
        d[u] = kRawInvalid;
        continue;
      }
      const double raw = std::round(1092.5 - 351.3 / (s[u] / 1000.0));
      d[u] = raw < 0.0 ? kRawInvalid : static_cast<std::uint16_t>(raw);
    }
  }
  return out;
}

DepthImage load_depth(const std::filesystem::path& file, DepthUnits units,
                      const Intrinsics& intrinsics) {
  return load_depth(file, units, intrinsics, ByteOrder::Auto);
}

DepthImage load_depth(const std::filesystem::path& file, DepthUnits units,
                      const Intrinsics& intrinsics, ByteOrder pgm_byte_order) {
  const std::vector<std::uint8_t> bytes = read_all(file);
  DepthImage out;
  switch (units) {
    case DepthUnits::Millimetres:
      out.depth_mm = decode_png16(bytes, file);
      break;
    case DepthUnits::Tum:
      out.depth_mm = tum_to_mm(decode_png16(bytes, file));
      break;
    case DepthUnits::KinectDisparity: {
      const Pgm16 pgm = parse_pgm16(bytes, pgm_byte_order, file.string());
      out.depth_mm = kinect_disparity_to_mm(pgm.samples);
      break;
    }
  }
  out.intrinsics = fit_intrinsics(intrinsics, out.depth_mm.cols, out.depth_mm.rows);
  return out;
}

void save_depth_png(const std::filesystem::path& file, const cv::Mat1w& depth_mm) {
  if (depth_mm.empty())
    throw std::runtime_error("save_depth_png " + file.string() + ": empty image");
  bool ok = false;
  try {
    ok = cv::imwrite(file.string(), depth_mm, {cv::IMWRITE_PNG_COMPRESSION, 3});
  } catch (const cv::Exception& e) {
    throw std::runtime_error("save_depth_png " + file.string() + ": " + e.what());
  }
  if (!ok) throw std::runtime_error("save_depth_png " + file.string() + ": could not be written");
}

}  // namespace telex
