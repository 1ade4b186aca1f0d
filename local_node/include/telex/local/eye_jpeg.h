// SPDX-License-Identifier: MIT
// One eye's JPEG from a VideoFrame, decoded only when it is the size the frame says it is.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <span>

namespace telex::local {

enum class EyeJpegStatus { Ok, Undecodable, WrongSize };

struct DecodedEye {
  EyeJpegStatus status = EyeJpegStatus::Undecodable;
  cv::Mat3b bgr;  // empty unless status == Ok
};

// Decodes `jpeg` (BGR) and accepts it only when it is width x height pixels, the size its
// VideoFrame announced: an image of another size would be drawn over depth it does not match.
DecodedEye decode_eye_jpeg(std::span<const std::uint8_t> jpeg, int width, int height);

}  // namespace telex::local
