// SPDX-License-Identifier: MIT
// The remote's eyes: --video-codec and --video-bitrate, the encoder's start-up check, and a
// station's Picture Loss Indication answered with an intra pair the station decodes again.
#include "telex/remote/eye_stream.h"

#include <gtest/gtest.h>

#include <sstream>

#include "process.h"
#include "telex/remote/daemon.h"
#include "telex/video/eye_decoder.h"
#include "test_client.h"
#include "test_support.h"

namespace telex::remote {
namespace {

using namespace std::chrono_literals;

TEST(EyeStream, BitRatesTakeSuffixesAndNameTheFlagWhenBad) {
  EXPECT_EQ(parse_bitrate_bps("4M"), 4'000'000);
  EXPECT_EQ(parse_bitrate_bps("2500k"), 2'500'000);
  EXPECT_EQ(parse_bitrate_bps("1.5M"), 1'500'000);
  EXPECT_EQ(parse_bitrate_bps("800000"), 800'000);
  for (const char* bad : {"", "4X", "fast", "10", "2G", "-4M", "4M "}) {
    try {
      parse_bitrate_bps(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("--video-bitrate"), std::string::npos) << e.what();
    }
  }
}

TEST(EyeStream, CodecNamesMapToEncodersAndAutoEndsInSoftware) {
  EXPECT_EQ(video_encoder_names("h264"), std::vector<std::string>{"libx264"});
  EXPECT_EQ(video_encoder_names("h264-nvenc"), std::vector<std::string>{"h264_nvenc"});
  EXPECT_EQ(video_encoder_names("auto").back(), "libx264");
  EXPECT_THROW(video_encoder_names("h265"), std::invalid_argument);
}

// This machine has neither a VA-API device nor NVENC: the start fails naming the flag, the
// encoder and libavcodec's reason; auto falls back to libx264.
TEST(EyeStream, AHardwareEncoderThatCannotOpenFailsTheStartByName) {
  EyeStreamConfig c;
  for (const char* hw : {"h264-vaapi", "h264-nvenc"}) {
    c.codec = hw;
    try {
      EyeStream s(c, 320, 240);
      GTEST_SKIP() << hw << " opened on this machine";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("--video-codec"), std::string::npos) << what;
      EXPECT_NE(what.find(hw[5] == 'v' ? "h264_vaapi" : "h264_nvenc"), std::string::npos) << what;
    }
  }
  c.codec = "auto";
  EyeStream s(c, 320, 240);
  EXPECT_FALSE(s.encoder_name().empty());
}

TEST(EyeStream, EncodesBothEyesAsOnePairAndReopensForAnotherSize) {
  EyeStreamConfig c;
  EyeStream s(c, 64, 48);
  StereoFrame f;
  f.left_bgr = cv::Mat3b(121, 161, cv::Vec3b(10, 20, 30));  // odd sides lose a column and a row
  f.right_bgr = cv::Mat3b(121, 161, cv::Vec3b(30, 20, 10));
  f.frame_id = 12;
  f.capture_ns = 5'000;
  std::vector<std::uint8_t> out;
  bool intra = false;
  ASSERT_TRUE(s.encode(f, out, intra));
  EXPECT_TRUE(intra);
  const auto parsed = video::parse_frame(out);
  ASSERT_EQ(parsed.status, video::HeaderStatus::Ok);
  EXPECT_EQ(parsed.header.eye_width_px, 160);
  EXPECT_EQ(parsed.header.eye_height_px, 120);
  EXPECT_EQ(parsed.header.frame_id, 12u);
  EXPECT_EQ(parsed.header.capture_ns, 5'000);
  EXPECT_EQ(s.counters().reopened, 1u);
  // Mismatched eyes are refused and counted, not thrown.
  f.right_bgr = cv::Mat3b(60, 80);
  EXPECT_FALSE(s.encode(f, out, intra));
  EXPECT_EQ(s.counters().failed, 1u);
}

TEST(EyeStream, MjpegPassesCameraJpegsThroughUnchanged) {
  EyeStreamConfig c;
  c.codec = "mjpeg";
  EyeStream s(c, 64, 48);
  StereoFrame f;
  f.left_bgr = cv::Mat3b(48, 64);
  f.right_bgr = cv::Mat3b(48, 64);
  f.left_jpeg = {0xFF, 0xD8, 1, 2, 0xFF, 0xD9};
  f.right_jpeg = {0xFF, 0xD8, 3, 0xFF, 0xD9};
  std::vector<std::uint8_t> out;
  bool intra = false;
  ASSERT_TRUE(s.encode(f, out, intra));
  EXPECT_EQ(s.counters().passed_through, 1u);
  const auto parsed = video::parse_frame(out);
  ASSERT_EQ(parsed.status, video::HeaderStatus::Ok);
  EXPECT_EQ(parsed.header.codec, video::VideoCodec::Mjpeg);
  // u32 left length, then the camera's bytes as they came.
  ASSERT_EQ(parsed.payload.size(), 4 + f.left_jpeg.size() + f.right_jpeg.size());
  EXPECT_TRUE(std::equal(f.left_jpeg.begin(), f.left_jpeg.end(), parsed.payload.begin() + 4));
  EXPECT_TRUE(std::equal(f.right_jpeg.begin(), f.right_jpeg.end(),
                         parsed.payload.begin() + 4 + static_cast<long>(f.left_jpeg.size())));
}

// End to end in one process: a station that loses a pair decodes damaged pictures until its PLI
// brings an intra pair; the remote counts the PLI and the intra it made.
TEST(EyeStream, APliAfterALostPairBringsAnIntraPairAndTheDecoderRecovers) {
  DaemonConfig cfg;
  cfg.depth_source = "synthetic:plane";
  cfg.stereo_source = "synthetic:sphere";
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  cfg.server.port = 0;
  cfg.stats_line = false;
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient viewer(d.port(), true, proto::kCapVideo);
  video::EyeDecoder decoder;
  video::DecodedPair pair;
  std::size_t next = 0;
  std::vector<video::DecodeStatus> seen;
  const auto decode_new = [&] {
    for (; next < viewer.video_.size(); ++next)
      seen.push_back(decoder.decode(viewer.video_[next].frame, pair));
  };
  ASSERT_TRUE(viewer.run_until([&] { return viewer.video_.size() >= 3; }, 10s));
  decode_new();
  ASSERT_EQ(seen.front(), video::DecodeStatus::Ok);
  // Lose the next pair: skip it.
  ASSERT_TRUE(viewer.run_until([&] { return viewer.video_.size() > next; }, 5s));
  ++next;
  ASSERT_TRUE(viewer.run_until([&] { return viewer.video_.size() > next + 1; }, 5s));
  decode_new();
  EXPECT_EQ(seen.back(), video::DecodeStatus::MissingReference);
  EXPECT_TRUE(decoder.needs_intra());
  viewer.send(proto::PictureLoss{0, proto::PictureLossReason::MissingReference});
  ASSERT_TRUE(viewer.run_until(
      [&] {
        decode_new();
        return !decoder.needs_intra();
      },
      10s));
  EXPECT_EQ(seen.back(), video::DecodeStatus::Ok);
  EXPECT_EQ(pair.left_bgr.size(), cv::Size(160, 120));
  EXPECT_TRUE(viewer.run_until([&] { return d.stats().plis_in == 1; }, 5s));
  EXPECT_GE(d.stats().video_intra_requests, 1u);
  EXPECT_NE(format_stats_line(d.stats(), DaemonStats{}, 1.0).find(" plis 1 "), std::string::npos);
  d.stop();
}

TEST(TelexRemoteCli, BadVideoFlagsExitTwoNamingTheFlag) {
  const auto dir = ::telex::test::scratch_dir("video_flags");
  for (const auto& [args, flag] :
       {std::pair{"--video-codec h265", "--video-codec"},
        std::pair{"--video-bitrate fast", "--video-bitrate"},
        std::pair{"--stereo synthetic:plane --video-codec h264-nvenc", "h264_nvenc"}}) {
    std::vector<std::string> argv{::telex::test::built_binary("telex-remote").string(), "--listen",
                                  "127.0.0.1:0", "--duration", "1"};
    std::istringstream words(args);
    for (std::string w; words >> w;) argv.push_back(w);
    ::telex::test::Process p(argv, dir / "out", dir / "err");
    EXPECT_EQ(p.wait(30s).value_or(-1), 2) << args;
    EXPECT_NE(p.stderr_text().find(flag), std::string::npos) << args << ": " << p.stderr_text();
  }
}

}  // namespace
}  // namespace telex::remote
