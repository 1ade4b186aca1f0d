// SPDX-License-Identifier: MIT
// V4L2 buffer conversion on bytes made from a known image: YUYV and MJPEG (with and without DHT).
#include "telex/remote/v4l2_convert.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

namespace telex::remote {
namespace {

// A smooth colour image: chroma subsampling and JPEG keep it close to the original.
cv::Mat3b known_image(int w, int h) {
  cv::Mat3b img(h, w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img(y, x) =
          cv::Vec3b(static_cast<uchar>(40 + 160 * x / w), static_cast<uchar>(30 + 180 * y / h),
                    static_cast<uchar>(200 - 150 * (x + y) / (w + h)));
  return img;
}

double mean_abs_diff(const cv::Mat3b& a, const cv::Mat3b& b) {
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const cv::Scalar m = cv::mean(diff);
  return (m[0] + m[1] + m[2]) / 3.0;
}

TEST(Yuyv, RoundTripsAKnownImage) {
  const auto img = known_image(64, 48);
  const auto bytes = bgr_to_yuyv(img);
  ASSERT_EQ(bytes.size(), 64u * 48u * 2u);
  const auto r = yuyv_to_bgr(bytes, 64, 48);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_LT(mean_abs_diff(r.bgr, img), 2.0);
}

TEST(Yuyv, PureGreyHasNoChromaError) {
  // Y=126 U=V=128 is mid grey in BT.601 limited range: (126-16)*1.164 = 128.
  std::vector<std::uint8_t> bytes(8 * 2 * 2);
  for (std::size_t i = 0; i < bytes.size(); i += 2) {
    bytes[i] = 126;
    bytes[i + 1] = 128;
  }
  const auto r = yuyv_to_bgr(bytes, 8, 2);
  ASSERT_TRUE(r.ok());
  for (int x = 0; x < 8; ++x) {
    EXPECT_NEAR(r.bgr(0, x)[0], 128, 1);
    EXPECT_NEAR(r.bgr(1, x)[2], 128, 1);
  }
}

TEST(Yuyv, HonoursStridePadding) {
  const auto img = known_image(16, 4);
  const auto packed = bgr_to_yuyv(img);
  const int stride = 16 * 2 + 8;
  std::vector<std::uint8_t> padded(static_cast<std::size_t>(stride) * 4, 0xEE);
  for (int y = 0; y < 4; ++y) std::copy_n(packed.begin() + y * 32, 32, padded.begin() + y * stride);
  const auto r = yuyv_to_bgr(padded, 16, 4, stride);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(cv::norm(r.bgr, yuyv_to_bgr(packed, 16, 4).bgr, cv::NORM_INF), 0.0);
}

TEST(Yuyv, ShortOrOddBuffersAreErrorsNotCrashes) {
  std::vector<std::uint8_t> bytes(100);
  EXPECT_FALSE(yuyv_to_bgr(bytes, 64, 48).ok());
  EXPECT_NE(yuyv_to_bgr(bytes, 64, 48).error.find("100 bytes"), std::string::npos);
  EXPECT_FALSE(yuyv_to_bgr(bytes, 5, 2).ok());
  EXPECT_FALSE(yuyv_to_bgr(bytes, 4, 4, 3).ok());
}

std::vector<std::uint8_t> strip_dht(const std::vector<std::uint8_t>& jpeg) {
  std::vector<std::uint8_t> out(jpeg.begin(), jpeg.begin() + 2);
  std::size_t i = 2;
  while (i + 4 <= jpeg.size()) {
    const std::uint8_t m = jpeg[i + 1];
    if (m == 0xDA) break;
    const std::size_t len = (static_cast<std::size_t>(jpeg[i + 2]) << 8) | jpeg[i + 3];
    if (m != 0xC4)
      out.insert(out.end(), jpeg.begin() + static_cast<long>(i),
                 jpeg.begin() + static_cast<long>(i + 2 + len));
    i += 2 + len;
  }
  out.insert(out.end(), jpeg.begin() + static_cast<long>(i), jpeg.end());
  return out;
}

TEST(Mjpeg, DecodesAnEncodedKnownImage) {
  const auto img = known_image(80, 60);
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
  const auto r = mjpeg_to_bgr(jpeg, 80, 60);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_LT(mean_abs_diff(r.bgr, img), 3.0);
  EXPECT_FALSE(mjpeg_to_bgr(jpeg, 640, 480).ok());  // size mismatch is reported
}

TEST(Mjpeg, WebcamFramesWithoutHuffmanTablesDecodeIdentically) {
  const auto img = known_image(80, 60);
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 80}));
  const auto stripped = strip_dht(jpeg);
  ASSERT_LT(stripped.size(), jpeg.size());  // the DHT segments really were removed
  const auto with = mjpeg_to_bgr(jpeg);
  const auto without = mjpeg_to_bgr(stripped);
  ASSERT_TRUE(with.ok());
  ASSERT_TRUE(without.ok()) << without.error;
  EXPECT_EQ(cv::norm(with.bgr, without.bgr, cv::NORM_INF), 0.0);
}

TEST(Mjpeg, GarbageAndTruncationAreErrors) {
  std::mt19937 rng(7);
  std::vector<std::uint8_t> junk(500);
  for (auto& b : junk) b = static_cast<std::uint8_t>(rng());
  EXPECT_FALSE(mjpeg_to_bgr(junk).ok());
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", known_image(32, 32), jpeg);
  jpeg.resize(40);
  EXPECT_FALSE(mjpeg_to_bgr(jpeg).ok());
  EXPECT_FALSE(convert_v4l2_buffer(fourcc('H', '2', '6', '4'), jpeg, 32, 32).ok());
  EXPECT_NE(convert_v4l2_buffer(fourcc('H', '2', '6', '4'), jpeg, 32, 32).error.find("H264"),
            std::string::npos);
}

}  // namespace
}  // namespace telex::remote
