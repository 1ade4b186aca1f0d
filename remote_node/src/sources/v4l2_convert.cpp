// SPDX-License-Identifier: MIT
// YUYV and MJPEG buffer conversion for the V4L2 stereo source.
#include "telex/remote/v4l2_convert.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

namespace telex::remote {

namespace {

constexpr std::uint8_t kMarker = 0xFF;
constexpr std::uint8_t kSoi = 0xD8;
constexpr std::uint8_t kSos = 0xDA;
constexpr std::uint8_t kDht = 0xC4;

// Offset of the SOS marker and whether a DHT segment precedes it; nullopt when the header is
// broken.
struct JpegScan {
  std::size_t sos_offset = 0;
  bool has_dht = false;
};

std::optional<JpegScan> scan_jpeg_header(std::span<const std::uint8_t> b) {
  if (b.size() < 4 || b[0] != kMarker || b[1] != kSoi) return std::nullopt;
  JpegScan scan;
  std::size_t i = 2;
  while (i + 4 <= b.size()) {
    if (b[i] != kMarker) return std::nullopt;
    const std::uint8_t marker = b[i + 1];
    if (marker == kMarker) {  // fill byte
      ++i;
      continue;
    }
    if (marker == kSos) {
      scan.sos_offset = i;
      return scan;
    }
    if (marker == kDht) scan.has_dht = true;
    const std::size_t length = (static_cast<std::size_t>(b[i + 2]) << 8) | b[i + 3];
    if (length < 2) return std::nullopt;
    i += 2 + length;
  }
  return std::nullopt;
}

// libjpeg writes the standard Annex K tables when it does not optimise coding, so the tables are
// taken from a frame it encodes rather than retyped here.
const std::vector<std::uint8_t>& standard_dht_segments() {
  static const std::vector<std::uint8_t> segments = [] {
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", cv::Mat3b(16, 16, cv::Vec3b(10, 200, 90)), jpeg,
                 {cv::IMWRITE_JPEG_QUALITY, 90, cv::IMWRITE_JPEG_OPTIMIZE, 0});
    std::vector<std::uint8_t> out;
    std::size_t i = 2;
    while (i + 4 <= jpeg.size() && jpeg[i] == kMarker && jpeg[i + 1] != kSos) {
      const std::size_t length = (static_cast<std::size_t>(jpeg[i + 2]) << 8) | jpeg[i + 3];
      if (jpeg[i + 1] == kDht)
        out.insert(out.end(), jpeg.begin() + static_cast<long>(i),
                   jpeg.begin() + static_cast<long>(i + 2 + length));
      i += 2 + length;
    }
    return out;
  }();
  return segments;
}

}  // namespace

ConvertResult yuyv_to_bgr(std::span<const std::uint8_t> bytes, int width, int height,
                          int bytes_per_line) {
  ConvertResult r;
  if (width <= 0 || height <= 0 || width % 2 != 0) {
    r.error = fmt::format("YUYV frame size {}x{} is invalid (width must be even and positive)",
                          width, height);
    return r;
  }
  const std::size_t stride =
      bytes_per_line > 0 ? static_cast<std::size_t>(bytes_per_line) : 2u * width;
  if (stride < 2u * width) {
    r.error = fmt::format("YUYV stride {} is below 2 * width {}", stride, 2 * width);
    return r;
  }
  const std::size_t need = stride * static_cast<std::size_t>(height - 1) + 2u * width;
  if (bytes.size() < need) {
    r.error =
        fmt::format("YUYV buffer has {} bytes, {}x{} needs {}", bytes.size(), width, height, need);
    return r;
  }
  const cv::Mat packed(height, width, CV_8UC2, const_cast<std::uint8_t*>(bytes.data()), stride);
  cv::cvtColor(packed, r.bgr, cv::COLOR_YUV2BGR_YUYV);
  return r;
}

ConvertResult mjpeg_to_bgr(std::span<const std::uint8_t> bytes, int expect_width,
                           int expect_height) {
  ConvertResult r;
  const auto scan = scan_jpeg_header(bytes);
  if (!scan) {
    r.error = fmt::format("MJPEG frame of {} bytes has no valid JPEG header", bytes.size());
    return r;
  }
  cv::Mat decoded;
  if (scan->has_dht) {
    decoded = cv::imdecode(
        cv::Mat(1, static_cast<int>(bytes.size()), CV_8U, const_cast<std::uint8_t*>(bytes.data())),
        cv::IMREAD_COLOR);
  } else {
    const auto& dht = standard_dht_segments();
    std::vector<std::uint8_t> fixed;
    fixed.reserve(bytes.size() + dht.size());
    fixed.insert(fixed.end(), bytes.begin(), bytes.begin() + static_cast<long>(scan->sos_offset));
    fixed.insert(fixed.end(), dht.begin(), dht.end());
    fixed.insert(fixed.end(), bytes.begin() + static_cast<long>(scan->sos_offset), bytes.end());
    decoded = cv::imdecode(fixed, cv::IMREAD_COLOR);
  }
  if (decoded.empty() || decoded.type() != CV_8UC3) {
    r.error = fmt::format("MJPEG frame of {} bytes failed to decode", bytes.size());
    return r;
  }
  if ((expect_width > 0 && decoded.cols != expect_width) ||
      (expect_height > 0 && decoded.rows != expect_height)) {
    r.error = fmt::format("MJPEG frame is {}x{}, the stream negotiated {}x{}", decoded.cols,
                          decoded.rows, expect_width, expect_height);
    return r;
  }
  r.bgr = decoded;
  return r;
}

ConvertResult convert_v4l2_buffer(std::uint32_t pixel_format, std::span<const std::uint8_t> bytes,
                                  int width, int height, int bytes_per_line) {
  if (pixel_format == kFourccYuyv) return yuyv_to_bgr(bytes, width, height, bytes_per_line);
  if (pixel_format == kFourccMjpeg) return mjpeg_to_bgr(bytes, width, height);
  ConvertResult r;
  r.error = fmt::format("pixel format {} is not supported (YUYV, MJPG)", fourcc_name(pixel_format));
  return r;
}

std::vector<std::uint8_t> bgr_to_yuyv(const cv::Mat3b& bgr) {
  CV_Assert(bgr.cols % 2 == 0);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(bgr.rows) * bgr.cols * 2);
  const auto clamp8 = [](double v) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
  };
  std::size_t o = 0;
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; x += 2) {
      double ys[2], us = 0, vs = 0;
      for (int k = 0; k < 2; ++k) {
        const cv::Vec3b p = bgr(y, x + k);
        const double b = p[0], g = p[1], rr = p[2];
        ys[k] = 16.0 + 0.257 * rr + 0.504 * g + 0.098 * b;
        us += 128.0 - 0.148 * rr - 0.291 * g + 0.439 * b;
        vs += 128.0 + 0.439 * rr - 0.368 * g - 0.071 * b;
      }
      out[o++] = clamp8(ys[0]);
      out[o++] = clamp8(us / 2);
      out[o++] = clamp8(ys[1]);
      out[o++] = clamp8(vs / 2);
    }
  }
  return out;
}

std::string fourcc_name(std::uint32_t code) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((code >> (8 * i)) & 0xFF);
    s[static_cast<std::size_t>(i)] = (c >= 32 && c < 127) ? c : '?';
  }
  return s;
}

}  // namespace telex::remote
