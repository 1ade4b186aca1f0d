// SPDX-License-Identifier: MIT
// The EyeEncoder back ends EyeEncoder::create chooses between by name.
#pragma once

#include <memory>

#include "telex/video/eye_encoder.h"

namespace telex::video::detail {

// libx264, h264_vaapi, h264_nvenc through libavcodec (h264_encoder.cpp).
std::unique_ptr<EyeEncoder> make_h264_encoder(const EncoderConfig& config);
// Two JPEGs per pair (mjpeg_encoder.cpp).
std::unique_ptr<EyeEncoder> make_mjpeg_encoder(const EncoderConfig& config);

}  // namespace telex::video::detail
