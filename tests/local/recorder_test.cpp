// SPDX-License-Identifier: MIT
// Session recording and replay without the daemons: a stroke over a noisy synthetic plane, run
// through the shipped surface build and force model tick by tick as the station does, recorded,
// read back topic by topic and replayed; the recorder's queues drop and count instead of waiting.
#include "telex/local/record/recorder.h"

#include <gtest/gtest.h>
#include <pty.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <glm/geometric.hpp>
#include <string>
#include <thread>
#include <vector>

#include "process.h"
#include "telex/bag/bag.h"
#include "telex/common/synthetic.h"
#include "test_support.h"

namespace telex::local {
namespace {

std::filesystem::path temp_bag(const std::string& name) {
  return ::telex::test::scratch_file(name);
}

struct Session {
  std::uint64_t ticks = 0, surfaces = 0;
  double peak_N = 0;  // over every tick
  std::vector<std::array<glm::dvec3, kFingerCount>> forces;
};

// 3 s at 1 kHz, a depth frame every 33 ms: the index finger presses into a plane at 0.6 m and
// strokes sideways; the thumb is untracked for the middle second.
Session record_stroke(const std::string& path, const HapticParams& haptic,
                      const SurfaceOptions& surface, double record_rate_hz,
                      std::int64_t t0_ns = 5'000'000'000) {
  RecorderConfig rc;
  rc.path = path;
  rc.force_rate_hz = record_rate_hz;
  rc.monotonic_to_bag_ns = 1'700'000'000'000'000'000;
  rc.config_json = session_config_json(haptic, surface, 1000.0).dump();
  // Queues that hold the whole session (3000 ticks, 91 surfaces): the loop below does not wait
  // for the writer, and a loaded machine's writer may fall behind it.
  rc.tick_queue = 1 << 14;
  rc.surface_queue = 128;
  SessionRecorder recorder(rc);

  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  synth::Scene scene;
  scene.add_plane({0, 0, 1}, 0.6);
  synth::SensorModel sensor;
  sensor.seed = 7;
  HapticModel model(haptic, kFingerCount);
  Session out;
  std::shared_ptr<const Surface> newest;
  std::array<FingertipInput, kFingerCount> in{};
  std::array<FingertipForce, kFingerCount> f{};
  std::uint64_t seq = 0;
  for (int i = 0; i < 3000; ++i) {
    const std::int64_t t = t0_ns + static_cast<std::int64_t>(i) * 1'000'000;
    if (i % 33 == 0) {
      AssembledFrame frame;
      frame.depth_mm =
          synth::render(scene, k, sensor, static_cast<std::uint64_t>(i)).depth.depth_mm;
      frame.intrinsics = k;
      frame.frame_id = static_cast<std::uint32_t>(++seq);
      frame.capture_ns = t - 20'000'000;
      newest = build_surface(frame, surface, {});
      EXPECT_TRUE(recorder.add_surface({seq, t, frame.capture_ns, frame.depth_mm.clone(), k, ""}));
      ++out.surfaces;
    }
    const double s = i * 1e-3;
    const double depth = 0.59 + std::min(s, 1.0) * 0.02;  // 1 cm in after 1 s
    const double x = s < 1.0 ? 0.0 : 0.03 * std::sin(2.0 * (s - 1.0));
    in[1] = {{x, 0.0, depth}, glm::normalize(glm::dvec3{0.1, -1.0, 0.2}), true};
    in[0] = {{x - 0.03, 0.02, depth - 0.005}, {0, -1, 0}, !(s > 1.0 && s < 2.0)};
    for (int j = 2; j < kFingerCount; ++j) in[j] = {{0.02 * j, 0.0, 0.5}, {0, -1, 0}, true};
    model.tick(t, newest, in, f);
    RecordedTick rt;
    rt.t_ns = t;
    rt.surface_seq = seq;
    rt.in = in;
    rt.out = f;
    EXPECT_TRUE(recorder.add_tick(rt));
    std::array<glm::dvec3, kFingerCount> row{};
    for (int j = 0; j < kFingerCount; ++j) {
      row[j] = f[j].force_N;
      out.peak_N = std::max(out.peak_N, glm::length(f[j].force_N));
    }
    out.forces.push_back(row);
    ++out.ticks;
  }
  const RecorderStats st = recorder.finish();
  EXPECT_EQ(st.error, "");
  EXPECT_EQ(st.ticks, out.ticks);
  EXPECT_EQ(st.surfaces, out.surfaces);
  EXPECT_EQ(st.dropped_ticks + st.dropped_surfaces, 0u);
  return out;
}

TEST(SessionRecorder, EveryTopicIsThereInStandardTypesAndTheForcesAreThoseTheModelGave) {
  const auto path = temp_bag("stroke.bag").string();
  HapticParams haptic;
  haptic.startup_ramp_s = 0.2;
  SurfaceOptions surface;
  surface.roi = false;  // this harness builds surfaces without fingertip windows
  const Session s = record_stroke(path, haptic, surface, 1000.0);
  ASSERT_GT(s.peak_N, 1.0);

  bag::Reader r(path);
  std::map<std::string, std::pair<std::string, std::uint64_t>> topics;
  for (const auto& t : r.topics()) topics[t.topic] = {t.type, t.messages};
  EXPECT_EQ(topics[kDepthTopic], std::make_pair(std::string("sensor_msgs/Image"), s.surfaces));
  EXPECT_EQ(topics[kDepthInfoTopic],
            std::make_pair(std::string("sensor_msgs/CameraInfo"), s.surfaces));
  EXPECT_EQ(topics[kFingertipsTopic],
            std::make_pair(std::string("geometry_msgs/PoseArray"), s.ticks));
  EXPECT_EQ(topics[kConfigTopic], std::make_pair(std::string("std_msgs/String"), std::uint64_t{1}));
  EXPECT_EQ(topics["/tf"].first, "tf2_msgs/TFMessage");
  for (int i = 0; i < kFingerCount; ++i) {
    EXPECT_EQ(topics[force_topic(i)],
              std::make_pair(std::string("geometry_msgs/WrenchStamped"), s.ticks));
    EXPECT_EQ(topics[display_topic(i)],
              std::make_pair(std::string("geometry_msgs/WrenchStamped"), s.ticks));
  }
  // At --record-rate 1000 every tick's force is there, in order, to the bit.
  r.select({force_topic(1)});
  bag::Message m;
  std::uint64_t n = 0;
  double peak = 0;
  while (r.next(m)) {
    ASSERT_LT(n, s.forces.size());
    const glm::dvec3 f{m.force_N[0], m.force_N[1], m.force_N[2]};
    EXPECT_EQ(f, s.forces[n][1]) << "tick " << n;
    EXPECT_EQ(m.frame_id, kCameraFrame);
    peak = std::max(peak, glm::length(f));
    ++n;
  }
  EXPECT_EQ(n, s.ticks);
  EXPECT_EQ(peak, s.peak_N);
  // The untracked thumb has no fingertip frame on /tf while it is lost.
  r.select({"/tf"});
  std::uint64_t thumb_frames = 0, tf_messages = 0;
  while (r.next(m)) {
    ++tf_messages;
    for (const auto& t : m.transforms) thumb_frames += t.child == "telex_fingertip_thumb";
  }
  EXPECT_EQ(tf_messages, s.ticks);
  EXPECT_NEAR(static_cast<double>(thumb_frames), 2000.0, 2.0);
}

TEST(SessionRecorder, ReplayTellsItsProgressUpToTheEnd) {
  const auto path = temp_bag("progress.bag").string();
  HapticParams haptic;
  SurfaceOptions surface;
  surface.roi = false;  // this harness builds surfaces without fingertip windows
  record_stroke(path, haptic, surface, 100.0);
  std::vector<double> told;
  replay_session(path, haptic, surface, [&](double done) { told.push_back(done); });
  ASSERT_GE(told.size(), 50u);
  EXPECT_LE(told.size(), 102u) << "about every per cent";
  EXPECT_GT(told.front(), 0.0);
  for (std::size_t i = 1; i < told.size(); ++i) EXPECT_GT(told[i], told[i - 1]);
  EXPECT_EQ(told.back(), 1.0);
}

// What `telex replay` writes to stderr: its progress on a terminal (a pty here), nothing of it
// into a file.
TEST(SessionRecorder, TelexReplayShowsProgressOnlyOnATerminal) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto path = temp_bag("shown.bag").string();
  HapticParams haptic;
  SurfaceOptions surface;
  surface.roi = false;
  record_stroke(path, haptic, surface, 100.0);
  const std::string telex = ::telex::test::built_binary("telex").string();
  {
    ::telex::test::Process file({telex, "replay", path}, temp_bag("replay.out"),
                                temp_bag("replay.err"));
    ASSERT_EQ(file.wait(std::chrono::seconds(60)), 0) << file.stderr_text();
    EXPECT_EQ(file.stderr_text().find('%'), std::string::npos) << file.stderr_text();
  }
  int master = -1;
  const pid_t pid = ::forkpty(&master, nullptr, nullptr, nullptr);
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::execl(telex.c_str(), telex.c_str(), "replay", path.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  std::string shown;
  char buf[4096];
  for (ssize_t n; (n = ::read(master, buf, sizeof buf)) > 0;)
    shown.append(buf, static_cast<std::size_t>(n));
  ::close(master);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << shown;
  ::telex::test::expect_contains(shown, "telex replay: ");
  ::telex::test::expect_contains(shown, " s left)");
  ::telex::test::expect_contains(shown, "force samples compared");  // the result follows
}

TEST(SessionRecorder, ReplayWithTheRecordedParametersGivesTheRecordedForcesAndOthersDiffer) {
  const auto path = temp_bag("replay.bag").string();
  HapticParams haptic;
  haptic.startup_ramp_s = 0.2;
  haptic.stiffness_N_per_m = 350.0;
  haptic.max_force_N = 10.0;  // no clamp: the force scales with the stiffness
  SurfaceOptions surface;
  surface.roi = false;  // this harness builds surfaces without fingertip windows
  surface.bilateral_options.radius_px = 3;
  const Session s = record_stroke(path, haptic, surface, 100.0);

  HapticParams h2;
  SurfaceOptions s2;
  double rate = 0;
  read_session_config(path, h2, s2, rate);
  EXPECT_EQ(h2.stiffness_N_per_m, 350.0);
  EXPECT_EQ(h2.startup_ramp_s, 0.2);
  EXPECT_EQ(s2.bilateral_options.radius_px, 3);
  EXPECT_EQ(rate, 1000.0);

  const ReplayResult same = replay_session(path, h2, s2);
  EXPECT_EQ(same.ticks, s.ticks);
  EXPECT_EQ(same.surfaces, s.surfaces);
  EXPECT_EQ(same.rows, 5u * 300u);  // 100 Hz over 3 s, five fingers
  EXPECT_EQ(same.unmatched, 0u);
  EXPECT_LE(same.rms_diff_N, 0.01);
  EXPECT_EQ(same.max_diff_N, 0.0);  // the model is deterministic
  EXPECT_EQ(same.peak_N, same.recorded_peak_N);
  EXPECT_GT(same.recorded_peak_N, 1.0);

  HapticParams softer = h2;
  softer.stiffness_N_per_m = 175.0;
  const ReplayResult soft = replay_session(path, softer, s2);
  EXPECT_NEAR(soft.peak_N, same.recorded_peak_N / 2.0, 0.05 * same.recorded_peak_N);
  EXPECT_GT(soft.rms_diff_N, 0.1);
  HapticParams slippery = h2;
  slippery.mu_static = slippery.mu_dynamic = 0.05;
  EXPECT_GT(replay_session(path, slippery, s2).rms_diff_N, 0.01);
}

TEST(SessionRecorder, AFullQueueDropsAndCountsAndNeverWaits) {
  const auto path = temp_bag("drops.bag").string();
  RecorderConfig rc;
  rc.path = path;
  rc.tick_queue = 8;
  rc.monotonic_to_bag_ns = 1'700'000'000'000'000'000;
  std::uint64_t accepted = 0;
  const std::uint64_t pushed = 100'000;
  {
    SessionRecorder recorder(rc);
    RecordedTick t;
    for (std::uint64_t i = 0; i < pushed; ++i) {
      t.t_ns = 1'000'000 + static_cast<std::int64_t>(i) * 1000;
      accepted += recorder.add_tick(t);
    }
    const RecorderStats st = recorder.finish();
    EXPECT_EQ(st.ticks, accepted);
    EXPECT_EQ(st.ticks + st.dropped_ticks, pushed);
    EXPECT_GT(st.dropped_ticks, 0u);
  }
  bag::Reader r(path);
  for (const auto& t : r.topics())
    if (t.topic == kFingertipsTopic) {
      EXPECT_EQ(t.messages, accepted);
    }
}

// A full disk (found by tools/fault_soak.sh): the failed write used to fault the recorder's thread,
// which stopped the station, and the bag library's destructor then threw again from the failed
// close (std::terminate). Now the recording stops with its error, the recorder takes and drops
// what comes after, and nothing ends the process. The disk fills here at a file-size limit
// (RLIMIT_FSIZE, SIGXFSZ ignored): writes past it fail as on a full disk.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &saved_);
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit lim = saved_;
    lim.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &lim);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &saved_);
    std::signal(SIGXFSZ, old_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  rlimit saved_{};
  void (*old_handler_)(int) = SIG_DFL;
};

