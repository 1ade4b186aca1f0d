// SPDX-License-Identifier: MIT
// Tests of the depth file loaders on files written here and on the shared real frames.
#include "telex/common/depth_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "process.h"
#include "telex/common/synthetic.h"
#include "test_support.h"

namespace telex {
namespace {

namespace fs = std::filesystem;

class DepthIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::telex::test::scratch_dir("depth_io");
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write_bytes(const std::string& name, const std::vector<std::uint8_t>& bytes) {
    const fs::path p = dir_ / name;
    std::ofstream out(p, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    return p;
  }
  // A binary PGM written independently of the parser under test.
  fs::path write_pgm(const std::string& name, const cv::Mat1w& samples, bool big_endian,
                     const std::string& header_extra = "", int maxval = 2047) {
    std::string header = "P5\n" + header_extra + std::to_string(samples.cols) + " " +
                         std::to_string(samples.rows) + "\n" + std::to_string(maxval) + "\n";
    std::vector<std::uint8_t> bytes(header.begin(), header.end());
    for (int v = 0; v < samples.rows; ++v)
      for (int u = 0; u < samples.cols; ++u) {
        const std::uint16_t s = samples(v, u);
        const std::uint8_t hi = s >> 8, lo = s & 0xFF;
        bytes.push_back(big_endian ? hi : lo);
        bytes.push_back(big_endian ? lo : hi);
      }
    return write_bytes(name, bytes);
  }
  std::string error_of(const fs::path& p, DepthUnits units) {
    try {
      load_depth(p, units);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

cv::Mat1w random_depth_mm(int w, int h, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> d(400, 4000);
  std::bernoulli_distribution hole(0.1);
  cv::Mat1w m(h, w);
  for (auto& px : m) px = hole(rng) ? 0 : static_cast<std::uint16_t>(d(rng));
  return m;
}

TEST_F(DepthIo, MillimetrePngRoundTrip) {
  const cv::Mat1w depth = random_depth_mm(64, 48, 1);
  save_depth_png(dir_ / "d.png", depth);
  const DepthImage img = load_depth(dir_ / "d.png", DepthUnits::Millimetres);
  EXPECT_EQ(cv::norm(img.depth_mm, depth, cv::NORM_INF), 0.0);
  // Intrinsics follow the file's resolution.
  EXPECT_EQ(img.intrinsics, kinect_v1_intrinsics(64, 48));
}

TEST_F(DepthIo, TumPngConvertsFifthsOfMillimetres) {
  cv::Mat1w tum(1, 6);
  tum << 0, 5000, 5002, 5003, 12345, 65535;  // 0 hole, 1 m, 1.0004 m, 1.0006 m, ...
  ASSERT_TRUE(cv::imwrite((dir_ / "t.png").string(), tum));
  const DepthImage img = load_depth(dir_ / "t.png", DepthUnits::Tum);
  const std::vector<std::uint16_t> expect = {0, 1000, 1000, 1001, 2469, 13107};
  for (int i = 0; i < 6; ++i) EXPECT_EQ(img.depth_mm(0, i), expect[i]) << i;
}

TEST_F(DepthIo, KinectDisparityUsesNyuFormula) {
  cv::Mat1w raw(1, 6);
  raw << 0, 500, 800, 1000, 1091, 2047;
  const cv::Mat1w mm = kinect_disparity_to_mm(raw);
  EXPECT_EQ(mm(0, 0), static_cast<std::uint16_t>(std::lround(351.3 / 1092.5 * 1000)));
  EXPECT_EQ(mm(0, 1), static_cast<std::uint16_t>(std::lround(351.3 / 592.5 * 1000)));
  EXPECT_EQ(mm(0, 2), 1201);  // 351.3 / 292.5 m
  EXPECT_EQ(mm(0, 3), 3798);  // 351.3 / 92.5 m
  EXPECT_EQ(mm(0, 4), 0);     // 234 m does not fit in 16-bit mm
  EXPECT_EQ(mm(0, 5), 0);     // the sensor's invalid code
}

TEST_F(DepthIo, PgmBothByteOrdersDetectedAndMatchSyntheticTruth) {
  // A quantised synthetic frame is exactly representable as raw disparity, so the loader must
  // give back the same millimetres (within the 1 mm rounding of the mm values themselves).
  synth::SensorModel m;
  m.seed = 7;
  const synth::Rendered r =
      synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(320, 240), m);
  const cv::Mat1w raw = mm_to_kinect_disparity(r.depth.depth_mm);
  for (bool big : {true, false}) {
    SCOPED_TRACE(big ? "big-endian" : "little-endian");
    const fs::path p = write_pgm(big ? "be.pgm" : "le.pgm", raw, big, "# NYU depth\n");
    const DepthImage img = load_depth(p, DepthUnits::KinectDisparity);
    ASSERT_EQ(img.depth_mm.size(), r.depth.depth_mm.size());
    EXPECT_EQ(cv::countNonZero(img.depth_mm), cv::countNonZero(r.depth.depth_mm));
    cv::Mat diff;
    cv::absdiff(img.depth_mm, r.depth.depth_mm, diff);
    double worst;
    cv::minMaxLoc(diff, nullptr, &worst);
    EXPECT_LE(worst, 1.0);
    // The explicit flag agrees with detection, and the wrong flag is visibly wrong.
    const DepthImage forced = load_depth(p, DepthUnits::KinectDisparity, kinect_v1_intrinsics(),
                                         big ? ByteOrder::BigEndian : ByteOrder::LittleEndian);
    EXPECT_EQ(cv::norm(forced.depth_mm, img.depth_mm, cv::NORM_INF), 0.0);
    const DepthImage wrong = load_depth(p, DepthUnits::KinectDisparity, kinect_v1_intrinsics(),
                                        big ? ByteOrder::LittleEndian : ByteOrder::BigEndian);
    EXPECT_LT(cv::countNonZero(wrong.depth_mm), cv::countNonZero(img.depth_mm) / 2);
  }
}

TEST_F(DepthIo, ParsePgmReportsByteOrderUsed) {
  cv::Mat1w raw(2, 2);
  raw << 600, 2047, 900, 0;
  const fs::path le = write_pgm("le.pgm", raw, false);
  std::ifstream in(le, std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  const Pgm16 pgm = parse_pgm16(bytes, ByteOrder::Auto, "le.pgm");
  EXPECT_EQ(pgm.byte_order, ByteOrder::LittleEndian);
  EXPECT_EQ(pgm.maxval, 2047);
  EXPECT_EQ(cv::norm(pgm.samples, raw, cv::NORM_INF), 0.0);
}

TEST_F(DepthIo, ErrorsNameTheFileAndProblem) {
  const fs::path missing = dir_ / "nope.png";
  std::string e = error_of(missing, DepthUnits::Millimetres);
  EXPECT_NE(e.find("nope.png"), std::string::npos) << e;
  EXPECT_NE(e.find("no such file"), std::string::npos) << e;

  e = error_of(write_bytes("empty.png", {}), DepthUnits::Millimetres);
  EXPECT_NE(e.find("empty.png"), std::string::npos) << e;
  EXPECT_NE(e.find("zero size"), std::string::npos) << e;

  e = error_of(write_bytes("text.png", {'h', 'e', 'l', 'l', 'o'}), DepthUnits::Millimetres);
  EXPECT_NE(e.find("wrong magic"), std::string::npos) << e;

  cv::Mat1b eight(10, 10, uchar{7});
  ASSERT_TRUE(cv::imwrite((dir_ / "eight.png").string(), eight));
  e = error_of(dir_ / "eight.png", DepthUnits::Millimetres);
  EXPECT_NE(e.find("eight.png"), std::string::npos) << e;
  EXPECT_NE(e.find("not 16-bit"), std::string::npos) << e;

  // A valid 16-bit PNG cut in half.
  save_depth_png(dir_ / "full.png", random_depth_mm(64, 48, 2));
  std::ifstream in(dir_ / "full.png", std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  bytes.resize(bytes.size() / 2);
  e = error_of(write_bytes("half.png", bytes), DepthUnits::Millimetres);
  EXPECT_NE(e.find("half.png"), std::string::npos) << e;
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;

  // PGM: wrong magic, 8-bit, truncated samples, truncated header.
  e = error_of(
      write_bytes("p6.pgm", {'P', '6', '\n', '1', ' ', '1', '\n', '2', '5', '5', '\n', 0, 0, 0}),
      DepthUnits::KinectDisparity);
  EXPECT_NE(e.find("wrong magic"), std::string::npos) << e;
  cv::Mat1w raw(4, 4, std::uint16_t{100});
  e = error_of(write_pgm("eight.pgm", raw, true, "", 255), DepthUnits::KinectDisparity);
  EXPECT_NE(e.find("not 16-bit"), std::string::npos) << e;
  const fs::path full = write_pgm("full.pgm", raw, true);
  std::ifstream pin(full, std::ios::binary);
  std::vector<std::uint8_t> pbytes((std::istreambuf_iterator<char>(pin)), {});
  pbytes.pop_back();
  e = error_of(write_bytes("cut.pgm", pbytes), DepthUnits::KinectDisparity);
  EXPECT_NE(e.find("cut.pgm"), std::string::npos) << e;
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  e = error_of(write_bytes("head.pgm", {'P', '5', '\n', '6', '4'}), DepthUnits::KinectDisparity);
  EXPECT_NE(e.find("truncated"), std::string::npos) << e;
  e = error_of(
      write_bytes("zero.pgm", {'P', '5', ' ', '0', ' ', '4', ' ', '2', '0', '4', '7', '\n'}),
      DepthUnits::KinectDisparity);
  EXPECT_NE(e.find("zero size"), std::string::npos) << e;
}

TEST(DepthUnitsParse, AcceptsTheThreeSpellings) {
  EXPECT_EQ(parse_depth_units("mm"), DepthUnits::Millimetres);
  EXPECT_EQ(parse_depth_units("tum"), DepthUnits::Tum);
  EXPECT_EQ(parse_depth_units("kinect-disparity"), DepthUnits::KinectDisparity);
  for (DepthUnits u : {DepthUnits::Millimetres, DepthUnits::Tum, DepthUnits::KinectDisparity})
    EXPECT_EQ(parse_depth_units(to_string(u)), u);
  try {
    parse_depth_units("metres");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("kinect-disparity"), std::string::npos);
  }
}

TEST(DepthIoReal, DeskFramesLoad) {
  TELEX_REQUIRE_REAL_DATA();
  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE(i);
    const fs::path p =
        test::real_data_dir() / "desk" / ("desk_" + std::to_string(i) + "_depth_mm.png");
    Intrinsics k{525.0, 525.0, 320.0, 240.0, 640, 480};
    const DepthImage img = load_depth(p, DepthUnits::Millimetres, k);
    ASSERT_EQ(img.width(), 640);
    ASSERT_EQ(img.height(), 480);
    EXPECT_EQ(img.intrinsics, k);
    const double holes = static_cast<double>(count_holes(img.depth_mm)) / (640 * 480);
    EXPECT_GE(holes, 0.07);
    EXPECT_LE(holes, 0.20);
    double lo, hi;
    cv::minMaxLoc(img.depth_mm, &lo, &hi, nullptr, nullptr, img.depth_mm > 0);
    EXPECT_GE(lo, 600);
    EXPECT_LE(hi, 1800);
  }
}

}  // namespace
}  // namespace telex
