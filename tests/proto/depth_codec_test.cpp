// SPDX-License-Identifier: MIT
// Depth codecs: bit-exact round trips on synthetic, edge-case and real frames, every tile size.
#include "telex/proto/depth_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "telex/common/depth_io.h"
#include "telex/common/synthetic.h"
#include "test_support.h"

namespace telex::proto {
namespace {

constexpr Codec kWireCodecs[] = {Codec::Raw, Codec::Zip, Codec::Fast};

// A structured-light-like frame: a tilted plane and a box, depths quantised on the disparity
// grid, shadow holes at the box edge and sparse dropouts. Fixed seed.
cv::Mat1w structured_frame(int w, int h, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.6);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  cv::Mat1w d(h, w);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double z_m = 0.9 + 0.8 * y / h + 0.1 * x / w;
      const bool box = x > w / 3 && x < w / 2 && y > h / 3 && y < 2 * h / 3;
      if (box) z_m = 0.7;
      // Kinect disparity quantisation: depth levels are 1/(a*raw+b) for integer raw.
      const double raw = std::round((1.0 / z_m - 3.3309495161) / -0.0030711016 + noise(rng));
      const double zq = 1.0 / (raw * -0.0030711016 + 3.3309495161);
      std::uint16_t v = static_cast<std::uint16_t>(std::lround(zq * 1000.0));
      if (x >= w / 2 && x < w / 2 + 6 && y > h / 3 && y < 2 * h / 3) v = 0;  // projector shadow
      if (u(rng) < 0.01) v = 0;
      d(y, x) = v;
    }
  }
  return d;
}

cv::Mat1w noise_frame(int w, int h, std::uint32_t seed) {
  std::mt19937 rng(seed);
  cv::Mat1w d(h, w);
  for (auto& v : d) v = static_cast<std::uint16_t>(rng());
  return d;
}

void expect_round_trip(const cv::Mat1w& img, Codec codec, int level = kDefaultZipLevel) {
  const auto bytes = encode_depth(img, codec, level);
  cv::Mat1w out;
  ASSERT_EQ(decode_depth(bytes, img.cols, img.rows, codec, out), DecodeStatus::Ok)
      << codec_name(codec) << " " << img.cols << "x" << img.rows;
  ASSERT_EQ(cv::norm(img, out, cv::NORM_INF), 0.0) << codec_name(codec);
}

// Every test below that takes a codec runs once per wire codec and names it when it fails
// (CodecRoundTrip/...: Raw, Zip, Fast).
class CodecRoundTrip : public ::testing::TestWithParam<Codec> {};

std::vector<cv::Mat1w> edge_case_frames(int w, int h) {
  std::vector<cv::Mat1w> frames = {
      cv::Mat1w(h, w, std::uint16_t{0}),      // all holes
      cv::Mat1w(h, w, std::uint16_t{1234}),   // single value, no holes
      cv::Mat1w(h, w, std::uint16_t{65535}),  // the largest value
      structured_frame(w, h, 1),
      noise_frame(w, h, 2),
  };
  cv::Mat1w alternating(h, w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) alternating(y, x) = ((x + y) & 1) ? 65535 : 0;
  frames.push_back(alternating);
  // Moderate noise (residuals mostly 3..14): the zip encoder packs 4-bit symbols for it.
  cv::Mat1w moderate(h, w);
  std::mt19937 rng(11);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      moderate(y, x) = static_cast<std::uint16_t>(3000 + 40 * x + rng() % 13);
  frames.push_back(moderate);
  cv::Mat1w no_holes = structured_frame(w, h, 3);
  no_holes.setTo(500, no_holes == 0);
  frames.push_back(no_holes);
  return frames;
}

TEST_P(CodecRoundTrip, EdgeCaseFrames) {
  for (const auto& f : edge_case_frames(97, 53)) expect_round_trip(f, GetParam());
}

