// SPDX-License-Identifier: MIT
// EyeStream: --video-codec and --video-bitrate, the encoder opened for the eyes' size, camera
// JPEG pass-through, and PLIs and bit rates from the network applied on the video thread.
#include "telex/remote/eye_stream.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace telex::remote {

std::vector<std::string> video_encoder_names(std::string_view codec) {
  if (codec == "h264") return {"libx264"};
  if (codec == "h264-vaapi") return {"h264_vaapi"};
  if (codec == "h264-nvenc") return {"h264_nvenc"};
  if (codec == "mjpeg") return {"mjpeg"};
  if (codec == "auto") return {"h264_vaapi", "h264_nvenc", "libx264"};
  throw std::invalid_argument(fmt::format(
      "--video-codec '{}' is not one of h264, h264-vaapi, h264-nvenc, mjpeg, auto", codec));
}

std::int64_t parse_bitrate_bps(std::string_view text) {
  const auto bad = [&] {
    return std::invalid_argument(fmt::format(
        "--video-bitrate '{}' is not a bit rate in 50k..1G (bit/s, e.g. 4M, 2500k, 800000)", text));
  };
  double value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (ec != std::errc() || ptr == text.data()) throw bad();
  const std::string_view suffix(ptr, static_cast<std::size_t>(end - ptr));
  double scale = 1;
  if (suffix == "k" || suffix == "K")
    scale = 1e3;
  else if (suffix == "M" || suffix == "m")
    scale = 1e6;
  else if (suffix == "G" || suffix == "g")
    scale = 1e9;
  else if (!suffix.empty())
    throw bad();
  const double bps = value * scale;
  if (!std::isfinite(bps) || bps < 50e3 || bps > 1e9) throw bad();
  return static_cast<std::int64_t>(std::llround(bps));
}

namespace {

// H.264's 4:2:0 needs even sides: an odd source loses its last column or row.
cv::Mat3b even_sides(const cv::Mat3b& img) {
  return img(cv::Rect(0, 0, img.cols & ~1, img.rows & ~1));
}

}  // namespace

EyeStream::EyeStream(const EyeStreamConfig& config, int probe_w, int probe_h)
    : config_(config), bitrate_bps_(config.bitrate_bps) {
  const auto names = video_encoder_names(config_.codec);
  std::string reasons;
  const bool h264 = names.front() != "mjpeg";
  if (h264) {
    probe_w &= ~1;
    probe_h &= ~1;
  }
  for (const auto& name : names) {
    try {
      encoder_ = open(name, probe_w, probe_h);
      encoder_name_ = name;
      break;
    } catch (const video::VideoError& e) {
      reasons += fmt::format("{}{}", reasons.empty() ? "" : "; ", e.what());
    }
  }
  if (!encoder_)
    throw std::invalid_argument(
        fmt::format("--video-codec {}: {}{}", config_.codec, reasons,
                    names.size() == 1 && h264 && names.front() != "libx264"
                        ? " (--video-codec h264 encodes in software; auto falls back to it)"
                        : ""));
  if (names.size() > 1)
    spdlog::info("--video-codec auto: the eyes are encoded with {}{}", encoder_name_,
                 reasons.empty() ? "" : fmt::format(" ({})", reasons));
  applied_bitrate_bps_ = config_.bitrate_bps;
}

EyeStream::~EyeStream() = default;

std::unique_ptr<video::EyeEncoder> EyeStream::open(const std::string& name, int eye_w,
                                                   int eye_h) const {
  video::EncoderConfig c;
  c.encoder = name;
  c.eye_width_px = eye_w;
  c.eye_height_px = eye_h;
  c.frame_rate_hz = config_.frame_rate_hz;
  c.bitrate_bps = bitrate_bps_.load();
  c.jpeg_quality = config_.jpeg_quality;
  return video::EyeEncoder::create(c);
}

void EyeStream::request_intra() { intra_wanted_ = true; }

void EyeStream::set_bitrate(std::int64_t bitrate_bps) {
  bitrate_bps_ = std::clamp<std::int64_t>(bitrate_bps, 50'000, 1'000'000'000);
}

void EyeStream::apply_requests() {
  if (intra_wanted_.exchange(false)) {
    encoder_->request_intra();
    ++counters_.intra_requests;
  }
  const std::int64_t want = bitrate_bps_.load();
  if (want != applied_bitrate_bps_) {
    encoder_->set_bitrate(want);
    applied_bitrate_bps_ = want;
  }
}

bool EyeStream::encode(const StereoFrame& frame, std::vector<std::uint8_t>& out, bool& is_intra) {
  const auto frame_id = static_cast<std::uint32_t>(frame.frame_id);
  const bool resize = config_.width_px > 0;
  const bool h264 = encoder_->codec() == video::VideoCodec::H264;
  // Camera JPEGs as they came: no decode, no encode.
  if (!h264 && !resize && !frame.left_jpeg.empty() && !frame.right_jpeg.empty()) {
    if (encoder_->encode_jpeg_pair(frame.left_jpeg, frame.right_jpeg, frame_id, frame.capture_ns,
                                   out) != video::EncodeStatus::Ok) {
      ++counters_.failed;
      return false;
    }
    ++counters_.pairs;
    ++counters_.passed_through;
    is_intra = true;
    return true;
  }
  cv::Mat3b l = frame.left_bgr, r = frame.right_bgr;
  if (l.empty() || r.empty() || l.size() != r.size()) {
    ++counters_.failed;
    return false;
  }
  if (resize) {
    cv::resize(l, l, cv::Size(config_.width_px, config_.height_px), 0, 0, cv::INTER_AREA);
    cv::resize(r, r, cv::Size(config_.width_px, config_.height_px), 0, 0, cv::INTER_AREA);
  }
  if (h264) {
    l = even_sides(l);
    r = even_sides(r);
  }
  const auto& cfg = encoder_->config();
  if (l.cols != cfg.eye_width_px || l.rows != cfg.eye_height_px) {
    try {
      encoder_ = open(encoder_name_, l.cols, l.rows);  // its first pair is intra
      applied_bitrate_bps_ = bitrate_bps_.load();
      ++counters_.reopened;
    } catch (const video::VideoError& e) {
      ++counters_.failed;
      spdlog::warn("eye encoder {} for {}x{} eyes: {}", encoder_name_, l.cols, l.rows, e.what());
      return false;
    }
  }
  apply_requests();
  const auto status = encoder_->encode(l, r, frame_id, frame.capture_ns, out);
  if (status != video::EncodeStatus::Ok) {
    if (status != video::EncodeStatus::Buffered) ++counters_.failed;
    return false;
  }
  is_intra = video::parse_frame(out).header.is_intra;
  ++counters_.pairs;
  return true;
}

}  // namespace telex::remote
