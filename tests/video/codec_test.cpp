// SPDX-License-Identifier: MIT
// EyeEncoder and EyeDecoder: round trips, a loss and its recovery, the rate, the failure paths.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "telex/video/eye_decoder.h"
#include "telex/video/eye_encoder.h"
#include "telex/video/quality.h"

namespace telex::video {
namespace {

using Bytes = std::vector<std::uint8_t>;
const cv::Size kEye(320, 240);

EncoderConfig config(const std::string& encoder, std::int64_t bitrate_bps = 1'000'000) {
  EncoderConfig c;
  c.encoder = encoder;
  c.eye_width_px = kEye.width;
  c.eye_height_px = kEye.height;
  c.bitrate_bps = bitrate_bps;
  return c;
}

struct Pair {
  cv::Mat3b left, right;
};
Pair scene(int index, double noise = 1.0) {
  Pair p;
  render_moving_eyes(index, kEye, noise, p.left, p.right);
  return p;
}

Bytes encode(EyeEncoder& enc, const Pair& p, int index) {
  Bytes out;
  const EncodeStatus s = enc.encode(p.left, p.right, static_cast<std::uint32_t>(index),
                                    1'000'000'000LL + index * 33'333'333LL, out);
  EXPECT_EQ(s, EncodeStatus::Ok) << encode_status_name(s);
  return out;
}

// Decodes a moving sequence and checks every pair: sizes exact, each eye close to its source
// and clearly farther from the other eye's (a swapped pair fails).
void round_trip(const std::string& encoder, double min_psnr_db) {
  auto enc = EyeEncoder::create(config(encoder));
  EyeDecoder dec;
  DecodedPair out;
  for (int i = 0; i < 20; ++i) {
    const Pair src = scene(i);
    const Bytes bytes = encode(*enc, src, i);
    ASSERT_EQ(dec.decode(bytes, out), DecodeStatus::Ok) << "pair " << i;
    EXPECT_EQ(out.header.frame_id, static_cast<std::uint32_t>(i));
    EXPECT_EQ(out.header.capture_ns, 1'000'000'000LL + i * 33'333'333LL);
    ASSERT_EQ(out.left_bgr.size(), kEye);
    ASSERT_EQ(out.right_bgr.size(), kEye);
    if (i < 3) continue;  // the rate control settles
    const double left_db = psnr_db(src.left, out.left_bgr);
    const double right_db = psnr_db(src.right, out.right_bgr);
    EXPECT_GT(left_db, min_psnr_db) << "pair " << i;
    EXPECT_GT(right_db, min_psnr_db) << "pair " << i;
    EXPECT_GT(left_db, psnr_db(src.right, out.left_bgr) + 5.0) << "left eye is the right's";
    EXPECT_GT(right_db, psnr_db(src.left, out.right_bgr) + 5.0) << "right eye is the left's";
    EXPECT_GT(ssim(src.left, out.left_bgr), 0.9);
  }
  EXPECT_EQ(enc->counters().pairs, 20u);
  EXPECT_EQ(dec.counters().pairs, 20u);
}

TEST(EyeCodec, H264RoundTripKeepsEachEyeInItsPlace) { round_trip("libx264", 30.0); }
TEST(EyeCodec, MjpegRoundTripKeepsEachEyeInItsPlace) { round_trip("mjpeg", 30.0); }

// Sides that are no multiple of the 16-pixel macroblock (the coded picture is larger) still come
// back exactly.
TEST(EyeCodec, EyesOfUnalignedSizeComeBackExactly) {
  for (const std::string name : {"libx264", "mjpeg"}) {
    EncoderConfig c = config(name);
    c.eye_width_px = 330;
    c.eye_height_px = 250;
    auto enc = EyeEncoder::create(c);
    EyeDecoder dec;
    DecodedPair out;
    for (int i = 0; i < 5; ++i) {
      cv::Mat3b left, right;
      render_moving_eyes(i, cv::Size(330, 250), 1.0, left, right);
      Bytes bytes;
      ASSERT_EQ(enc->encode(left, right, 0, 0, bytes), EncodeStatus::Ok) << name;
      ASSERT_EQ(dec.decode(bytes, out), DecodeStatus::Ok) << name << " pair " << i;
      ASSERT_EQ(out.left_bgr.size(), cv::Size(330, 250));
      ASSERT_EQ(out.right_bgr.size(), cv::Size(330, 250));
      if (i > 0) {
        EXPECT_GT(psnr_db(right, out.right_bgr), 28.0) << name << " pair " << i;
      }
    }
  }
}

TEST(EyeCodec, H264FirstPairIsIntraAndTheRestAreNot) {
  auto enc = EyeEncoder::create(config("libx264"));
  for (int i = 0; i < 40; ++i) {
    const Bytes bytes = encode(*enc, scene(i), i);
    const ParsedFrame p = parse_frame(bytes);
    ASSERT_EQ(p.status, HeaderStatus::Ok);
    EXPECT_EQ(p.header.codec, VideoCodec::H264);
    EXPECT_EQ(p.header.encode_seq, static_cast<std::uint32_t>(i));
    // Intra refresh: no periodic IDR, not even after a whole refresh period.
    EXPECT_EQ(p.header.is_intra, i == 0) << "pair " << i;
  }
}

TEST(EyeCodec, LossIsReportedUntilAnIntraPairAfterRequestIntra) {
  auto enc = EyeEncoder::create(config("libx264"));
  EyeDecoder dec;
  DecodedPair out;
  int i = 0;
  for (; i < 10; ++i) ASSERT_EQ(dec.decode(encode(*enc, scene(i), i), out), DecodeStatus::Ok);
  EXPECT_FALSE(dec.needs_intra());
  (void)encode(*enc, scene(i), i);  // lost on the link
  ++i;
  // Every pair after the loss says the reference is missing (the caller sends a PLI) ...
  for (int k = 0; k < 5; ++k, ++i) {
    EXPECT_EQ(dec.decode(encode(*enc, scene(i), i), out), DecodeStatus::MissingReference);
    EXPECT_TRUE(dec.needs_intra());
  }
  EXPECT_EQ(dec.counters().gaps, 1u);
  // ... until the encoder, told of it, sends an intra pair: the picture is back within 2 pairs.
  enc->request_intra();
  const int requested_at = i;
  for (; i < requested_at + 2; ++i) {
    const Pair src = scene(i);
    const Bytes bytes = encode(*enc, src, i);
    if (dec.decode(bytes, out) == DecodeStatus::Ok) break;
  }
  ASSERT_LT(i, requested_at + 2) << "no recovery within 2 pairs of request_intra()";
  EXPECT_FALSE(dec.needs_intra());
  EXPECT_GT(psnr_db(scene(i).left, out.left_bgr), 30.0);
  EXPECT_EQ(enc->counters().intra_requests, 1u);
  EXPECT_EQ(enc->counters().intra_pairs, 2u);  // the first pair and the requested one
}

TEST(EyeCodec, DecoderJoiningMidStreamAsksForIntra) {
  auto enc = EyeEncoder::create(config("libx264"));
  for (int i = 0; i < 5; ++i) (void)encode(*enc, scene(i), i);
  EyeDecoder dec;
  EXPECT_TRUE(dec.needs_intra());
  DecodedPair out;
  const DecodeStatus s = dec.decode(encode(*enc, scene(5), 5), out);
  EXPECT_TRUE(s == DecodeStatus::DecodeError || s == DecodeStatus::MissingReference)
      << decode_status_name(s);
  EXPECT_TRUE(dec.needs_intra());
  enc->request_intra();
  EXPECT_EQ(dec.decode(encode(*enc, scene(6), 6), out), DecodeStatus::Ok);
}

TEST(EyeCodec, SetBitrateLowersTheBytesProduced) {
  auto enc = EyeEncoder::create(config("libx264", 2'000'000));
  const auto bytes_over = [&](int first, int count) {
    std::size_t total = 0;
    for (int i = first; i < first + count; ++i) total += encode(*enc, scene(i, 4.0), i).size();
    return total;
  };
  (void)bytes_over(0, 15);
  const std::size_t high = bytes_over(15, 30);
  enc->set_bitrate(250'000);
  (void)bytes_over(45, 15);
  const std::size_t low = bytes_over(60, 30);
  EXPECT_LT(low * 3, high) << "high " << high << " B, low " << low << " B";
  // About the target: 250 kbit/s over 1 s of pairs, within a factor of 2.
  EXPECT_LT(low, 2 * 250'000 / 8);
}

TEST(EyeCodec, MjpegPassesCameraJpegsThrough) {
  auto enc = EyeEncoder::create(config("mjpeg"));
  const Pair src = scene(3);
  Bytes left_jpeg, right_jpeg;
  cv::imencode(".jpg", src.left, left_jpeg, {cv::IMWRITE_JPEG_QUALITY, 90});
  cv::imencode(".jpg", src.right, right_jpeg, {cv::IMWRITE_JPEG_QUALITY, 90});
  Bytes out;
  ASSERT_EQ(enc->encode_jpeg_pair(left_jpeg, right_jpeg, 9, 123, out), EncodeStatus::Ok);
  const ParsedFrame p = parse_frame(out);
  ASSERT_EQ(p.status, HeaderStatus::Ok);
  // The camera's bytes, untouched, after the left length.
  ASSERT_EQ(p.payload.size(), 4 + left_jpeg.size() + right_jpeg.size());
  EXPECT_TRUE(std::equal(left_jpeg.begin(), left_jpeg.end(), p.payload.begin() + 4));
  EXPECT_TRUE(std::equal(right_jpeg.begin(), right_jpeg.end(),
                         p.payload.begin() + 4 + static_cast<std::ptrdiff_t>(left_jpeg.size())));
  EyeDecoder dec;
  DecodedPair pair;
  ASSERT_EQ(dec.decode(out, pair), DecodeStatus::Ok);
  EXPECT_GT(psnr_db(cv::imdecode(left_jpeg, cv::IMREAD_COLOR), pair.left_bgr), 40.0);
  EXPECT_GT(psnr_db(cv::imdecode(right_jpeg, cv::IMREAD_COLOR), pair.right_bgr), 40.0);
  EXPECT_EQ(pair.header.frame_id, 9u);
  EXPECT_EQ(pair.header.capture_ns, 123);
}

TEST(EyeCodec, MjpegOfTheWrongSizeIsADecodeErrorAndLeavesTheEyes) {
  auto enc = EyeEncoder::create(config("mjpeg"));
  EyeDecoder dec;
  DecodedPair pair;
  ASSERT_EQ(dec.decode(encode(*enc, scene(0), 0), pair), DecodeStatus::Ok);
  const cv::Mat3b before = pair.left_bgr.clone();
  Bytes small;
  cv::Mat3b half;
  cv::resize(scene(1).left, half, kEye / 2);
  cv::imencode(".jpg", half, small);
  Bytes out;
  ASSERT_EQ(enc->encode_jpeg_pair(small, small, 1, 0, out), EncodeStatus::Ok);
  EXPECT_EQ(dec.decode(out, pair), DecodeStatus::DecodeError);
  EXPECT_EQ(cv::norm(before, pair.left_bgr, cv::NORM_INF), 0.0);
  EXPECT_EQ(dec.counters().decode_errors, 1u);
}

TEST(EyeCodec, GarbageIsABadHeaderOrDecodeErrorNeverACrash) {
  auto enc = EyeEncoder::create(config("libx264"));
  Bytes bytes = encode(*enc, scene(0), 0);
  EyeDecoder dec;
  DecodedPair out;
  EXPECT_EQ(dec.decode(Bytes(10, 0xAB), out), DecodeStatus::BadHeader);
  EXPECT_EQ(dec.last_header_status(), HeaderStatus::Truncated);
  // The payload replaced by noise of the same length.
  cv::RNG rng(7);
  for (std::size_t k = kHeaderBytes; k < bytes.size(); ++k)
    bytes[k] = static_cast<std::uint8_t>(rng.uniform(0, 256));
  const DecodeStatus s = dec.decode(bytes, out);
  EXPECT_NE(s, DecodeStatus::Ok) << decode_status_name(s);
  EXPECT_TRUE(dec.needs_intra());
}

TEST(EyeCodec, EncoderRefusesPairsOfAnotherSize) {
  for (const char* name : {"libx264", "mjpeg"}) {
    auto enc = EyeEncoder::create(config(name));
    cv::Mat3b small(kEye / 2, cv::Vec3b(1, 2, 3));
    Bytes out;
    EXPECT_EQ(enc->encode(small, small, 0, 0, out), EncodeStatus::BadInput) << name;
    EXPECT_EQ(enc->counters().failed, 1u);
  }
  auto h264 = EyeEncoder::create(config("libx264"));
  Bytes out;
  EXPECT_EQ(h264->encode_jpeg_pair(Bytes{1}, Bytes{2}, 0, 0, out), EncodeStatus::WrongCodec);
}

// This machine has no VA-API device and no NVIDIA GPU: the error must name the encoder and say
// why. Where one is present, the same test runs a pair through it instead.
TEST(EyeCodec, HardwareEncoderFailsClearlyOrWorks) {
  for (const std::string name : {"h264_vaapi", "h264_nvenc"}) {
    std::unique_ptr<EyeEncoder> enc;
    try {
      enc = EyeEncoder::create(config(name));
    } catch (const VideoError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("video encoder '" + name + "'"), std::string::npos) << what;
      const bool says_why =
          what.find("not in this libavcodec build") != std::string::npos ||
          what.find("could not open") != std::string::npos ||
          what.find("has no VA-API device at /dev/dri/renderD128") != std::string::npos;
      EXPECT_TRUE(says_why) << what;
      EXPECT_NE(what.find("libavcodec"), std::string::npos) << what;
      continue;
    }
    EyeDecoder dec;
    DecodedPair out;
    Bytes bytes;
    for (int i = 0; i < 5 && bytes.empty(); ++i)
      if (enc->encode(scene(i).left, scene(i).right, 0, 0, bytes) != EncodeStatus::Ok)
        bytes.clear();
    ASSERT_FALSE(bytes.empty()) << name;
    EXPECT_EQ(dec.decode(bytes, out), DecodeStatus::Ok) << name;
  }
}

TEST(EyeCodec, BadSettingsNameTheSetting) {
  const auto message = [](EncoderConfig c) -> std::string {
    try {
      (void)EyeEncoder::create(c);
    } catch (const VideoError& e) {
      return e.what();
    }
    return "no error";
  };
  EncoderConfig c = config("x265");
  EXPECT_NE(message(c).find("'x265' is not one of libx264"), std::string::npos) << message(c);
  c = config("libx264");
  c.eye_width_px = 321;
  EXPECT_NE(message(c).find("eye width 321 px"), std::string::npos) << message(c);
  c = config("libx264", 5);
  EXPECT_NE(message(c).find("--video-bitrate 5 bit/s"), std::string::npos) << message(c);
  c = config("libx264");
  c.preset = "warpspeed";
  EXPECT_NE(message(c).find("video encoder 'libx264' could not open"), std::string::npos)
      << message(c);
  c = config("mjpeg");
  c.jpeg_quality = 0;
  EXPECT_NE(message(c).find("JPEG quality 0"), std::string::npos) << message(c);
}

}  // namespace
}  // namespace telex::video