// rvl-ref against the bytes of the paper's own algorithm (Wilson 2017, CompressRVL/EncodeVLE:
// 3-bit groups, low first, with a continue bit; nibbles packed most significant first into 32-bit
// words, written here little-endian as on the paper's x86 host), worked out by hand:
//   0 0 1000 1001 / 999 0 0 5
//   zeros 2 -> 2; nonzeros 3 -> 3; 1000: delta 1000, zigzag 2000 = 0b11'111'010'000 -> 8 A F 3;
//   1001: zigzag 2 -> 2; 999: delta -2, zigzag 3 -> 3; zeros 2 -> 2; nonzeros 1 -> 1;
//   5: delta -994, zigzag 1987 = 0b11'111'000'011 -> B 8 F 3.
//   Words 0x238AF323 and 0x21B8F3 << 8 = 0x21B8F300.
//   All zeros (3x3): zeros 9 -> 9 1; nonzeros 0 -> 0; word 0x910 << 20 = 0x91000000.
TEST(DepthCodec, RvlReferenceWritesThePapersBytes) {
  cv::Mat1w a = (cv::Mat1w(2, 4) << 0, 0, 1000, 1001, 999, 0, 0, 5);
  const std::vector<std::uint8_t> want_a{0x23, 0xF3, 0x8A, 0x23, 0x00, 0xF3, 0xB8, 0x21};
  EXPECT_EQ(rvl_ref_encode(a), want_a);
  const std::vector<std::uint8_t> want_zeros{0x00, 0x00, 0x00, 0x91};
  EXPECT_EQ(rvl_ref_encode(cv::Mat1w(3, 3, std::uint16_t{0})), want_zeros);
  cv::Mat1w back;
  ASSERT_EQ(rvl_ref_decode(want_a, 4, 2, back), DecodeStatus::Ok);
  EXPECT_EQ(cv::norm(a, back, cv::NORM_INF), 0.0);
}

TEST(DepthCodec, RvlReferenceRoundTripsEdgeCaseFrames) {
  const int w = 97, h = 53;  // odd sizes exercise the edges of every loop
  for (const auto& f : edge_case_frames(w, h)) {
    const auto bytes = rvl_ref_encode(f);
    cv::Mat1w out;
    ASSERT_EQ(rvl_ref_decode(bytes, w, h, out), DecodeStatus::Ok);
    ASSERT_EQ(cv::norm(f, out, cv::NORM_INF), 0.0);
  }
}

