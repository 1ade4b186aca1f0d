// SPDX-License-Identifier: MIT
// Decodes what EyeEncoder made back into the left and right eye, and says when a reference is
// missing so the caller can ask the encoder for an intra picture (a Picture Loss Indication).
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string_view>

#include "telex/video/frame_header.h"

namespace telex::video {

enum class DecodeStatus : std::uint8_t {
  Ok = 0,
  BadHeader,         // parse_frame refused the bytes (see last_header_status)
  DecodeError,       // the codec library refused the bytes: send a PLI
  MissingReference,  // a pair was lost before this one (encode_seq gap), or the picture still
                     // rests on a lost one: the eyes may be damaged; send a PLI
  NoPicture,         // the decoder took the bytes but gave no picture yet
};
std::string_view decode_status_name(DecodeStatus status);

struct DecodedPair {
  EncodedFrameHeader header;
  cv::Mat3b left_bgr;   // reused across calls when the size stays
  cv::Mat3b right_bgr;  //
};

struct DecoderCounters {
  std::uint64_t pairs = 0;              // pictures produced (including damaged ones)
  std::uint64_t bad_header = 0;         //
  std::uint64_t decode_errors = 0;      //
  std::uint64_t missing_reference = 0;  // pairs decoded while a reference was missing
  std::uint64_t gaps = 0;               // encode_seq gaps seen (pairs lost before us)
};

class EyeDecoder {
 public:
  EyeDecoder();
  ~EyeDecoder();
  EyeDecoder(const EyeDecoder&) = delete;
  EyeDecoder& operator=(const EyeDecoder&) = delete;

  // Decodes one whole encoded frame (header + payload). On Ok and MissingReference `out` holds
  // the pair (damaged in the second case); on the others `out`'s images are untouched. After a
  // loss (or a change of eye size, or from the start) every H.264 pair is MissingReference until
  // an intra pair arrives. Never throws.
  DecodeStatus decode(std::span<const std::uint8_t> bytes, DecodedPair& out);

  // True from a loss or decode error until an intra pair decodes: keep asking for one.
  bool needs_intra() const { return needs_intra_; }
  HeaderStatus last_header_status() const { return last_header_status_; }
  const DecoderCounters& counters() const { return counters_; }

 private:
  struct Impl;
  DecodeStatus decode_h264(const ParsedFrame& parsed, DecodedPair& out);
  DecodeStatus decode_mjpeg(const ParsedFrame& parsed, DecodedPair& out);

  std::unique_ptr<Impl> impl_;
  bool needs_intra_ = false;
  HeaderStatus last_header_status_ = HeaderStatus::Ok;
  DecoderCounters counters_;
};

}  // namespace telex::video
