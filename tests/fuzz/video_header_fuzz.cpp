// SPDX-License-Identifier: MIT
// libFuzzer target: the encoded stereo pair's header parser (telex/video/frame_header.h), with
// the robot head's joints (flag bit 1, protocol 7's posed pairs) and without. Any bytes give a
// status; a frame that parses holds what the header promises (a known codec, sides the codec
// takes, a bounded payload, a finite pose within pi), re-serializes to the same bytes, is
// Truncated one byte short and TrailingBytes one byte long, and takes a head pose only when it
// has none (stamp_head_pose).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <span>
#include <vector>

#include "telex/video/frame_header.h"

namespace {

using namespace telex::video;
using Bytes = std::vector<std::uint8_t>;

void check(bool ok) {
  if (!ok) std::abort();
}

bool side_fits(std::uint16_t side_px, VideoCodec codec) {
  return side_px > 0 && side_px <= kMaxEyeSidePx && (codec != VideoCodec::H264 || side_px % 2 == 0);
}

void check_header(const EncodedFrameHeader& h) {
  check(h.codec == VideoCodec::H264 || h.codec == VideoCodec::Mjpeg);
  check(side_fits(h.eye_width_px, h.codec) && side_fits(h.eye_height_px, h.codec));
  check(h.payload_bytes <= kMaxPayloadBytes);
  if (h.head_joint_rad)
    for (const float a : *h.head_joint_rad)
      check(std::isfinite(a) && std::abs(a) <= std::numbers::pi_v<float>);
}

// A posed frame keeps its pose; an unposed one takes the joints (pi itself is within bounds) and
// parses again to the same header with them, and the same payload after the longer header.
void check_stamp(std::span<const std::uint8_t> bytes, const ParsedFrame& parsed) {
  const std::array<float, 3> joints{std::numbers::pi_v<float>, -0.25f, 0.0f};
  Bytes frame(bytes.begin(), bytes.end());
  const bool stamped = stamp_head_pose(frame, joints);
  if (parsed.header.head_joint_rad) {
    check(!stamped && std::equal(frame.begin(), frame.end(), bytes.begin(), bytes.end()));
    return;
  }
  check(stamped && frame.size() == bytes.size() + kHeadPoseBytes);
  const ParsedFrame again = parse_frame(frame);
  EncodedFrameHeader want = parsed.header;
  want.head_joint_rad = joints;
  check(again.status == HeaderStatus::Ok && again.header == want &&
        std::equal(again.payload.begin(), again.payload.end(), parsed.payload.begin(),
                   parsed.payload.end()));
  // Joints the parser would refuse are refused here too, leaving the frame as it was.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Bytes untouched(bytes.begin(), bytes.end());
  check(!stamp_head_pose(untouched, {0.0f, nan, 0.0f}) &&
        std::equal(untouched.begin(), untouched.end(), bytes.begin(), bytes.end()));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  const ParsedFrame parsed = parse_frame(bytes);
  if (parsed.status != HeaderStatus::Ok) {
    check(parsed.payload.empty());
    return 0;
  }
  check_header(parsed.header);
  check(parsed.payload.size() == parsed.header.payload_bytes &&
        parsed.payload.data() == data + header_bytes(parsed.header) &&
        header_bytes(parsed.header) + parsed.payload.size() == size);
  Bytes again;
  serialize_header(parsed.header, again);
  again.insert(again.end(), parsed.payload.begin(), parsed.payload.end());
  check(again.size() == size && std::equal(again.begin(), again.end(), data));
  check(parse_frame(bytes.first(size - 1)).status == HeaderStatus::Truncated);
  again.push_back(0);
  check(parse_frame(again).status == HeaderStatus::TrailingBytes);
  check_stamp(bytes, parsed);
  return 0;
}
