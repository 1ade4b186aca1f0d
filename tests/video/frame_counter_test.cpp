// SPDX-License-Identifier: MIT
// The frame counter in the eyes' pixels: through H.264 at 2 and 4 Mbit/s and MJPEG, at full size
// and resized by half; damaged, absent or foreign patterns read as nothing, never as a number.
#include "telex/video/frame_counter.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "telex/video/eye_decoder.h"
#include "telex/video/eye_encoder.h"
#include "telex/video/quality.h"

namespace telex::video {
namespace {

// Counters that exercise every bit: small, large, alternating, and seeded random ones.
std::vector<std::uint32_t> counters(int n) {
  std::vector<std::uint32_t> out = {0u, 1u, 0xFFFFFFFFu, 0xAAAAAAAAu, 0x55555555u, 123456789u};
  std::mt19937 rng(28);
  while (static_cast<int>(out.size()) < n) out.push_back(static_cast<std::uint32_t>(rng()));
  return out;
}

std::optional<std::uint32_t> read_half(const cv::Mat& image, int interpolation) {
  cv::Mat half;
  cv::resize(image, half, cv::Size(image.cols / 2, image.rows / 2), 0, 0, interpolation);
  return read_frame_counter(half);
}

// Stamps both eyes of a moving, noisy scene with each counter, encodes, decodes, and reads the
// counter back from each eye at full size and at half size (area and bilinear).
void round_trip(const std::string& encoder, std::int64_t bitrate_bps, cv::Size eye) {
  EncoderConfig c;
  c.encoder = encoder;
  c.eye_width_px = eye.width;
  c.eye_height_px = eye.height;
  c.bitrate_bps = bitrate_bps;
  auto enc = EyeEncoder::create(c);
  EyeDecoder dec;
  DecodedPair out;
  const auto values = counters(30);
  for (std::size_t i = 0; i < values.size(); ++i) {
    cv::Mat3b left, right;
    render_moving_eyes(static_cast<int>(i), eye, 2.0, left, right);
    stamp_frame_counter(left, values[i]);
    stamp_frame_counter(right, values[i]);
    std::vector<std::uint8_t> bytes;
    ASSERT_EQ(enc->encode(left, right, static_cast<std::uint32_t>(i), 0, bytes), EncodeStatus::Ok);
    ASSERT_EQ(dec.decode(bytes, out), DecodeStatus::Ok) << "pair " << i;
    for (const cv::Mat& decoded : {cv::Mat(out.left_bgr), cv::Mat(out.right_bgr)}) {
      EXPECT_EQ(read_frame_counter(decoded), values[i]) << encoder << " pair " << i;
      EXPECT_EQ(read_half(decoded, cv::INTER_AREA), values[i]) << encoder << " half, pair " << i;
      EXPECT_EQ(read_half(decoded, cv::INTER_LINEAR), values[i]) << encoder << " half, pair " << i;
    }
  }
}

TEST(FrameCounter, SurvivesH264At2MbitFor720pEyes) {
  round_trip("libx264", 2'000'000, cv::Size(1280, 720));
}
TEST(FrameCounter, SurvivesH264At4MbitFor720pEyes) {
  round_trip("libx264", 4'000'000, cv::Size(1280, 720));
}
TEST(FrameCounter, SurvivesH264AndMjpegForVgaEyes) {
  round_trip("libx264", 2'000'000, cv::Size(640, 480));
  round_trip("mjpeg", 0, cv::Size(640, 480));
}

TEST(FrameCounter, ReadsExactlyWithoutACodec) {
  cv::Mat3b left, right;
  render_moving_eyes(3, cv::Size(640, 480), 0.0, left, right);
  for (const std::uint32_t value : counters(200)) {
    cv::Mat image = left.clone();
    stamp_frame_counter(image, value);
    ASSERT_EQ(read_frame_counter(image), value);
    cv::Mat gray;
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
    ASSERT_EQ(read_frame_counter(gray), value) << "one channel reads too";
  }
}

// A 640x480 eye sent at another size (--video-size 1280x720 stretches 4:3 to 16:9; 800x600 and
// 320x240 keep it) reads the same, and so does one that went through H.264 at that size.
TEST(FrameCounter, ReadsAfterAResizeOfOtherFactorsAcrossAndDown) {
  cv::Mat3b left, right;
  render_moving_eyes(5, cv::Size(640, 480), 0.0, left, right);
  for (const cv::Size to :
       {cv::Size(1280, 720), cv::Size(800, 600), cv::Size(320, 240), cv::Size(1920, 1080)})
    for (const int interpolation : {cv::INTER_AREA, cv::INTER_LINEAR}) {
      cv::Mat image = left.clone();
      stamp_frame_counter(image, 0xC0FFEEu);
      cv::Mat resized;
      cv::resize(image, resized, to, 0, 0, interpolation);
      EXPECT_EQ(read_frame_counter(resized), 0xC0FFEEu) << to << " " << interpolation;
    }
  EncoderConfig c;
  c.encoder = "libx264";
  c.eye_width_px = 1280;
  c.eye_height_px = 720;
  c.bitrate_bps = 2'000'000;
  auto enc = EyeEncoder::create(c);
  EyeDecoder dec;
  DecodedPair out;
  for (std::uint32_t i = 0; i < 10; ++i) {
    cv::Mat3b l, r;
    render_moving_eyes(static_cast<int>(i), cv::Size(640, 480), 2.0, l, r);
    stamp_frame_counter(l, 100 + i);
    stamp_frame_counter(r, 100 + i);
    cv::resize(l, l, cv::Size(1280, 720), 0, 0, cv::INTER_AREA);
    cv::resize(r, r, cv::Size(1280, 720), 0, 0, cv::INTER_AREA);
    std::vector<std::uint8_t> bytes;
    ASSERT_EQ(enc->encode(l, r, i, 0, bytes), EncodeStatus::Ok);
    ASSERT_EQ(dec.decode(bytes, out), DecodeStatus::Ok) << "pair " << i;
    EXPECT_EQ(read_frame_counter(out.right_bgr), 100 + i) << "after H.264 at 1280x720, pair " << i;
  }
}

TEST(FrameCounter, StampsOnlyItsCorner) {
  cv::Mat3b left, right;
  render_moving_eyes(1, cv::Size(1280, 720), 0.0, left, right);
  cv::Mat image = left.clone();
  stamp_frame_counter(image, 42);
  const cv::Rect r = frame_counter_rect(image.size());
  EXPECT_EQ(r, cv::Rect(24, 18, 384, 108));  // cells 24 x 18 px, one in from the edges
  cv::Mat diff;
  cv::absdiff(image, cv::Mat(left), diff);
  cv::Mat outside = diff.clone();
  outside(r).setTo(cv::Scalar::all(0));
  EXPECT_EQ(cv::countNonZero(outside.reshape(1)), 0) << "pixels changed outside the pattern";
}

TEST(FrameCounter, NoPatternReadsAsNothing) {
  cv::Mat3b left, right;
  for (int i = 0; i < 20; ++i) {
    render_moving_eyes(i, cv::Size(640, 480), 2.0, left, right);
    EXPECT_FALSE(read_frame_counter(left)) << "scene " << i;
  }
  EXPECT_FALSE(read_frame_counter(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(0))));
  EXPECT_FALSE(read_frame_counter(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(255))));
  EXPECT_FALSE(read_frame_counter(cv::Mat()));
  // A pattern with one bit flipped (both its cells inverted): every pair is still clear, so only
  // the CRC stands between it and a wrong number; it catches every one-bit error.
  std::mt19937 rng(7);
  int accepted = 0;
  for (int n = 0; n < 2000; ++n) {
    cv::Mat image(480, 640, CV_8UC3, cv::Scalar::all(128));
    stamp_frame_counter(image, static_cast<std::uint32_t>(rng()));
    const cv::Rect r = frame_counter_rect(image.size());
    const int cell = r.width / 16;
    const int bit = static_cast<int>(rng() % 48);
    const cv::Rect a(r.x + 2 * (bit % 8) * cell, r.y + (bit / 8) * cell, 2 * cell, cell);
    cv::bitwise_not(image(a), image(a));
    accepted += read_frame_counter(image).has_value();
  }
  EXPECT_EQ(accepted, 0) << "a one-bit error passed the CRC";
}

