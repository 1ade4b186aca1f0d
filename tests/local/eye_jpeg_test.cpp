// SPDX-License-Identifier: MIT
// The station's eye decode: a JPEG is used only when it is the size its VideoFrame announced.
#include "telex/local/eye_jpeg.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace telex::local {
namespace {

std::vector<std::uint8_t> jpeg_of(int width, int height) {
  cv::Mat3b img(height, width, cv::Vec3b(40, 120, 200));
  cv::rectangle(img, cv::Rect(0, 0, width / 2, height / 2), cv::Scalar(255, 255, 255), -1);
  std::vector<std::uint8_t> out;
  EXPECT_TRUE(cv::imencode(".jpg", img, out));
  return out;
}

TEST(EyeJpeg, TheAnnouncedSizeIsDecoded) {
  const auto d = decode_eye_jpeg(jpeg_of(64, 48), 64, 48);
  ASSERT_EQ(d.status, EyeJpegStatus::Ok);
  EXPECT_EQ(d.bgr.cols, 64);
  EXPECT_EQ(d.bgr.rows, 48);
  EXPECT_GT(d.bgr(40, 60)[2], 150);  // the red-heavy background survived the round trip
}

TEST(EyeJpeg, AnotherSizeIsDroppedAsWrongSize) {
  const auto jpeg = jpeg_of(64, 48);
  for (const auto& [w, h] :
       std::vector<std::pair<int, int>>{{48, 64}, {640, 480}, {64, 47}, {0, 0}}) {
    const auto d = decode_eye_jpeg(jpeg, w, h);
    EXPECT_EQ(d.status, EyeJpegStatus::WrongSize) << w << "x" << h;
    EXPECT_TRUE(d.bgr.empty());
  }
}

TEST(EyeJpeg, BytesThatAreNoJpegAreUndecodable) {
  auto jpeg = jpeg_of(64, 48);
  jpeg.resize(20);
  EXPECT_EQ(decode_eye_jpeg(jpeg, 64, 48).status, EyeJpegStatus::Undecodable);
  EXPECT_EQ(decode_eye_jpeg({}, 64, 48).status, EyeJpegStatus::Undecodable);
  const std::vector<std::uint8_t> text{'h', 'e', 'l', 'l', 'o'};
  EXPECT_EQ(decode_eye_jpeg(text, 64, 48).status, EyeJpegStatus::Undecodable);
}

}  // namespace
}  // namespace telex::local
