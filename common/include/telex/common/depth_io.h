// SPDX-License-Identifier: MIT
// Loading depth frames from the three common file formats, converted to millimetres.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "telex/common/depth_image.h"

namespace telex {

// Units of the stored values:
//   Millimetres      16-bit PNG, 1 unit = 1 mm, 0 = hole.
//   Tum              16-bit PNG, 1 unit = 1/5000 m (TUM RGB-D): mm = round(v / 5), 0 = hole.
//   KinectDisparity  raw 11-bit Kinect disparity in a 16-bit binary PGM (P5, NYU Depth format),
//                    converted with the NYU toolbox fit Z[m] = 351.3 / (1092.5 - raw);
//                    raw 2047 (the sensor's "invalid") and raw >= 1092 (no finite depth) are holes.
enum class DepthUnits { Millimetres, Tum, KinectDisparity };

// "mm" | "tum" | "kinect-disparity"; throws std::invalid_argument naming the valid spellings.
DepthUnits parse_depth_units(std::string_view text);
std::string_view to_string(DepthUnits units);

// Byte order of 16-bit PGM samples. The PGM spec says big-endian, but some Kinect tools wrote
// little-endian; Auto picks little-endian only when the big-endian reading has values above 2047
// (impossible for 11-bit disparity) and the little-endian reading has none.
enum class ByteOrder { Auto, BigEndian, LittleEndian };

// Loads a depth frame and converts it to millimetres. The intrinsics are scaled to the file's
// resolution when it differs from theirs. Throws std::runtime_error whose message names the file
// and the problem (missing, empty, wrong magic, not 16-bit, truncated, undecodable).
DepthImage load_depth(const std::filesystem::path& file, DepthUnits units,
                      const Intrinsics& intrinsics = kinect_v1_intrinsics());
DepthImage load_depth(const std::filesystem::path& file, DepthUnits units,
                      const Intrinsics& intrinsics, ByteOrder pgm_byte_order);

// Writes a CV_16UC1 millimetre image as 16-bit PNG. Throws std::runtime_error naming the file.
void save_depth_png(const std::filesystem::path& file, const cv::Mat1w& depth_mm);

// ---- the pure pieces the loaders are built from -------------------------------------------------

struct Pgm16 {
  cv::Mat1w samples;
  ByteOrder byte_order = ByteOrder::BigEndian;  // the order actually used (never Auto)
  int maxval = 0;
};
// Parses a binary 16-bit PGM (P5, maxval 256..65535, '#' comments in the header). `name` goes
// into error messages. Throws std::runtime_error on any malformed input.
Pgm16 parse_pgm16(std::span<const std::uint8_t> bytes, ByteOrder order, const std::string& name);

// 1/5000 m units to mm (round half up), 0 stays 0.
cv::Mat1w tum_to_mm(const cv::Mat1w& tum);
// Raw Kinect disparity to mm with the NYU fit; holes as documented for KinectDisparity.
cv::Mat1w kinect_disparity_to_mm(const cv::Mat1w& raw);
// Millimetres to the nearest raw disparity (2047 for holes and depths nearer than raw 0).
cv::Mat1w mm_to_kinect_disparity(const cv::Mat1w& depth_mm);

}  // namespace telex
