// SPDX-License-Identifier: MIT
// Pure conversions of V4L2 capture buffers (YUYV 4:2:2, MJPEG) to BGR images, testable on recorded
// bytes.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

namespace telex::remote {

// V4L2 fourcc codes the stereo source negotiates, in preference order.
inline constexpr std::uint32_t fourcc(char a, char b, char c, char d) {
  return static_cast<std::uint32_t>(a) | (static_cast<std::uint32_t>(b) << 8) |
         (static_cast<std::uint32_t>(c) << 16) | (static_cast<std::uint32_t>(d) << 24);
}
inline constexpr std::uint32_t kFourccYuyv = fourcc('Y', 'U', 'Y', 'V');
inline constexpr std::uint32_t kFourccMjpeg = fourcc('M', 'J', 'P', 'G');

struct ConvertResult {
  cv::Mat3b bgr;      // empty on error
  std::string error;  // names the problem when bgr is empty
  bool ok() const { return !bgr.empty(); }
};

// YUYV (Y0 U Y1 V per two pixels). `bytes_per_line` is the driver's stride (0 = 2 * width).
ConvertResult yuyv_to_bgr(std::span<const std::uint8_t> bytes, int width, int height,
                          int bytes_per_line = 0);

// One Motion-JPEG frame. Webcams often omit the Huffman tables (DHT); the standard tables of
// ITU-T T.81 Annex K are inserted when they are missing. Expected size checked when > 0.
ConvertResult mjpeg_to_bgr(std::span<const std::uint8_t> bytes, int expect_width = 0,
                           int expect_height = 0);

// Any supported fourcc.
ConvertResult convert_v4l2_buffer(std::uint32_t pixel_format, std::span<const std::uint8_t> bytes,
                                  int width, int height, int bytes_per_line = 0);

// BGR -> YUYV bytes (BT.601, as a camera would deliver): the inverse used to make test buffers and
// by the synthetic stereo source's wire format checks.
std::vector<std::uint8_t> bgr_to_yuyv(const cv::Mat3b& bgr);

std::string fourcc_name(std::uint32_t code);

}  // namespace telex::remote
