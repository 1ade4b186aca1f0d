// SPDX-License-Identifier: MIT
// One valid sample of every message type, shared by the proto tests.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include "telex/proto/messages.h"

namespace telex::proto::test {

// An encoded pair as EyeEncoder writes it (header, then `payload_bytes` of payload); the bytes are
// not H.264, which the protocol does not look into. With `head_joint_rad`, the header carries the
// robot head's joints at capture as the remote daemon stamps them.
inline std::vector<std::uint8_t> encoded_pair(
    std::uint32_t payload_bytes = 9,
    std::optional<std::array<float, 3>> head_joint_rad = std::nullopt) {
  video::EncodedFrameHeader h;
  h.frame_id = 31;
  h.encode_seq = 30;
  h.capture_ns = 1'700'000'000'000'000'000;
  h.codec = video::VideoCodec::H264;
  h.is_intra = true;
  h.eye_width_px = 64;
  h.eye_height_px = 48;
  h.payload_bytes = payload_bytes;
  h.head_joint_rad = head_joint_rad;
  std::vector<std::uint8_t> b;
  video::serialize_header(h, b);
  for (std::uint32_t i = 0; i < payload_bytes; ++i) b.push_back(static_cast<std::uint8_t>(i * 7));
  return b;
}

inline std::vector<Message> sample_messages() {
  std::vector<Message> m;
  m.push_back(Hello{1, kCapDepthTcp | kCapVideo, {Codec::Zip, Codec::Fast, Codec::Raw}, 40000});
  m.push_back(Accept{0xDEADBEEF, Codec::Fast, Transport::Udp, 40001});
  m.push_back(Reject{RejectReason::NoCommonCodec, "no common codec: offered raw only"});
  m.push_back(Heartbeat{1, 2, 3, 0xFFFFFFFFFFFFFFFFull});
  m.push_back(Bye{7});
  StreamConfig sc;
  sc.registration.t_eye_depth_m = {0.025, 0.0, -0.01};
  sc.registration.scale_x = 1.05;
  sc.fps = 29.97f;
  m.push_back(sc);
  m.push_back(DepthTile{5, 400, 0, 80, 60, Codec::Zip, {1, 2, 3, 4, 5, 6, 7}});
  m.push_back(FrameManifest{42, 64, false, {0, 3, 63}, {true, {0.5f, -0.25f, 0.125f}}});
  m.push_back(EncodedVideo{encoded_pair()});
  m.push_back(RoiRequest{{{10, 20, 80, 60, 3}, {0, 0, 640, 480, 0}}});
  m.push_back(Stats{{{"tiles_sent", 123456789}, {"drops.crc", 0}}});
  m.push_back(TileNack{41, {9, 10, 17}});
  m.push_back(HeadCommand{123456789, {0.3f, -0.1f, 0.05f}, 77, 4500, DeadmanState::Pressed});
  m.push_back(PictureLoss{17, PictureLossReason::DecodeError});
  m.push_back(ReceiverReport{250'000, 180'000, 120'000, 140, 3, 40, 21'500, 23'000, -35.5f});
  m.push_back(VideoNack{41, 2});
  return m;
}

inline Header sample_header(std::uint32_t seq = 9) {
  Header h;
  h.flags = kFlagKeyFrame;
  h.session_id = 0x01020304;
  h.seq = seq;
  h.frame_id = 77;
  h.capture_ns = 1'700'000'000'123'456'789ull;
  return h;
}

}  // namespace telex::proto::test