// Value tables with gaps past the Rice escape (the 1000 -> 40000 jump), symbol steps that leave
// the fast encoder's four-pixel path (>= 14) and that need its raw escape (>= 20), and a frame
// without a table whose fast stream picks a Rice parameter above 0.
TEST(DepthCodec, RoundTripsWideTableGapsLargeStepsAndRiceParameters) {
  const int w = 83, h = 41;
  std::vector<std::uint16_t> levels;
  for (int i = 0; i < 32; ++i) levels.push_back(static_cast<std::uint16_t>(1000 + 37 * i));
  for (int i = 0; i < 32; ++i) levels.push_back(static_cast<std::uint16_t>(40000 + 3 * i));
  cv::Mat1w steps(h, w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      steps(y, x) = (x % 11 == 5) ? 0 : levels[static_cast<std::size_t>((x * 7 + y * 13) % 64)];
  const auto fast = encode_depth(steps, Codec::Fast);
  ASSERT_EQ(fast[0], 0x01) << "table, Rice k = 0";
  for (Codec c : kWireCodecs) {
    SCOPED_TRACE(codec_name(c));
    expect_round_trip(steps, c);
  }
  for (int level : {0, 6}) expect_round_trip(steps, Codec::Zip, level);

  cv::Mat1w ramp(h, w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      ramp(y, x) = static_cast<std::uint16_t>(1 + 700 * x + 13 * y + (x * y) % 97);
  const auto ramp_fast = encode_depth(ramp, Codec::Fast);
  EXPECT_EQ(ramp_fast[0] & 0x01, 0) << "no table";
  EXPECT_GT((ramp_fast[0] >> 1) & 0x0F, 0) << "Rice k above 0";
  for (Codec c : kWireCodecs) {
    SCOPED_TRACE(codec_name(c));
    expect_round_trip(ramp, c);
  }

  // No proper prefix of either stream decodes.
  for (const cv::Mat1w* f : {&steps, &ramp}) {
    for (Codec c : {Codec::Zip, Codec::Fast}) {
      const auto bytes = encode_depth(*f, c);
      cv::Mat1w out;
      for (std::size_t cut = 0; cut < bytes.size(); ++cut)
        ASSERT_NE(decode_depth({bytes.data(), cut}, w, h, c, out), DecodeStatus::Ok)
            << codec_name(c) << " cut at " << cut;
    }
  }
}

TEST(DepthCodec, RoundTripsEveryZipLevel) {
  const cv::Mat1w f = structured_frame(160, 120, 4);
  for (int level = 0; level <= 9; ++level) expect_round_trip(f, Codec::Zip, level);
  EXPECT_THROW(encode_depth(f, Codec::Zip, -1), std::invalid_argument);
  EXPECT_THROW(encode_depth(f, Codec::Zip, 10), std::invalid_argument);
}

TEST_P(CodecRoundTrip, TileSizesFromOnePixelUp) {
  const cv::Mat1w frame = structured_frame(128, 96, 5);
  const cv::Mat1w noise = noise_frame(128, 96, 6);
  // Every size 1..16 on both axes, then a sparse sample up to the whole frame.
  std::vector<int> sizes;
  for (int s = 1; s <= 16; ++s) sizes.push_back(s);
  for (int s : {17, 31, 33, 60, 64, 80, 95, 96}) sizes.push_back(s);
  for (int tw : sizes) {
    for (int th : sizes) {
      const cv::Rect r((tw * 7) % (128 - tw + 1), (th * 5) % (96 - th + 1), tw, th);
      expect_round_trip(frame(r), GetParam());
      expect_round_trip(noise(r), GetParam());
    }
  }
}

TEST_P(CodecRoundTrip, TileGridCoversTheFrameAndEachTileDecodesAlone) {
  const Codec c = GetParam();
  const cv::Mat1w frame = structured_frame(203, 157, 7);  // not a multiple of the tile size
  const TileGrid grid{203, 157, 40, 30};
  ASSERT_TRUE(grid.valid());
  EXPECT_EQ(grid.cols(), 6);
  EXPECT_EQ(grid.rows(), 6);
  const auto tiles = encode_tiles(frame, grid, c);
  ASSERT_EQ(tiles.size(), 36u);
  cv::Mat1w decoded(157, 203, std::uint16_t{9});
  // Decode in reverse order: no tile depends on another.
  for (auto it = tiles.rbegin(); it != tiles.rend(); ++it)
    ASSERT_EQ(decode_tile_into(it->bytes, grid, it->index, c, decoded), DecodeStatus::Ok);
  EXPECT_EQ(cv::norm(frame, decoded, cv::NORM_INF), 0.0);
  cv::Mat1w out(157, 203);
  EXPECT_EQ(decode_tile_into({}, grid, 36, Codec::Zip, out), DecodeStatus::BadGeometry);
}

TEST_P(CodecRoundTrip, RejectsTruncatedAndOversizedStreams) {
  const Codec c = GetParam();
  const cv::Mat1w f = structured_frame(80, 60, 8);
  const auto bytes = encode_depth(f, c);
  cv::Mat1w out;
  for (std::size_t cut : {std::size_t{0}, std::size_t{1}, bytes.size() / 2, bytes.size() - 1}) {
    const std::span<const std::uint8_t> part(bytes.data(), cut);
    EXPECT_NE(decode_depth(part, 80, 60, c, out), DecodeStatus::Ok) << "cut at " << cut;
  }
  // The same bytes claimed for a smaller tile must not decode either.
  EXPECT_NE(decode_depth(bytes, 40, 60, c, out), DecodeStatus::Ok);
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_NE(decode_depth(longer, 80, 60, c, out), DecodeStatus::Ok);
}

TEST(DepthCodec, RejectsBadGeometryAndUnknownCodecs) {
  cv::Mat1w out;
  EXPECT_EQ(decode_depth({}, 0, 10, Codec::Zip, out), DecodeStatus::BadGeometry);
  EXPECT_EQ(decode_depth({}, 10, 10, static_cast<Codec>(7), out), DecodeStatus::UnknownCodec);
}

// Replaces the zip header's varint body length (after the flags byte) with `claimed`.
std::vector<std::uint8_t> with_body_length(std::vector<std::uint8_t> bytes, std::uint32_t claimed) {
  std::size_t end = 1;
  while (bytes[end] & 0x80) ++end;
  ++end;
  std::vector<std::uint8_t> varint;
  do {
    varint.push_back(static_cast<std::uint8_t>((claimed & 0x7F) | (claimed > 0x7F ? 0x80 : 0)));
    claimed >>= 7;
  } while (claimed);
  bytes.erase(bytes.begin() + 1, bytes.begin() + static_cast<std::ptrdiff_t>(end));
  bytes.insert(bytes.begin() + 1, varint.begin(), varint.end());
  return bytes;
}

TEST(DepthCodec, ZipRejectsAClaimedBodyBeyondTheTile) {
  // A 10x10 all-holes tile compresses to a few bytes; claim a 1 GiB body instead.
  const auto bytes =
      with_body_length(encode_depth(cv::Mat1w(10, 10, std::uint16_t{0}), Codec::Zip), 1u << 30);
  cv::Mat1w out;
  EXPECT_EQ(decode_depth(bytes, 10, 10, Codec::Zip, out), DecodeStatus::DecompressionBomb);
}

TEST(DepthCodec, ZipStopsAtTheClaimedBodyLength) {
  // Body of a 64x64 frame, decoded as a 2x2 tile with its body length shrunk: inflate must stop
  // at the claimed size rather than write the whole stream.
  const auto bytes = with_body_length(encode_depth(structured_frame(64, 64, 9), Codec::Zip), 16);
  cv::Mat1w out;
  EXPECT_EQ(decode_depth(bytes, 2, 2, Codec::Zip, out), DecodeStatus::DecompressionBomb);
}

TEST(DepthCodec, PredictiveCodecsCompressStructuredDepth) {
  const cv::Mat1w f = structured_frame(320, 240, 10);
  const std::size_t raw = f.total() * 2;
  const std::size_t zip = encode_depth(f, Codec::Zip).size();
  const std::size_t fast = encode_depth(f, Codec::Fast).size();
  const std::size_t rvl = rvl_ref_encode(f).size();
  EXPECT_LT(zip * 4, raw);
  EXPECT_LT(fast * 4, raw);
  EXPECT_LT(fast, rvl);
}

TEST_P(CodecRoundTrip, EverySyntheticSceneWithSensorNoiseWholeAndTiled) {
  const Codec c = GetParam();
  const Intrinsics intr = kinect_v1_intrinsics(320, 240);
  for (const std::string& name : synth::Scene::names()) {
    const synth::Scene scene = synth::Scene::named(name);
    for (std::uint64_t frame = 0; frame < 2; ++frame) {
      const cv::Mat1w d =
          synth::render(scene.at_time(0.1 * frame), intr, synth::SensorModel{}, frame)
              .depth.depth_mm;
      expect_round_trip(d, c);
      const TileGrid grid{d.cols, d.rows, 80, 60};
      cv::Mat1w out(d.rows, d.cols, std::uint16_t{0});
      for (const auto& t : encode_tiles(d, grid, c))
        ASSERT_EQ(decode_tile_into(t.bytes, grid, t.index, c, out), DecodeStatus::Ok);
      EXPECT_EQ(cv::norm(d, out, cv::NORM_INF), 0.0) << name;
    }
  }
}

TEST_P(CodecRoundTrip, RealFramesWholeAndTiled) {
  TELEX_REQUIRE_REAL_DATA();
  const Codec c = GetParam();
  for (int i = 0; i < 3; ++i) {
    const auto path =
        test::real_data_dir() / "desk" / ("desk_" + std::to_string(i) + "_depth_mm.png");
    const cv::Mat1w f = load_depth(path, DepthUnits::Millimetres).depth_mm;
    ASSERT_FALSE(f.empty()) << path;
    expect_round_trip(f, c);
    const TileGrid grid{f.cols, f.rows, 80, 60};
    cv::Mat1w out(f.rows, f.cols, std::uint16_t{0});
    for (const auto& t : encode_tiles(f, grid, c))
      ASSERT_EQ(decode_tile_into(t.bytes, grid, t.index, c, out), DecodeStatus::Ok);
    EXPECT_EQ(cv::norm(f, out, cv::NORM_INF), 0.0);
  }
}

TEST(DepthCodec, RvlReferenceRoundTripsRealFrames) {
  TELEX_REQUIRE_REAL_DATA();
  for (int i = 0; i < 3; ++i) {
    const auto path =
        test::real_data_dir() / "desk" / ("desk_" + std::to_string(i) + "_depth_mm.png");
    const cv::Mat1w f = load_depth(path, DepthUnits::Millimetres).depth_mm;
    ASSERT_FALSE(f.empty()) << path;
    cv::Mat1w out;
    ASSERT_EQ(rvl_ref_decode(rvl_ref_encode(f), f.cols, f.rows, out), DecodeStatus::Ok);
    EXPECT_EQ(cv::norm(f, out, cv::NORM_INF), 0.0);
  }
}

INSTANTIATE_TEST_SUITE_P(Codecs, CodecRoundTrip, ::testing::ValuesIn(kWireCodecs),
                         [](const auto& info) { return std::string(codec_name(info.param)); });

}  // namespace
}  // namespace telex::proto
