// SPDX-License-Identifier: MIT
// The eyes' JPEG decode with its size check (see eye_jpeg.h).
#include "telex/local/eye_jpeg.h"

#include <opencv2/imgcodecs.hpp>

namespace telex::local {

DecodedEye decode_eye_jpeg(std::span<const std::uint8_t> jpeg, int width, int height) {
  DecodedEye out;
  if (jpeg.empty()) return out;
  cv::Mat img;
  try {
    // imdecode reads through a Mat header; the bytes are not written.
    const cv::Mat1b bytes(1, static_cast<int>(jpeg.size()), const_cast<std::uint8_t*>(jpeg.data()));
    img = cv::imdecode(bytes, cv::IMREAD_COLOR);
  } catch (const cv::Exception&) {
    return out;
  }
  if (img.empty() || img.type() != CV_8UC3) return out;
  if (img.cols != width || img.rows != height) {
    out.status = EyeJpegStatus::WrongSize;
    return out;
  }
  out.status = EyeJpegStatus::Ok;
  out.bgr = img;
  return out;
}

}  // namespace telex::local
