// SPDX-License-Identifier: MIT
// The eyes' messages (EncodedVideo, PictureLoss, ReceiverReport, VideoNack): encoding and bounded
// decoding, kept apart from messages.cpp, which dispatches to them.
#pragma once

#include <optional>

#include "byte_io.h"
#include "telex/proto/messages.h"

namespace telex::proto::detail {

struct PayloadError {
  ErrorReason reason;
  const char* detail;  // static
};

// Throw std::invalid_argument for values decode would refuse (a sender bug).
void put_video(Writer& w, const EncodedVideo& m);
void put_picture_loss(Writer& w, const PictureLoss& m);
void put_receiver_report(Writer& w, const ReceiverReport& m);
void put_video_nack(Writer& w, const VideoNack& m);

// Read the payload from `r` into `m`; an error says why (never throw, never read past `r`).
std::optional<PayloadError> get_video(Reader& r, EncodedVideo& m);
std::optional<PayloadError> get_picture_loss(Reader& r, PictureLoss& m);
std::optional<PayloadError> get_receiver_report(Reader& r, ReceiverReport& m);
std::optional<PayloadError> get_video_nack(Reader& r, VideoNack& m);

}  // namespace telex::proto::detail
