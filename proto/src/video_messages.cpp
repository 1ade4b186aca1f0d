// SPDX-License-Identifier: MIT
// The eyes' messages on the wire (docs/PROTOCOL.md 2.7), little-endian like the rest.
#include "video_messages.h"

#include <bit>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace telex::proto::detail {
namespace {

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("proto::encode: ") + what);
}

PayloadError bad(const char* detail) { return {ErrorReason::BadPayload, detail}; }

// The report's checks, shared by both directions: what decode refuses, encode refuses too.
const char* report_problem(const ReceiverReport& m) {
  if (m.interval_us == 0 || m.interval_us > kMaxReportIntervalUs)
    return "ReceiverReport interval not in 1..10 s";
  if (std::abs(static_cast<std::int64_t>(m.delay_mean_us)) > kMaxReportDelayUs ||
      std::abs(static_cast<std::int64_t>(m.delay_last_us)) > kMaxReportDelayUs)
    return "ReceiverReport delay beyond 60 s";
  if (!std::isfinite(m.delay_gradient_us_per_s)) return "ReceiverReport gradient not finite";
  if (m.video_bytes > m.bytes_received) return "ReceiverReport video bytes above all bytes";
  // Without samples the delays are all-zero bytes: one encoding per report (-0.0 would differ).
  if (m.delay_samples == 0 && (m.delay_mean_us != 0 || m.delay_last_us != 0 ||
                               std::bit_cast<std::uint32_t>(m.delay_gradient_us_per_s) != 0u))
    return "ReceiverReport delays set without samples";
  return nullptr;
}

}  // namespace

void put_video(Writer& w, const EncodedVideo& m) {
  require(video::parse_frame(m.frame).status == video::HeaderStatus::Ok,
          "EncodedVideo frame does not parse (video::parse_frame)");
  w.bytes(m.frame);
}

void put_picture_loss(Writer& w, const PictureLoss& m) {
  require(static_cast<std::uint8_t>(m.reason) <= kMaxPictureLossReason,
          "PictureLoss reason not 0 or 1");
  w.u32(m.last_good_seq);
  w.u8(static_cast<std::uint8_t>(m.reason));
}

void put_receiver_report(Writer& w, const ReceiverReport& m) {
  if (const char* why = report_problem(m)) require(false, why);
  w.u32(m.interval_us);
  w.u64(m.bytes_received);
  w.u64(m.video_bytes);
  w.u32(m.datagrams_received);
  w.u32(m.fragments_lost);
  w.u32(m.delay_samples);
  w.u32(static_cast<std::uint32_t>(m.delay_mean_us));
  w.u32(static_cast<std::uint32_t>(m.delay_last_us));
  w.f32(m.delay_gradient_us_per_s);
}

void put_video_nack(Writer& w, const VideoNack& m) {
  require(m.count >= 1 && m.count <= kMaxVideoNackPairs, "VideoNack count not in 1..16");
  w.u32(m.first_seq);
  w.u16(m.count);
}

std::optional<PayloadError> get_video(Reader& r, EncodedVideo& m) {
  const auto bytes = r.bytes(r.remaining());
  const video::ParsedFrame parsed = video::parse_frame(bytes);
  switch (parsed.status) {
    case video::HeaderStatus::Ok:
      break;
    case video::HeaderStatus::Truncated:
      return PayloadError{ErrorReason::Truncated,
                          "EncodedVideo shorter than its frame header says"};
    case video::HeaderStatus::BadGeometry:
      return PayloadError{ErrorReason::BadTileGeometry, "EncodedVideo eye size"};
    case video::HeaderStatus::PayloadTooLong:
      return PayloadError{ErrorReason::DecompressionBomb, "EncodedVideo payload above 32 MiB"};
    case video::HeaderStatus::BadMagic:
      return bad("EncodedVideo frame header magic or version");
    case video::HeaderStatus::UnknownCodec:
      return bad("EncodedVideo codec unknown");
    case video::HeaderStatus::BadFlags:
      return bad("EncodedVideo frame header flags");
    case video::HeaderStatus::TrailingBytes:
      return bad("EncodedVideo bytes beyond the frame's payload");
    case video::HeaderStatus::BadHeadPose:
      return bad("EncodedVideo head joint not finite or beyond pi");
  }
  m.frame.assign(bytes.begin(), bytes.end());
  return std::nullopt;
}

std::optional<PayloadError> get_picture_loss(Reader& r, PictureLoss& m) {
  m.last_good_seq = r.u32();
  const std::uint8_t reason = r.u8();
  if (!r.ok()) return PayloadError{ErrorReason::Truncated, "PictureLoss fields"};
  if (reason > kMaxPictureLossReason) return bad("PictureLoss reason not 0 or 1");
  m.reason = static_cast<PictureLossReason>(reason);
  return std::nullopt;
}

std::optional<PayloadError> get_receiver_report(Reader& r, ReceiverReport& m) {
  m.interval_us = r.u32();
  m.bytes_received = r.u64();
  m.video_bytes = r.u64();
  m.datagrams_received = r.u32();
  m.fragments_lost = r.u32();
  m.delay_samples = r.u32();
  m.delay_mean_us = static_cast<std::int32_t>(r.u32());
  m.delay_last_us = static_cast<std::int32_t>(r.u32());
  m.delay_gradient_us_per_s = r.f32();
  if (!r.ok()) return PayloadError{ErrorReason::Truncated, "ReceiverReport fields"};
  if (const char* why = report_problem(m)) return bad(why);
  return std::nullopt;
}

std::optional<PayloadError> get_video_nack(Reader& r, VideoNack& m) {
  m.first_seq = r.u32();
  m.count = r.u16();
  if (!r.ok()) return PayloadError{ErrorReason::Truncated, "VideoNack fields"};
  if (m.count == 0 || m.count > kMaxVideoNackPairs) return bad("VideoNack count not in 1..16");
  return std::nullopt;
}

}  // namespace telex::proto::detail
