// SPDX-License-Identifier: MIT
// The remote daemon end to end over loopback: Dummy device, tile skipping, refusals, timeouts, CLI.
#include "telex/remote/daemon.h"

#include <gtest/gtest.h>
#include <sched.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <thread>

#include "process.h"
#include "telex/base/periodic.h"
#include "telex/video/eye_decoder.h"
#include "test_client.h"
#include "test_support.h"

namespace telex::remote {
namespace {

using namespace std::chrono_literals;

// Records the sender's view of every processed frame, keyed by frame id.
struct SenderLog {
  std::mutex mu;
  std::map<std::uint32_t, cv::Mat1w> views;
  std::map<std::uint32_t, bool> keys;
  void attach(RemoteDaemon& d) {
    d.set_frame_observer([this](const ProcessedFrame& f) {
      std::lock_guard lock(mu);
      views[f.frame_id] = f.sent_view_mm;
      keys[f.frame_id] = f.key_frame;
    });
  }
  cv::Mat1w view(std::uint32_t id) {
    std::lock_guard lock(mu);
    auto it = views.find(id);
    return it == views.end() ? cv::Mat1w() : it->second;
  }
};

DaemonConfig base_config(const std::string& source) {
  DaemonConfig c;
  c.depth_source = source;
  c.server.port = 0;
  c.stats_line = false;
  return c;
}

struct ThreadPolicy {
  std::string name;
  int policy = 0, priority = 0;
};

// What the kernel holds for each thread of this process: name, policy and rt_priority
// (/proc/self/task/*/stat fields 2, 41 and 40).
std::vector<ThreadPolicy> thread_policies() {
  std::vector<ThreadPolicy> out;
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream in(e.path() / "stat");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto open = text.find('('), close = text.rfind(')');  // the name may hold spaces
    if (open == std::string::npos || close == std::string::npos) continue;
    std::istringstream fields(text.substr(close + 2));
    std::vector<std::string> f{std::istream_iterator<std::string>(fields), {}};
    if (f.size() < 39) continue;
    // f[0] is field 3.
    out.push_back(
        {text.substr(open + 1, close - open - 1), std::stoi(f[41 - 3]), std::stoi(f[40 - 3])});
  }
  return out;
}

// Whether this machine grants SCHED_FIFO (CAP_SYS_NICE or an RLIMIT_RTPRIO).
bool fifo_granted() {
  bool granted = false;
  std::thread t([&] { granted = try_realtime(1).rfind("SCHED_FIFO", 0) == 0; });
  t.join();
  return granted;
}

// The threads from capture to the network run SCHED_FIFO 50 and the head loop 60, so other
// programs on the robot's computer cannot delay depth (docs/BENCHMARKS.md); --no-realtime leaves
// them all as started. What the kernel holds is read back from /proc by thread name.
TEST(RemoteDaemon, ThreadsFromCaptureToTheNetworkRunRealtimeUnlessTurnedOff) {
  const bool granted = fifo_granted();
  // First without video: the synthetic scene's render on the capture thread is then this
  // process's first parallel OpenCV call (run alone, as ctest runs it).
  for (const auto& [realtime, video] : {std::pair{true, false}, {true, true}, {false, true}}) {
    SCOPED_TRACE(std::string(realtime ? "realtime" : "--no-realtime") +
                 (video ? ", video" : ", no video"));
    DaemonConfig cfg = base_config("synthetic:plane");
    cfg.head = "sim";
    if (video) cfg.stereo_source = "synthetic:sphere";
    cfg.realtime = realtime;
    RemoteDaemon d(cfg);
    d.start();
    std::vector<std::string> names;
    for (const auto& [name, how] : d.scheduling()) {
      names.push_back(name);
      if (!realtime)
        EXPECT_EQ(how, "default scheduling") << name;
      else if (granted)
        EXPECT_EQ(how, name == "head" ? "SCHED_FIFO priority 60" : "SCHED_FIFO priority 50")
            << name;
      else
        EXPECT_NE(how.find("refused"), std::string::npos) << name << ": " << how;
    }
    EXPECT_EQ(names, (std::vector<std::string>{"capture", "process", "network", "head"}));
    const bool fifo = realtime && granted;
    const std::map<std::string, int> want{{"telex-capture", kRemotePathPriority},
                                          {"telex-process", kRemotePathPriority},
                                          {"telex-net", kRemotePathPriority},
                                          {"telex-head", kHeadLoopPriority},
                                          {"telex-stereo", 0},
                                          {"telex-video", 0}};
    std::map<std::string, int> seen;
    for (const auto& t : thread_policies()) {
      if (!want.contains(t.name)) {
        // Nothing else: OpenCV's workers (the synthetic scene's render) stay below the path.
        EXPECT_NE(t.policy, SCHED_FIFO) << t.name << " at " << t.priority;
        continue;
      }
      seen[t.name] = t.policy == SCHED_FIFO ? t.priority : 0;
      if (t.policy != SCHED_FIFO) {
        EXPECT_EQ(t.policy, SCHED_OTHER) << t.name;
      }
    }
    std::map<std::string, int> expected = want;
    if (!video) expected.erase("telex-stereo"), expected.erase("telex-video");
    if (!fifo) {
      for (auto& [name, prio] : expected) prio = 0;
    }
    EXPECT_EQ(seen, expected);  // video and the stereo capture stay below the depth path
    const DaemonStats s = d.stats();
    EXPECT_EQ(s.path_threads, 4);
    EXPECT_EQ(s.realtime_threads, fifo ? 4 : 0);
    EXPECT_NE(format_stats_line(s, DaemonStats{}, 1.0).find(fifo ? "realtime 4/4" : "realtime 0/4"),
              std::string::npos);
    d.stop();
  }
  // Where the machine refuses SCHED_FIFO, what was checked is that each thread says so.
}

TEST(RemoteDaemon, DummyDeviceFramesReachTheClientIntactOverUdp) {
  SenderLog log;  // declared first: outlives the daemon thread that feeds it
  RemoteDaemon d(base_config("openni:Dummy"));
  log.attach(d);
  d.start();
  test::TestClient client(d.port(), /*udp=*/true);
  ASSERT_TRUE(client.run_until([&] { return client.frames_.size() >= 5; }, 10s))
      << "frames received: " << client.frames_.size();
  ASSERT_TRUE(client.accept_.has_value());
  EXPECT_EQ(client.accept_->transport, proto::Transport::Udp);
  ASSERT_TRUE(client.config_.has_value());
  EXPECT_EQ(client.config_->width, 320);
  EXPECT_EQ(client.config_->height, 240);
  EXPECT_EQ(client.decode_errors_, 0u) << client.last_error_;
  for (const auto& [id, f] : client.frames_) {
    const cv::Mat1w sent = log.view(id);
    ASSERT_FALSE(sent.empty());
    EXPECT_EQ(cv::norm(f.depth_mm, sent, cv::NORM_INF), 0.0) << "frame " << id;
  }
  EXPECT_TRUE(client.frames_.begin()->second.key_frame);  // a new receiver starts with a key frame
  client.close();
  d.stop();
}

TEST(RemoteDaemon, StaticNoisySceneSkipsTilesAndReceiverMatchesSender) {
  auto cfg = base_config("synthetic:plane");
  cfg.source_options.synthetic_fps = 30;
  cfg.pipeline.stabilise_k_sigma = 5.0;
  cfg.pipeline.key_frame_every = 1000;  // measure the skipping, not the key frame interval
  SenderLog log;                        // declared first: outlives the daemon thread that feeds it
  RemoteDaemon d(cfg);
  log.attach(d);
  d.start();
  test::TestClient client(d.port(), true);
  ASSERT_TRUE(client.run_until([&] { return client.frames_.size() >= 16; }, 30s))
      << client.frames_.size() << " frames; daemon processed " << d.stats().frames_processed
      << ", sent " << d.stats().frames_sent << ", queue drops " << d.stats().frames_queue_dropped
      << "; client decode errors " << client.decode_errors_ << ", reassembled "
      << client.reassembly().completed << ", stale " << client.reassembly().stale << ", timed out "
      << client.reassembly().dropped_timeout << ", superseded "
      << client.reassembly().dropped_superseded << ", malformed " << client.reassembly().malformed;
  EXPECT_EQ(client.decode_errors_, 0u);
  const auto first = client.frames_.begin();
  ASSERT_TRUE(first->second.key_frame);
  std::size_t later_bytes = 0, later_frames = 0;
  for (auto it = std::next(first); it != client.frames_.end(); ++it) {
    later_bytes += it->second.wire_bytes;
    ++later_frames;
    EXPECT_EQ(cv::norm(it->second.depth_mm, log.view(it->first), cv::NORM_INF), 0.0)
        << "frame " << it->first;
  }
  const double key_bytes = static_cast<double>(first->second.wire_bytes);
  const double mean_later = static_cast<double>(later_bytes) / static_cast<double>(later_frames);
  RecordProperty("key_frame_bytes", std::to_string(key_bytes));
  RecordProperty("mean_later_frame_bytes", std::to_string(mean_later));
  std::printf("static plane: key frame %.0f B, later frames mean %.0f B (%.1fx less)\n", key_bytes,
              mean_later, key_bytes / mean_later);
  EXPECT_GE(key_bytes / mean_later, 10.0);
  client.close();
  d.stop();
}

TEST(RemoteDaemon, TcpTransportCarriesTheSameFrames) {
  auto cfg = base_config("synthetic:box,noise=on");
  cfg.server.force_tcp = true;
  cfg.source_options.synthetic_fps = 30;
  cfg.source_options.width = 320;
  cfg.source_options.height = 240;
  SenderLog log;  // declared first: outlives the daemon thread that feeds it
  RemoteDaemon d(cfg);
  log.attach(d);
  d.start();
  test::TestClient client(d.port(), true);  // offers UDP, server insists on TCP
  ASSERT_TRUE(client.run_until([&] { return client.frames_.size() >= 4; }, 10s));
  EXPECT_EQ(client.accept_->transport, proto::Transport::Tcp);
  for (const auto& [id, f] : client.frames_)
    EXPECT_EQ(cv::norm(f.depth_mm, log.view(id), cv::NORM_INF), 0.0);
  d.stop();
}

TEST(RemoteDaemon, SecondOperatorIsRejectedWithAReasonAndHeartbeatsAreAnswered) {
  auto cfg = base_config("synthetic:plane");
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient first(d.port(), true);
  ASSERT_TRUE(first.run_until([&] { return first.accept_.has_value(); }, 5s));
  test::TestClient second(d.port(), true);
  ASSERT_TRUE(second.run_until([&] { return second.reject_.has_value(); }, 5s));
  EXPECT_EQ(second.reject_->reason, proto::RejectReason::Busy);
  EXPECT_NE(second.reject_->text.find("another operator"), std::string::npos);
  EXPECT_FALSE(second.accept_.has_value());

  proto::Heartbeat hb;
  hb.t1_ns = 12345;
  first.send(hb);
  ASSERT_TRUE(first.run_until([&] { return !first.heartbeats_.empty(); }, 5s));
  EXPECT_EQ(first.heartbeats_[0].t1_ns, 12345u);
  EXPECT_GE(first.heartbeats_[0].t3_ns, first.heartbeats_[0].t2_ns);
  EXPECT_EQ(d.stats().clients_rejected, 1u);
  d.stop();
}

std::uint64_t ended(const RemoteDaemon& d, SessionEnd why) {
  return d.stats().sessions_ended[static_cast<std::size_t>(why)];
}
std::uint64_t ended_total(const RemoteDaemon& d) {
  std::uint64_t n = 0;
  for (auto v : d.stats().sessions_ended) n += v;
  return n;
}
// Waits until the daemon has counted `n` session ends in all.
bool wait_ended(const RemoteDaemon& d, std::uint64_t n) {
  for (int i = 0; i < 500 && ended_total(d) < n; ++i) std::this_thread::sleep_for(10ms);
  return ended_total(d) == n;
}

TEST(RemoteDaemon, EachSessionEndIsCountedUnderItsReasonAndShownInTheStatsLine) {
  auto cfg = base_config("synthetic:plane");
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  RemoteDaemon d(cfg);
  d.start();
  const DaemonStats before = d.stats();
  {
    test::TestClient polite(d.port(), true);
    ASSERT_TRUE(polite.run_until([&] { return polite.accept_.has_value(); }, 5s));
    polite.send(proto::Bye{});
    ASSERT_TRUE(wait_ended(d, 1));
    EXPECT_EQ(ended(d, SessionEnd::ClientBye), 1u);
  }
  {
    test::TestClient abrupt(d.port(), true);
    ASSERT_TRUE(abrupt.run_until([&] { return abrupt.accept_.has_value(); }, 5s));
    abrupt.close();
    ASSERT_TRUE(wait_ended(d, 2));
    EXPECT_EQ(ended(d, SessionEnd::ConnectionLost), 1u);
  }
  const std::string line = format_stats_line(d.stats(), before, 1.0);
  EXPECT_NE(line.find("ended client-bye=1 connection-lost=1"), std::string::npos) << line;
  d.stop();
  EXPECT_EQ(ended(d, SessionEnd::ServerStopping), 0u);  // nobody was connected at the stop
}

TEST(RemoteDaemon, SilentClientTimesOutAndTheNextIsAccepted) {
  auto cfg = base_config("synthetic:plane");
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  cfg.server.client_timeout = 300ms;
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient silent(d.port(), true);
  ASSERT_TRUE(silent.run_until([&] { return silent.accept_.has_value(); }, 5s));
  ASSERT_TRUE(silent.run_until([&] { return silent.tcp_closed_; }, 5s));  // the server hung up
  EXPECT_EQ(d.stats().client_timeouts, 1u);
  EXPECT_EQ(ended(d, SessionEnd::ClientSilent), 1u);
  EXPECT_EQ(ended_total(d), 1u);
  test::TestClient next(d.port(), true);
  ASSERT_TRUE(
      next.run_until([&] { return next.accept_.has_value() && !next.frames_.empty(); }, 5s));
  EXPECT_GT(next.accept_->session_id, silent.accept_->session_id);
  d.stop();
}

TEST(RemoteDaemon, MalformedBytesAreCountedAndTheServerKeepsServing) {
  auto cfg = base_config("synthetic:plane");
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  RemoteDaemon d(cfg);
  d.start();
  {
    test::TestClient bad(d.port(), true);
    ASSERT_TRUE(bad.run_until([&] { return bad.accept_.has_value(); }, 5s));
    std::vector<std::uint8_t> junk(64, 0xAB);
    junk[0] = 60;  // a length prefix that frames 60 bytes of garbage
    junk[1] = junk[2] = junk[3] = 0;
    bad.send_raw(junk);
    ASSERT_TRUE(bad.run_until([&] { return bad.tcp_closed_; }, 5s));
  }
  EXPECT_GE(d.stats().malformed_in, 1u);
  EXPECT_EQ(ended(d, SessionEnd::Unparseable), 1u);
  EXPECT_EQ(ended_total(d), 1u);
  test::TestClient good(d.port(), true);
  ASSERT_TRUE(good.run_until([&] { return !good.frames_.empty(); }, 5s));
  d.stop();
}

TEST(RemoteDaemon, VideoIsSentOnlyWhenAsked) {
  auto cfg = base_config("synthetic:plane");
  cfg.stereo_source = "synthetic:sphere";
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient plain(d.port(), true);
  ASSERT_TRUE(plain.run_until([&] { return plain.frames_.size() >= 5; }, 5s));
  EXPECT_TRUE(plain.video_.empty());
  plain.close();
  test::TestClient viewer(d.port(), true, proto::kCapVideo);
  ASSERT_TRUE(viewer.run_until([&] { return viewer.video_.size() >= 2; }, 10s));
  // Both eyes in one H.264 pair (the default --video-codec), the first decodable alone.
  const auto first = video::parse_frame(viewer.video_[0].frame);
  ASSERT_EQ(first.status, video::HeaderStatus::Ok);
  EXPECT_EQ(first.header.codec, video::VideoCodec::H264);
  EXPECT_TRUE(first.header.is_intra);
  EXPECT_FALSE(first.header.head_joint_rad.has_value());  // no head: no pose
  EXPECT_EQ(first.header.eye_width_px, 160);
  EXPECT_EQ(first.header.eye_height_px, 120);
  video::EyeDecoder decoder;
  video::DecodedPair pair;
  EXPECT_EQ(decoder.decode(viewer.video_[0].frame, pair), video::DecodeStatus::Ok);
  EXPECT_EQ(pair.left_bgr.size(), cv::Size(160, 120));
  EXPECT_EQ(pair.right_bgr.size(), cv::Size(160, 120));
  d.stop();
}

// With a head the pairs carry its joints at their capture (PROTOCOL.md 2.7, version 7): the
// operator turns the head's yaw target to 0.3 rad, the sim servos follow it late, and the pairs
// show the yaw growing along the encoder's sequence, never past the target. Without a head (the
// test above) the pairs carry none.
TEST(RemoteDaemon, EyePairsCarryTheHeadsJointsAtTheirCapture) {
  auto cfg = base_config("synthetic:plane");
  cfg.stereo_source = "synthetic:sphere";
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  cfg.head = "sim";
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient viewer(d.port(), true, proto::kCapVideo);
  std::uint32_t sample_id = 0;
  const auto turned = [&] {
    for (const auto& v : viewer.video_) {
      const auto p = video::parse_frame(v.frame);
      if (p.header.head_joint_rad && (*p.header.head_joint_rad)[0] > 0.2f) return true;
    }
    return false;
  };
  const auto posed_pairs = [&] {
    int n = 0;
    for (const auto& v : viewer.video_)
      n += video::parse_frame(v.frame).header.head_joint_rad ? 1 : 0;
    return n;
  };
  // Until a pair shows the turn, and two carry joints to compare: the sim head moves in real
  // time, so in the slower sanitizer builds the first pair with joints could already show it.
  for (int i = 0; i < 1000 && (!turned() || posed_pairs() < 2); ++i) {
    viewer.send(proto::HeadCommand{static_cast<std::uint64_t>(steady_now_ns()),
                                   {0.3f, 0.0f, 0.0f},
                                   ++sample_id,
                                   0,
                                   proto::DeadmanState::NotUsed});
    viewer.run_until([] { return false; }, 10ms);
  }
  d.stop();
  ASSERT_TRUE(turned()) << viewer.video_.size() << " pairs";
  float previous_yaw = -1.0f;
  int posed = 0;
  for (const auto& v : viewer.video_) {
    const auto p = video::parse_frame(v.frame);
    ASSERT_EQ(p.status, video::HeaderStatus::Ok);
    // Only a pair captured before the head loop's first reading may go without.
    if (posed == 0 && !p.header.head_joint_rad) continue;
    ASSERT_TRUE(p.header.head_joint_rad.has_value()) << "pair " << p.header.encode_seq;
    const float yaw = (*p.header.head_joint_rad)[0];
    EXPECT_GE(yaw, previous_yaw - 1e-4f) << "pair " << p.header.encode_seq;
    EXPECT_LE(yaw, 0.3f + 1e-4f);
    previous_yaw = yaw;
    ++posed;
  }
  EXPECT_GE(posed, 2);
}

TEST(RemoteDaemon, EyesThatPlayOnceWaitForAViewerAndTheirEndIsReported) {
  const auto dir = telex::test::scratch_dir("eyes_play_once");
  for (int i = 0; i < 3; ++i)
    for (const char* eye : {"left", "right"})
      ASSERT_TRUE(cv::imwrite((dir / (std::string(eye) + std::to_string(i) + ".png")).string(),
                              cv::Mat3b(120, 160, cv::Vec3b(40, 80, std::uint8_t(100 + i)))));
  auto cfg = base_config("synthetic:plane");
  cfg.stereo_source =
      "files:" + (dir / "left*.png").string() + "," + (dir / "right*.png").string() + ",fps=5";
  RemoteDaemon d(cfg);
  d.start();
  EXPECT_EQ(d.stats().eyes, EyeState::Held);
  // A station without video does not start them.
  test::TestClient plain(d.port(), true);
  // Under TSan on a loaded 2-core machine fewer than 3 depth frames of a 640x480 synthetic plane
  // came in 5 s.
  const auto three_frames =
      std::chrono::milliseconds(static_cast<int>(5000 * telex::test::kSanitizerSlowdown));
  ASSERT_TRUE(plain.run_until([&] { return plain.frames_.size() >= 3; }, three_frames));
  EXPECT_EQ(d.stats().eyes, EyeState::Held);
  EXPECT_EQ(d.stats().video_frames, 0u);
  plain.close();
  // The first that asks for video gets every pair (one message per pair), then the stats line
  // says they ended.
  test::TestClient viewer(d.port(), true, proto::kCapVideo);
  ASSERT_TRUE(viewer.run_until([&] { return d.stats().eyes == EyeState::Ended; }, 10s));
  ASSERT_TRUE(viewer.run_until([&] { return viewer.video_.size() >= 3; }, 5s))
      << viewer.video_.size() << " pairs came; the remote encoded " << d.stats().video_frames
      << " and sent " << d.stats().video_pairs_sent << " whole";
  EXPECT_EQ(d.stats().video_frames, 3u);
  EXPECT_EQ(viewer.video_.size(), 3u);
  EXPECT_NE(format_stats_line(d.stats(), DaemonStats{}, 1.0).find("| realtime "),
            std::string::npos);
  EXPECT_TRUE(format_stats_line(d.stats(), DaemonStats{}, 1.0).ends_with(" | eyes ended"));
  d.stop();
}

TEST(RemoteDaemon, EyesThatNeverDeliverAreReportedAsNone) {
  auto cfg = base_config("synthetic:plane");
  EXPECT_EQ(RemoteDaemon(cfg).stats().eyes, EyeState::Off);
  // Files that are no images: every read fails, no pair is ever delivered.
  const auto dir = telex::test::scratch_dir("eyes_never");
  for (const char* name : {"left0.png", "right0.png"}) std::ofstream(dir / name) << "not a png";
  cfg.stereo_source =
      "files:" + (dir / "left*.png").string() + "," + (dir / "right*.png").string() + ",loop";
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient viewer(d.port(), true, proto::kCapVideo);
  ASSERT_TRUE(viewer.run_until([&] { return d.stats().source_errors >= 3; }, 10s));
  EXPECT_EQ(d.stats().eyes, EyeState::None);
  EXPECT_TRUE(viewer.video_.empty());
  EXPECT_TRUE(format_stats_line(d.stats(), DaemonStats{}, 1.0).ends_with(" | eyes none"));
  d.stop();
}

int run_remote(const std::string& args) { return telex::test::exit_code_of("telex-remote", args); }

TEST(TelexRemoteCli, BadFlagsAndValuesExitTwo) {
  ASSERT_TRUE(std::filesystem::exists(telex::test::built_binary("telex-remote")));
  EXPECT_EQ(run_remote("--no-such-flag"), 2);
  EXPECT_EQ(run_remote("--codec gzip"), 2);
  EXPECT_EQ(run_remote("--listen nonsense"), 2);
  EXPECT_EQ(run_remote("--listen 127.0.0.1:99999"), 2);
  EXPECT_EQ(run_remote("--tile 80by60"), 2);
  EXPECT_EQ(run_remote("--source kinect9"), 2);
  EXPECT_EQ(run_remote("--stabilise -1"), 2);
  EXPECT_EQ(run_remote("--fill-window 4"), 2);
  EXPECT_EQ(run_remote("--help"), 0);
}

TEST(TelexRemoteCli, RunsForADurationFromAJsonConfigAndMissingDeviceExitsOne) {
  const auto dir = ::telex::test::scratch_dir("cli");
  std::filesystem::create_directories(dir);
  const auto json = dir / "remote.json";
  std::ofstream(json)
      << R"({"source": "synthetic:plane", "listen": "127.0.0.1:0", "size": "160x120", "duration": 0.5})";
  EXPECT_EQ(run_remote("--config " + json.string()), 0);
  std::ofstream(dir / "bad.json") << R"({"codec": "gzip"})";
  EXPECT_EQ(run_remote("--config " + (dir / "bad.json").string()), 2);
  EXPECT_EQ(run_remote("--source openni:no-such-device --listen 127.0.0.1:0 --duration 1"), 1);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace telex::remote

namespace telex::remote {
namespace {

// Issue 49: an exception that escapes a daemon thread (here the processing thread, through the
// frame observer) no longer reaches std::terminate: run() ends with exit 1 naming the thread.
TEST(RemoteDaemon, AThreadThatThrowsEndsTheRunWithExitOneNotTerminate) {
  DaemonConfig cfg = base_config("synthetic:plane");
  cfg.head = "sim";
  cfg.realtime = false;
  cfg.duration_s = 60;  // the fault, not the duration, ends the run
  RemoteDaemon d(cfg);
  d.set_frame_observer([](const ProcessedFrame&) { throw std::runtime_error("injected fault"); });
  d.start();
  EXPECT_EQ(d.run(), 1);
}

}  // namespace
}  // namespace telex::remote