TEST(SessionRecorder, AFullDiskStopsTheRecordingOnlyAndNeverEndsTheProcess) {
  const auto path = temp_bag("full.bag").string();
  RecorderConfig rc;
  rc.path = path;
  rc.monotonic_to_bag_ns = 1'700'000'000'000'000'000;
  rc.surface_queue = 4;
  std::uint64_t offered = 0;
  const FileSizeLimit full(4 << 20);
  {
    SessionRecorder recorder(rc);
    const Intrinsics k = kinect_v1_intrinsics(640, 480);
    // Noise, so the LZ4 chunks stay large: a few of them fill the 4 MiB.
    cv::Mat1w depth(480, 640);
    cv::randu(depth, 500, 4000);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (recorder.stats().error.empty() && std::chrono::steady_clock::now() < deadline) {
      ++offered;
      const auto t = static_cast<std::int64_t>(offered) * 33'000'000;
      recorder.add_surface({offered, t, t, depth.clone(), k, ""});
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    const RecorderStats failed = recorder.stats();
    ASSERT_NE(failed.error, "") << "no write failed past 4 MiB after " << offered << " surfaces";
    EXPECT_NE(failed.error.find(path), std::string::npos) << failed.error;
    EXPECT_GT(failed.surfaces, 0u);
    EXPECT_FALSE(recorder.thread_fault().has_value())
        << "a full disk is the recording's failure, not a fault that stops the station";
    // Afterwards the recorder still takes what it is given, without waiting, and drops it.
    for (int i = 0; i < 20; ++i) recorder.add_surface({0, 0, 0, depth.clone(), k, ""});
    const RecorderStats end = recorder.finish();
    EXPECT_EQ(end.error, failed.error);
    EXPECT_GT(end.dropped_surfaces, 0u);
    std::printf("the recording stopped after %llu of %llu surfaces: %s\n",
                static_cast<unsigned long long>(end.surfaces),
                static_cast<unsigned long long>(offered), end.error.c_str());
  }  // the destructor: before, std::terminate from the bag library's second close
}

TEST(SessionRecorder, BadPathsAndBagsThatAreNotSessionsAreNamed) {
  RecorderConfig rc;
  rc.path = "/nonexistent-dir/x.bag";
  try {
    SessionRecorder r(rc);
    FAIL() << "opened " << rc.path;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot create bag /nonexistent-dir/x.bag"),
              std::string::npos)
        << e.what();
  }
  rc.path = temp_bag("rate.bag").string();
  rc.force_rate_hz = 0;
  EXPECT_THROW(SessionRecorder{rc}, std::invalid_argument);

  const auto plain = temp_bag("plain.bag").string();
  {
    bag::Writer w(plain);
    w.text("/chatter", 1'000'000'000, "hello");
  }
  HapticParams h;
  SurfaceOptions s;
  double rate = 0;
  try {
    read_session_config(plain, h, s, rate);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("is not a telex session: no std_msgs/String on "
                                         "/telex/config (it holds /chatter"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(replay_session(plain, h, s), std::runtime_error);
  nlohmann::json bad = {{"haptic", {{"stiffness_N_per_m", "stiff"}}}};
  EXPECT_THROW(apply_session_config(bad, h, s, rate), std::invalid_argument);
}

}  // namespace
}  // namespace telex::local
