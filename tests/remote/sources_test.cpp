// SPDX-License-Identifier: MIT
// Source specs, OpenNI2's Dummy device, .oni record/playback and V4L2 open errors.
#include "telex/remote/sources.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "telex/remote/openni_record.h"

namespace telex::remote {
namespace {

using namespace std::chrono_literals;

// OpenNI2's Dummy and file drivers keep threads that outlive Device::close; repeated opens in one
// process crashed or hung here now and then, so each OpenNI test runs in a fresh process.
template <typename F>
void run_isolated(F body) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        body();
        std::exit(::testing::Test::HasFailure() ? 1 : 0);
      },
      ::testing::ExitedWithCode(0), "");
}

TEST(SourceSpec, SplitsKindArgFlagsAndValues) {
  const auto s = parse_source_spec("oni:/tmp/a.oni,loop,fast");
  EXPECT_EQ(s.kind, "oni");
  EXPECT_EQ(s.arg, "/tmp/a.oni");
  EXPECT_TRUE(s.has("loop"));
  EXPECT_TRUE(s.has("fast"));
  EXPECT_FALSE(s.has("realtime"));

  const auto f = parse_source_spec("files:/data/*.png,units=tum");
  EXPECT_EQ(f.arg, "/data/*.png");
  EXPECT_EQ(f.options.at("units"), "tum");
  EXPECT_TRUE(f.flags.empty());

  const auto bare = parse_source_spec("synthetic,animate");
  EXPECT_EQ(bare.kind, "synthetic");
  EXPECT_EQ(bare.arg, "");
  EXPECT_TRUE(bare.has("animate"));

  const auto v = parse_source_spec("v4l2:/dev/video0,/dev/video2,format=mjpeg");
  EXPECT_EQ(v.arg, "/dev/video0");
  ASSERT_EQ(v.flags.size(), 1u);
  EXPECT_EQ(v.flags[0], "/dev/video2");
}

TEST(SourceSpec, RejectsMalformedSpecsWithTheirName) {
  EXPECT_THROW(parse_source_spec(""), std::invalid_argument);
  EXPECT_THROW(parse_source_spec(":x"), std::invalid_argument);
  EXPECT_THROW(parse_source_spec("oni:a,,loop"), std::invalid_argument);
  try {
    make_depth_source("kinect2:foo");
    FAIL() << "unknown kind accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("kinect2"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("openni"), std::string::npos);
  }
  EXPECT_THROW(make_depth_source("oni:x.oni,loop,bogus"), std::invalid_argument);
  EXPECT_THROW(make_depth_source("oni:x.oni,realtime,fast"), std::invalid_argument);
  EXPECT_THROW(make_depth_source("oni"), std::invalid_argument);
}

void dummy_device_delivers_depth_frames() {
  auto source = make_depth_source("openni:Dummy");
  source->start();
  const Intrinsics k = source->intrinsics();
  EXPECT_EQ(k.width, 320);
  EXPECT_EQ(k.height, 240);
  std::uint64_t last_id = 0;
  std::int64_t last_ns = 0;
  int frames = 0;
  for (int i = 0; i < 50 && frames < 3; ++i) {
    auto r = source->read(500ms);
    if (r.status == ReadStatus::Timeout) continue;
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    EXPECT_EQ(r.frame.image.width(), 320);
    EXPECT_EQ(r.frame.image.height(), 240);
    EXPECT_GT(r.frame.frame_id, last_id);
    EXPECT_GE(r.frame.capture_ns, last_ns);
    // The Dummy device draws real depth values: not an all-zero image.
    EXPECT_GT(cv::countNonZero(r.frame.image.depth_mm), 0);
    last_id = r.frame.frame_id;
    last_ns = r.frame.capture_ns;
    ++frames;
  }
  EXPECT_EQ(frames, 3);
  source->stop();
}

TEST(OpenNiSource, DummyDeviceDeliversDepthFrames) {
  run_isolated(dummy_device_delivers_depth_frames);
}

TEST(OpenNiSource, MissingDeviceNamesItAndWhatToTry) {
  auto source = make_depth_source("openni:no-such-device-42");
  try {
    source->start();
    FAIL() << "opened a device that does not exist";
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("no-such-device-42"), std::string::npos) << msg;
    EXPECT_NE(msg.find("openni:Dummy"), std::string::npos) << msg;
  }
}

void records_dummy_then_playback_opens_and_ends() {
  const auto dir =
      std::filesystem::temp_directory_path() / ("telex_oni_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto path = dir / "dummy.oni";
  const int recorded = record_oni("Dummy", path, 10);
  ASSERT_GE(recorded, 10);
  ASSERT_GT(std::filesystem::file_size(path), 1000u);

  auto play = make_depth_source("oni:" + path.string() + ",fast");
  play->start();
  // The recording's index lists what the Recorder wrote (it may lose the one frame in flight).
  EXPECT_GE(play->frame_count(), recorded - 1);
  EXPECT_LE(play->frame_count(),
            recorded + 1);  // and one frame still in flight when counting stopped
  EXPECT_EQ(play->intrinsics().width, 320);
  EXPECT_EQ(play->intrinsics().height, 240);
  // Without loop the source must report the end instead of timing out forever. Debian's OniFile
  // driver (2.2.0.33) reaches EOF on Dummy recordings without delivering frames, so the frame
  // content is checked only for frames that do arrive.
  bool ended = false;
  int frames = 0;
  for (int i = 0; i < 40 && !ended; ++i) {
    auto r = play->read(200ms);
    if (r.status == ReadStatus::EndOfStream) ended = true;
    if (r.status == ReadStatus::Frame) {
      ++frames;
      EXPECT_EQ(r.frame.image.width(), 320);
      EXPECT_GT(cv::countNonZero(r.frame.image.depth_mm), 0);
    }
    ASSERT_NE(r.status, ReadStatus::Error) << r.error;
  }
  EXPECT_TRUE(ended);
  EXPECT_LE(frames, recorded);
  play->stop();
  std::filesystem::remove_all(dir);
}

TEST(OniPlayback, RecordsDummyThenPlaybackOpensAndEnds) {
  run_isolated(records_dummy_then_playback_opens_and_ends);
}

TEST(OniPlayback, MissingFileIsNamed) {
  auto source = make_depth_source("oni:/nonexistent/rec.oni");
  try {
    source->start();
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/rec.oni"), std::string::npos);
  }
}

TEST(V4l2Source, MissingDeviceIsNamed) {
  auto source = make_stereo_source("v4l2:/dev/video-missing-L,/dev/video-missing-R");
  try {
    source->start();
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/video-missing-L"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_stereo_source("v4l2:/dev/video0"), std::invalid_argument);
  EXPECT_THROW(make_stereo_source("v4l2:/dev/video0,/dev/video1,format=h264"),
               std::invalid_argument);
}

}  // namespace
}  // namespace telex::remote