TEST(FrameCounter, AWashedOutBitIsAnErasure) {
  cv::Mat image(480, 640, CV_8UC3, cv::Scalar::all(128));
  stamp_frame_counter(image, 77);
  ASSERT_EQ(read_frame_counter(image), 77u);
  const cv::Rect r = frame_counter_rect(image.size());
  const int cell = r.width / 16;
  image(cv::Rect(r.x, r.y, 2 * cell, cell)).setTo(cv::Scalar::all(128));  // bit 0 gone
  EXPECT_FALSE(read_frame_counter(image));
}

TEST(FrameCounter, ErasedItIsGoneAndTheSmoothPictureUnderItReturns) {
  // A picture smooth across the corner (a ramp in x and y): what the erase paints from the rows
  // above and below the pattern is that picture again, within a level; nothing outside changes.
  for (const cv::Size size : {cv::Size(640, 480), cv::Size(1280, 720)}) {
    cv::Mat3b ramp(size);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x)
        ramp(y, x) = cv::Vec3b(static_cast<std::uint8_t>(40 + y / 6),
                               static_cast<std::uint8_t>(60 + x / 8), 90);
    cv::Mat image = ramp.clone();
    stamp_frame_counter(image, 123456u);
    ASSERT_EQ(read_frame_counter(image), 123456u);
    erase_frame_counter(image);
    EXPECT_FALSE(read_frame_counter(image)) << size;
    cv::Mat diff;
    cv::absdiff(image, cv::Mat(ramp), diff);
    double worst = 0;
    cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
    EXPECT_LE(worst, 1.0) << size;
  }
  // One channel (a stamped picture made gray) comes back flat; an image too small for the
  // pattern is left as it is.
  cv::Mat gray(480, 640, CV_8UC1, cv::Scalar::all(100));
  cv::Mat3b bgr(480, 640, cv::Vec3b(100, 100, 100));
  stamp_frame_counter(bgr, 9);
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  ASSERT_EQ(read_frame_counter(gray), 9u);
  erase_frame_counter(gray);
  EXPECT_EQ(cv::countNonZero(gray != 100), 0);
  cv::Mat small(60, 80, CV_8UC3, cv::Scalar::all(7));
  erase_frame_counter(small);
  EXPECT_EQ(cv::countNonZero(small.reshape(1) != 7), 0);
}

TEST(FrameCounter, TooSmallAnImageIsLeftAlone) {
  cv::Mat small(60, 80, CV_8UC3, cv::Scalar::all(100));
  stamp_frame_counter(small, 5);
  EXPECT_EQ(cv::countNonZero(small.reshape(1) != 100), 0);
  EXPECT_FALSE(read_frame_counter(small));
  EXPECT_TRUE(frame_counter_rect(small.size()).empty());
}

}  // namespace
}  // namespace telex::video
