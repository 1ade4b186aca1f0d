// SPDX-License-Identifier: MIT
// libFuzzer target: the depth decoders (raw, zip, fast, reference RVL) on arbitrary bitstreams.
#include <cstdint>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <span>

#include "telex/proto/depth_codec.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace telex::proto;
  if (size < 3) return 0;
  const int w = 1 + data[0] % 96;
  const int h = 1 + data[1] % 64;
  const int which = data[2] % 4;
  const std::span<const std::uint8_t> bits(data + 3, size - 3);
  cv::Mat1w out;
  DecodeStatus st;
  if (which == 3) {
    st = rvl_ref_decode(bits, w, h, out);
  } else {
    const auto codec = static_cast<Codec>(which);
    st = decode_depth(bits, w, h, codec, out);
    if (st == DecodeStatus::Ok) {
      // Whatever decodes is a w x h image that survives its own round trip.
      if (out.rows != h || out.cols != w) std::abort();
      cv::Mat1w again;
      if (decode_depth(encode_depth(out, codec), w, h, codec, again) != DecodeStatus::Ok ||
          cv::norm(out, again, cv::NORM_INF) != 0.0)
        std::abort();
    }
  }
  if (st == DecodeStatus::Ok && (out.rows != h || out.cols != w)) std::abort();
  return 0;
}
