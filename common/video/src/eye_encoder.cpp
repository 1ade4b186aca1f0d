// SPDX-License-Identifier: MIT
// EyeEncoder: the choice of back end, the settings' checks, the header in front of each pair.
#include "telex/video/eye_encoder.h"

#include <algorithm>

#include "encoders.h"

namespace telex::video {

std::string_view encode_status_name(EncodeStatus status) {
  switch (status) {
    case EncodeStatus::Ok:
      return "ok";
    case EncodeStatus::Buffered:
      return "buffered";
    case EncodeStatus::BadInput:
      return "bad input";
    case EncodeStatus::WrongCodec:
      return "wrong codec";
    case EncodeStatus::EncoderError:
      return "encoder error";
  }
  return "unknown";
}

std::unique_ptr<EyeEncoder> EyeEncoder::create(const EncoderConfig& config) {
  const bool h264 = config.encoder == "libx264" || config.encoder == "h264_vaapi" ||
                    config.encoder == "h264_nvenc";
  if (!h264 && config.encoder != "mjpeg")
    throw VideoError("video encoder '" + config.encoder +
                     "' is not one of libx264, h264_vaapi, h264_nvenc, mjpeg");
  const int side_multiple = h264 ? 2 : 1;
  for (const auto& [name, side] :
       {std::pair{"width", config.eye_width_px}, std::pair{"height", config.eye_height_px}}) {
    if (side <= 0 || side > kMaxEyeSidePx || side % side_multiple != 0)
      throw VideoError("video encoder '" + config.encoder + "': eye " + name + " " +
                       std::to_string(side) + " px is not " + (h264 ? "an even number " : "") +
                       "in 1.." + std::to_string(kMaxEyeSidePx));
  }
  if (!(config.frame_rate_hz > 0.0 && config.frame_rate_hz <= 240.0))
    throw VideoError("video encoder '" + config.encoder + "': frame rate " +
                     std::to_string(config.frame_rate_hz) + " Hz is not in (0, 240]");
  if (h264 && (config.bitrate_bps < 10'000 || config.bitrate_bps > 1'000'000'000))
    throw VideoError("video encoder '" + config.encoder + "': --video-bitrate " +
                     std::to_string(config.bitrate_bps) + " bit/s is not in 10 kbit/s..1 Gbit/s");
  if (h264 && config.intra_refresh_frames < 2)
    throw VideoError("video encoder '" + config.encoder + "': intra refresh period " +
                     std::to_string(config.intra_refresh_frames) + " frames is below 2");
  if (!h264 && (config.jpeg_quality < 1 || config.jpeg_quality > 100))
    throw VideoError("video encoder 'mjpeg': JPEG quality " + std::to_string(config.jpeg_quality) +
                     " is not in 1..100");
  return h264 ? detail::make_h264_encoder(config) : detail::make_mjpeg_encoder(config);
}

EncodeStatus EyeEncoder::encode_jpeg_pair(std::span<const std::uint8_t>,
                                          std::span<const std::uint8_t>, std::uint32_t,
                                          std::int64_t, std::vector<std::uint8_t>&) {
  return fail(EncodeStatus::WrongCodec);
}

void EyeEncoder::finish_pair(std::uint32_t frame_id, std::int64_t capture_ns, bool is_intra,
                             std::vector<std::uint8_t>& out) {
  EncodedFrameHeader header;
  header.frame_id = frame_id;
  header.encode_seq = next_seq_++;
  header.capture_ns = capture_ns;
  header.codec = codec_;
  header.is_intra = is_intra;
  header.eye_width_px = static_cast<std::uint16_t>(config_.eye_width_px);
  header.eye_height_px = static_cast<std::uint16_t>(config_.eye_height_px);
  header.payload_bytes = static_cast<std::uint32_t>(out.size() - kHeaderBytes);
  std::vector<std::uint8_t> bytes;
  bytes.reserve(kHeaderBytes);
  serialize_header(header, bytes);
  std::copy(bytes.begin(), bytes.end(), out.begin());
  ++counters_.pairs;
  if (is_intra) ++counters_.intra_pairs;
  counters_.bytes_out += out.size();
}

}  // namespace telex::video
