// SPDX-License-Identifier: MIT
// MJPEG pairs: the comparison codec, and what camera JPEGs pass through as without decoding.
#include <opencv2/imgcodecs.hpp>

#include "encoders.h"
#include "telex/base/byte_cursor.h"

namespace telex::video::detail {

namespace {

// Payload: u32 left length, left JPEG, right JPEG. Each eye is its own JPEG (not one
// side-by-side JPEG) so camera bytes pass through untouched; the pair still shares one header.
class MjpegEncoder final : public EyeEncoder {
 public:
  explicit MjpegEncoder(const EncoderConfig& config)
      : EyeEncoder(config, VideoCodec::Mjpeg),
        params_{cv::IMWRITE_JPEG_QUALITY, config.jpeg_quality} {}

  EncodeStatus encode(const cv::Mat3b& left_bgr, const cv::Mat3b& right_bgr, std::uint32_t frame_id,
                      std::int64_t capture_ns, std::vector<std::uint8_t>& out) override {
    const cv::Size eye(config_.eye_width_px, config_.eye_height_px);
    if (left_bgr.size() != eye || right_bgr.size() != eye) return fail(EncodeStatus::BadInput);
    // cv::imencode as the remote daemon's video loop: the same bytes it sends today.
    try {
      cv::imencode(".jpg", left_bgr, left_, params_);
      cv::imencode(".jpg", right_bgr, right_, params_);
    } catch (const cv::Exception&) {
      return fail(EncodeStatus::EncoderError);
    }
    return encode_jpeg_pair(left_, right_, frame_id, capture_ns, out);
  }

  EncodeStatus encode_jpeg_pair(std::span<const std::uint8_t> left_jpeg,
                                std::span<const std::uint8_t> right_jpeg, std::uint32_t frame_id,
                                std::int64_t capture_ns, std::vector<std::uint8_t>& out) override {
    if (left_jpeg.empty() || right_jpeg.empty() ||
        left_jpeg.size() + right_jpeg.size() + 4 > kMaxPayloadBytes)
      return fail(EncodeStatus::BadInput);
    out.assign(kHeaderBytes, 0);
    out.reserve(kHeaderBytes + 4 + left_jpeg.size() + right_jpeg.size());
    ByteWriter w(out);
    w.u32(static_cast<std::uint32_t>(left_jpeg.size()));
    w.bytes(left_jpeg);
    w.bytes(right_jpeg);
    finish_pair(frame_id, capture_ns, true, out);
    return EncodeStatus::Ok;
  }

  void set_bitrate(std::int64_t) override {}
  void request_intra() override {}  // every MJPEG pair is intra

 private:
  std::vector<int> params_;
  std::vector<std::uint8_t> left_, right_;
};

}  // namespace

std::unique_ptr<EyeEncoder> make_mjpeg_encoder(const EncoderConfig& config) {
  return std::make_unique<MjpegEncoder>(config);
}

}  // namespace telex::video::detail
