// SPDX-License-Identifier: MIT
// Source specs, OpenNI2's Dummy device, .oni record/playback and V4L2 open errors.
#include "telex/remote/sources.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>

#include "driver_child.h"
#include "process.h"
#include "telex/remote/openni_record.h"

namespace telex::remote {
namespace {

using telex::test::run_driver_test;

using namespace std::chrono_literals;

// The Dummy and OniFile drivers of Debian's OpenNI2 2.2.0.33 have teardown races of their own:
// OzStream::stop() never joins its frame thread (the source now waits it out before destroying a
// stream, let_driver_thread_exit in openni_source.cpp), yet on a loaded machine a driver thread
// still occasionally faults (SIGSEGV) after a recording or playback. So each OpenNI test body runs
// in a forked child (run_driver_test, tests/support/driver_child.h): a crash inside OpenNI2 with
// no failure before it is recorded as a test property and retried once; a failure, or a crash
// anywhere else, fails the test at once.

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

TEST(SourceRegistry, HelpListsEverySchemeAndUnknownSchemesNameTheValidOnes) {
  const std::string depth_help = depth_source_help(), stereo_help = stereo_source_help();
  for (const auto& s : depth_source_schemes()) {
    EXPECT_NE(depth_help.find(s.form), std::string::npos) << s.name;
    EXPECT_EQ(s.form.substr(0, s.name.size()), s.name);
  }
  for (const auto& s : stereo_source_schemes())
    EXPECT_NE(stereo_help.find(s.form), std::string::npos) << s.name;
  EXPECT_NE(stereo_help.find("files:LEFT_PATTERN,RIGHT_PATTERN[,fps=F][,loop]"), std::string::npos);
  try {
    make_stereo_source("oni:x.oni");  // a depth scheme, not a stereo one
    FAIL() << "unknown stereo scheme accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("unknown stereo source 'oni'"), std::string::npos) << what;
    EXPECT_NE(what.find("v4l2, files, bag, synthetic"), std::string::npos) << what;
  }
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
    EXPECT_NE(std::string(e.what()).find("openni, freenect, oni, files, bag, synthetic"),
              std::string::npos);
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
  run_driver_test(dummy_device_delivers_depth_frames);
}

void missing_device_names_it_and_what_to_try() {
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

TEST(OpenNiSource, MissingDeviceNamesItAndWhatToTry) {
  run_driver_test(missing_device_names_it_and_what_to_try);
}

// A fresh temp directory per process, removed at the end of the test body.
struct TempDir {
  std::filesystem::path path = ::telex::test::scratch_dir("oni");
  TempDir() { std::filesystem::create_directories(path); }
  ~TempDir() { std::filesystem::remove_all(path); }
};

struct Played {
  std::vector<cv::Mat1w> depth;
  std::vector<std::uint64_t> timestamp_us;  // the recording's timestamps
  std::vector<double> arrival_s;            // when read() returned each frame, from start()
  double end_s = 0;                         // when read() reported the end
  bool ended = false;
};

// Reads up to `max_frames` frames from `spec`; stops at the end of the recording.
Played play(const std::string& spec, int max_frames) {
  Played out;
  auto source = make_depth_source(spec);
  source->start();
  const auto t0 = std::chrono::steady_clock::now();
  const auto since = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  for (int i = 0; i < 400 && static_cast<int>(out.depth.size()) < max_frames && !out.ended; ++i) {
    auto r = source->read(200ms);
    EXPECT_NE(r.status, ReadStatus::Error) << r.error;
    if (r.status == ReadStatus::Error) break;
    if (r.status == ReadStatus::EndOfStream) {
      out.ended = true;
      out.end_s = since();
    }
    if (r.status != ReadStatus::Frame) continue;
    EXPECT_EQ(r.frame.image.width(), 320);
    EXPECT_EQ(r.frame.image.height(), 240);
    out.arrival_s.push_back(since());
    out.depth.push_back(r.frame.image.depth_mm.clone());
    out.timestamp_us.push_back(
        static_cast<std::uint64_t>(std::llround(r.frame.scene_time_s * 1e6)));
  }
  source->stop();
  return out;
}

bool same(const cv::Mat1w& a, const cv::Mat1w& b) {
  return a.size() == b.size() && cv::countNonZero(a != b) == 0;
}

// The Recorder stamps a frame with (its device time - the device time of the first frame it
// recorded). Finds that first device time from the first captured frame that equals a played one,
// then checks every captured frame that falls inside the recording against the played frame with
// its timestamp, pixel for pixel. Returns how many captured frames were compared.
int compare_with_capture(const OniCapture& capture, const Played& played) {
  std::optional<std::uint64_t> origin;
  for (int k = 0; k < capture.frames() && !origin; ++k)
    for (std::size_t j = 0; j < played.depth.size() && !origin; ++j)
      if (same(capture.depth_mm[k], played.depth[j]))
        origin = capture.device_timestamp_us[k] - played.timestamp_us[j];
  EXPECT_TRUE(origin.has_value()) << "no played frame equals any captured frame";
  if (!origin) return 0;
  int compared = 0;
  for (int k = 0; k < capture.frames(); ++k) {
    const auto ts = capture.device_timestamp_us[k] - *origin;
    for (std::size_t j = 0; j < played.depth.size(); ++j) {
      if (played.timestamp_us[j] != ts) continue;
      EXPECT_TRUE(same(capture.depth_mm[k], played.depth[j]))
          << "captured frame " << k << " differs from the played frame at " << ts << " us";
      ++compared;
      break;
    }
  }
  return compared;
}

constexpr int kRecordFrames = 12;

void playback_fast_delivers_every_recorded_frame_exactly() {
  TempDir dir;
  const auto path = dir.path / "dummy.oni";
  const OniCapture capture = record_oni_frames("Dummy", path, kRecordFrames);
  ASSERT_EQ(capture.frames(), kRecordFrames);
  // The Dummy device draws a moving pattern: consecutive frames differ, so equality below is not
  // satisfied by any frame at all.
  ASSERT_FALSE(same(capture.depth_mm[0], capture.depth_mm[1]));
  EXPECT_EQ(oni_nodes_missing_cropping(path), 0);

  auto probe = make_depth_source("oni:" + path.string() + ",fast");
  probe->start();
  const auto in_file = probe->frame_count();
  EXPECT_EQ(probe->intrinsics().width, 320);
  EXPECT_EQ(probe->intrinsics().height, 240);
  probe->stop();
  // The Recorder writes every frame the device delivered between its start and stop: the ones
  // read here, give or take the frame in flight at each end.
  EXPECT_GE(in_file, kRecordFrames - 1);
  EXPECT_LE(in_file, kRecordFrames + 3);

  // fast = the file driver's manual stepping: every frame of the file, in order, then the end.
  const Played played = play("oni:" + path.string() + ",fast", 1000);
  EXPECT_TRUE(played.ended);
  ASSERT_EQ(static_cast<std::int64_t>(played.depth.size()), in_file);
  EXPECT_EQ(played.timestamp_us.front(), 0u);
  for (std::size_t j = 1; j < played.timestamp_us.size(); ++j)
    EXPECT_GT(played.timestamp_us[j], played.timestamp_us[j - 1]);
  // Every captured frame is in the file (at most the first, read before the Recorder's thread
  // started, is missing), pixel for pixel.
  EXPECT_GE(compare_with_capture(capture, played), kRecordFrames - 1);
}

TEST(OniPlayback, FastDeliversEveryRecordedFrameExactly) {
  run_driver_test(playback_fast_delivers_every_recorded_frame_exactly);
}

void playback_realtime_delivers_recorded_frames() {
  TempDir dir;
  const auto path = dir.path / "dummy.oni";
  // 20 frames at the Dummy device's 30 Hz: about 0.63 s of recording.
  const OniCapture capture = record_oni_frames("Dummy", path, 20);
  ASSERT_EQ(capture.frames(), 20);
  // realtime: paced by the file's timestamps; a reader that falls behind misses frames (newest
  // wins), so only what arrives is compared, and the end must still be reported.
  const Played played = play("oni:" + path.string() + ",realtime", 1000);
  EXPECT_TRUE(played.ended);
  ASSERT_GE(played.depth.size(), 15u) << "a 30 Hz reader keeps up with a 30 Hz playback";
  for (std::size_t j = 1; j < played.timestamp_us.size(); ++j)
    EXPECT_GT(played.timestamp_us[j], played.timestamp_us[j - 1]);
  EXPECT_GE(compare_with_capture(capture, played), 15);
  // Paced: the frames arrive over the span of their timestamps (a playback as fast as possible
  // takes milliseconds), and each gap follows the recorded gap. The bounds leave room for a
  // loaded machine's late wake-ups, not for an unpaced playback.
  const double ts_span =
      static_cast<double>(played.timestamp_us.back() - played.timestamp_us.front()) / 1e6;
  const double wall_span = played.arrival_s.back() - played.arrival_s.front();
  ASSERT_GT(ts_span, 0.4) << "the recording's timestamps span too little";
  EXPECT_NEAR(wall_span, ts_span, 0.15 * ts_span + 0.05) << "timestamps span " << ts_span << " s";
  std::vector<double> gap_error;
  for (std::size_t j = 1; j < played.arrival_s.size(); ++j) {
    const double recorded =
        static_cast<double>(played.timestamp_us[j] - played.timestamp_us[j - 1]) / 1e6;
    const double played_gap = played.arrival_s[j] - played.arrival_s[j - 1];
    gap_error.push_back(std::abs(played_gap - recorded));
  }
  std::sort(gap_error.begin(), gap_error.end());
  EXPECT_LT(gap_error[gap_error.size() / 2], 0.010) << "median |played gap - recorded gap| (s)";
  EXPECT_GE(played.end_s, played.arrival_s.back());
}

TEST(OniPlayback, RealtimeDeliversRecordedFrames) {
  run_driver_test(playback_realtime_delivers_recorded_frames);
}

void playback_loop_wraps_around() {
  TempDir dir;
  const auto path = dir.path / "dummy.oni";
  const OniCapture capture = record_oni_frames("Dummy", path, 6);
  ASSERT_EQ(capture.frames(), 6);
  const Played once = play("oni:" + path.string() + ",fast", 1000);
  const auto n = once.depth.size();
  ASSERT_GE(n, 5u);
  // Looping never ends and repeats the file frame for frame, timestamps starting over.
  const Played looped = play("oni:" + path.string() + ",fast,loop", static_cast<int>(2 * n + 3));
  EXPECT_FALSE(looped.ended);
  ASSERT_EQ(looped.depth.size(), 2 * n + 3);
  for (std::size_t j = 0; j < looped.depth.size(); ++j) {
    EXPECT_TRUE(same(looped.depth[j], once.depth[j % n])) << "looped frame " << j;
    EXPECT_EQ(looped.timestamp_us[j], once.timestamp_us[j % n]) << "looped frame " << j;
  }
  EXPECT_GE(compare_with_capture(capture, looped), 5);
}

TEST(OniPlayback, LoopWrapsAround) { run_driver_test(playback_loop_wraps_around); }

void recorder_output_without_cropping_is_repaired_and_plays() {
  TempDir dir;
  const auto raw = dir.path / "raw.oni";
  // Exactly what openni::Recorder writes for the Dummy device: no cropping record, which OpenNI2's
  // file driver needs before it delivers a frame.
  const OniCapture capture = record_oni_frames("Dummy", raw, 8, 1000ms, /*repair=*/false);
  ASSERT_EQ(capture.frames(), 8);
  EXPECT_EQ(oni_nodes_missing_cropping(raw), 1);
  const auto raw_size = std::filesystem::file_size(raw);

  // The source plays such a file from a repaired temp copy and leaves the original alone.
  const Played played = play("oni:" + raw.string() + ",fast", 1000);
  EXPECT_TRUE(played.ended);
  EXPECT_GE(compare_with_capture(capture, played), 7);
  EXPECT_EQ(std::filesystem::file_size(raw), raw_size);
  EXPECT_EQ(oni_nodes_missing_cropping(raw), 1);

  // Repair into a new file: one record inserted; repairing that again changes nothing.
  const auto fixed = dir.path / "fixed.oni";
  EXPECT_EQ(repair_oni_for_playback(raw, fixed), 1);
  EXPECT_EQ(oni_nodes_missing_cropping(fixed), 0);
  const auto fixed_size = std::filesystem::file_size(fixed);
  EXPECT_GT(fixed_size, raw_size);
  EXPECT_EQ(repair_oni_for_playback(fixed, fixed), 0);
  EXPECT_EQ(std::filesystem::file_size(fixed), fixed_size);
  const Played replayed = play("oni:" + fixed.string() + ",fast", 1000);
  ASSERT_EQ(replayed.depth.size(), played.depth.size());
  for (std::size_t j = 0; j < played.depth.size(); ++j)
    EXPECT_TRUE(same(replayed.depth[j], played.depth[j]));
}

TEST(OniPlayback, RecorderOutputWithoutCroppingIsRepairedAndPlays) {
  run_driver_test(recorder_output_without_cropping_is_repaired_and_plays);
}

TEST(OniRepair, RejectsFilesThatAreNotRecordingsByName) {
  const auto path = ::telex::test::scratch_dir("not_oni") / "not.oni";
  {
    std::ofstream f(path, std::ios::binary);
    f << "NI10 this is not a recording at all, just some bytes";
  }
  try {
    oni_nodes_missing_cropping(path);
    FAIL() << "parsed junk";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
  EXPECT_THROW(repair_oni_for_playback(path, path.string() + ".out"), std::runtime_error);
  EXPECT_THROW(oni_nodes_missing_cropping("/nonexistent/x.oni"), std::runtime_error);
  std::filesystem::remove(path);
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
