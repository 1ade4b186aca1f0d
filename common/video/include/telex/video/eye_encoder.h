// SPDX-License-Identifier: MIT
// Encodes a stereo pair as one unit: H.264 (libx264, or a hardware encoder by name) of the two eyes
// side by side, or MJPEG (two JPEGs, also straight from the cameras).
//
// Why one side-by-side picture rather than two streams: both eyes are one instant (one frame id,
// one capture time, one header), so the station can never show a left eye of one instant with a
// right eye of another; one rate controller shares the bit budget between the eyes instead of
// two fighting over the link; and the per-frame costs (header, fragment headers, encoder call,
// slice headers, a lost-frame recovery) are paid once per pair, not twice.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "telex/video/frame_header.h"

namespace telex::video {

// Start-up errors (an encoder that is absent or will not open, a bad setting): the message names
// the encoder or setting and why.
class VideoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct EncoderConfig {
  // "libx264" (software H.264), "h264_vaapi", "h264_nvenc" (hardware H.264) or "mjpeg".
  std::string encoder = "libx264";
  int eye_width_px = 1280;  // one eye; even for H.264
  int eye_height_px = 720;
  double frame_rate_hz = 30.0;
  // H.264 target (--video-bitrate); mjpeg ignores it. With a VBV of two frames (no pair much
  // above its share) x264 stays 10-25 % below it: a ceiling more than an average.
  std::int64_t bitrate_bps = 4'000'000;
  // x264 preset: "ultrafast" (with deblocking on) measured best: the SSIM goal at 4 Mbit/s in the
  // least time (docs/BENCHMARKS.md "The eyes' codec").
  std::string preset = "ultrafast";
  // One intra-refresh wave sweeps the picture in this many frames (x264 keyint): the picture
  // heals by itself within it after a loss, without the burst of a periodic key frame. (The
  // decoder still reports MissingReference until the IDR a request_intra() brings.)
  int intra_refresh_frames = 30;
  int threads = 2;        // encoder threads (x264 sliced threads: no added latency)
  int jpeg_quality = 80;  // mjpeg only, as the remote daemon's MJPEG today
  std::string vaapi_device = "/dev/dri/renderD128";  // h264_vaapi only
};

enum class EncodeStatus : std::uint8_t {
  Ok = 0,
  Buffered,      // the encoder kept the picture (a hardware pipeline's delay): nothing to send
  BadInput,      // eye sizes differ from the configuration, or empty JPEG bytes
  WrongCodec,    // JPEG pass-through to an H.264 encoder
  EncoderError,  // the codec library refused the picture (counted; the next pair may succeed)
};
std::string_view encode_status_name(EncodeStatus status);

struct EncoderCounters {
  std::uint64_t pairs = 0;           // pairs encoded
  std::uint64_t intra_pairs = 0;     // of them decodable alone
  std::uint64_t failed = 0;          // pairs refused (BadInput, WrongCodec, EncoderError)
  std::uint64_t intra_requests = 0;  // request_intra() calls honoured (one per encoded pair)
  std::uint64_t bytes_out = 0;       // header + payload
};

class EyeEncoder {
 public:
  // Opens the encoder; throws VideoError naming the encoder and why when it is not in this
  // libavcodec build, has no device, or refuses the settings.
  static std::unique_ptr<EyeEncoder> create(const EncoderConfig& config);
  virtual ~EyeEncoder() = default;

  // Encodes one pair (BGR, each eye_width_px x eye_height_px) into `out` (replaced): the
  // serialized EncodedFrameHeader, then the payload. Never throws.
  virtual EncodeStatus encode(const cv::Mat3b& left_bgr, const cv::Mat3b& right_bgr,
                              std::uint32_t frame_id, std::int64_t capture_ns,
                              std::vector<std::uint8_t>& out) = 0;
  // MJPEG only: wraps two camera JPEGs as they are, without decoding them. Never throws.
  virtual EncodeStatus encode_jpeg_pair(std::span<const std::uint8_t> left_jpeg,
                                        std::span<const std::uint8_t> right_jpeg,
                                        std::uint32_t frame_id, std::int64_t capture_ns,
                                        std::vector<std::uint8_t>& out);

  // New target bit rate from the next pair on (a rate controller); H.264 only, mjpeg ignores it.
  // set_bitrate and request_intra may be called from any thread (the network's); encode and the
  // rest from one thread.
  virtual void set_bitrate(std::int64_t bitrate_bps) = 0;
  // The next pair is decodable alone (the station lost a reference: a Picture Loss Indication).
  virtual void request_intra() = 0;

  VideoCodec codec() const { return codec_; }
  const EncoderConfig& config() const { return config_; }
  const EncoderCounters& counters() const { return counters_; }

 protected:
  EyeEncoder(const EncoderConfig& config, VideoCodec codec) : config_(config), codec_(codec) {}
  // Writes the header for `payload_bytes` at the start of `out` and counts the pair.
  void finish_pair(std::uint32_t frame_id, std::int64_t capture_ns, bool is_intra,
                   std::vector<std::uint8_t>& out);
  EncodeStatus fail(EncodeStatus status) {
    ++counters_.failed;
    return status;
  }

  EncoderConfig config_;
  VideoCodec codec_;
  EncoderCounters counters_;
  std::uint32_t next_seq_ = 0;
};

}  // namespace telex::video
