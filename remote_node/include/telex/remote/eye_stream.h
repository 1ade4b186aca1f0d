// SPDX-License-Identifier: MIT
// The eyes' encoder as the remote daemon drives it: the --video-codec choice, the eye size sent,
// camera JPEG pass-through, and the two hooks the network side calls (a Picture Loss Indication,
// a new bit rate from the rate controller) applied on the video thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "telex/remote/sources.h"
#include "telex/video/eye_encoder.h"

namespace telex::remote {

struct EyeStreamConfig {
  // --video-codec: h264 (libx264), h264-vaapi, h264-nvenc, mjpeg, or auto (the first hardware
  // encoder that opens, else libx264).
  std::string codec = "h264";
  std::int64_t bitrate_bps = 4'000'000;  // --video-bitrate (H.264 only)
  int jpeg_quality = 80;                 // --jpeg-quality (mjpeg only)
  int width_px = 0;                      // --video-size, one eye; 0: the source's size
  int height_px = 0;
  double frame_rate_hz = 30.0;
};

// The --video-codec values in the order auto tries them; throws std::invalid_argument naming
// --video-codec for anything else.
std::vector<std::string> video_encoder_names(std::string_view codec);
// "4M", "2500k", "800000" (bit/s) -> bit/s; throws std::invalid_argument naming --video-bitrate.
std::int64_t parse_bitrate_bps(std::string_view text);

struct EyeStreamCounters {
  std::uint64_t pairs = 0;           // pairs encoded and handed out
  std::uint64_t passed_through = 0;  // of them camera JPEG pairs sent as they came
  std::uint64_t failed = 0;          // pairs the encoder refused (counted, skipped)
  std::uint64_t intra_requests = 0;  // PLIs applied (several before one pair count once)
  std::uint64_t reopened = 0;        // encoders opened again for a new eye size
};

class EyeStream {
 public:
  // Opens the encoder for `probe_w` x `probe_h` eyes (the size expected; a source of another size
  // reopens it at its first pair), so a hardware encoder that cannot open fails the start. Throws
  // std::invalid_argument naming --video-codec, the encoder and libavcodec's reason.
  EyeStream(const EyeStreamConfig& config, int probe_w, int probe_h);
  ~EyeStream();

  // Video thread: the pair as one encoded frame (EncodedFrameHeader + payload) in `out`. Camera
  // JPEGs go through unchanged with mjpeg and no --video-size. False when nothing is to be sent
  // (counted). Never throws.
  bool encode(const StereoFrame& frame, std::vector<std::uint8_t>& out, bool& is_intra);

  // Any thread; applied before the next pair. The station lost a reference (a PLI).
  void request_intra();
  // Any thread: the rate controller's output (bit/s), clamped to 50 kbit/s..1 Gbit/s. The
  // extension point for issue 28's controller, to be called from RemoteDaemon::on_receiver_report
  // (which today only records the report for the stats line).
  void set_bitrate(std::int64_t bitrate_bps);
  std::int64_t bitrate_bps() const { return bitrate_bps_.load(); }
  const std::string& encoder_name() const { return encoder_name_; }
  const EyeStreamCounters& counters() const { return counters_; }  // video thread

 private:
  std::unique_ptr<video::EyeEncoder> open(const std::string& name, int eye_w, int eye_h) const;
  void apply_requests();

  EyeStreamConfig config_;
  std::string encoder_name_;  // the libavcodec name that opened
  std::unique_ptr<video::EyeEncoder> encoder_;
  std::atomic<bool> intra_wanted_{false};
  std::atomic<std::int64_t> bitrate_bps_;
  std::int64_t applied_bitrate_bps_ = 0;
  EyeStreamCounters counters_;
};

}  // namespace telex::remote
