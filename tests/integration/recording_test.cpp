// SPDX-License-Identifier: MIT
// ROS bags end to end: a press session recorded by telex-local --record, read back topic by topic,
// its peak wrench against the station's own force log, replayed by `telex replay`; and a bag
// written here with the library served by telex-remote --source bag: to a station that presses it.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <sstream>

#include "daemons.h"
#include "process.h"
#include "telex/bag/bag.h"
#include "telex/common/synthetic.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

// Peak |(fx, fy, fz)| per finger in telex-local's --log-forces CSV (every tick).
std::map<std::string, double> csv_peaks(const std::filesystem::path& csv) {
  std::map<std::string, double> peak;
  const CsvFile table = read_csv_file(csv);
  for (const auto& f : table.rows) {
    if (f.size() < 8) continue;
    const double n = std::hypot(std::stod(f[5]), std::stod(f[6]), std::stod(f[7]));
    peak[f[1]] = std::max(peak[f[1]], n);
  }
  return peak;
}

nlohmann::json run_replay(const std::filesystem::path& dir, const std::filesystem::path& bag,
                          std::vector<std::string> extra, const std::string& name) {
  std::vector<std::string> argv{built_binary("telex").string(), "replay", bag.string(), "--json"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  Process p(argv, dir / (name + ".out"), dir / (name + ".err"));
  const auto rc = p.wait(120s);
  EXPECT_TRUE(rc.has_value() && *rc == 0) << p.stderr_text();
  return summary_of(p);
}

TEST(Recording, APressSessionHoldsEveryTopicItsLoggedPeakAndReplaysToItsForces) {
  TELEX_REQUIRE_BINARIES("telex", "telex-local", "telex-remote");
  const auto dir = scratch_dir("recording_press");
  const auto bag_path = dir / "press.bag";
  RemoteProcess remote(dir, {"--source", "synthetic:plane"});
  Process local(
      local_args(remote.port, dir,
                 {"--hand", "script:press", "--stiffness", "500", "--max-force", "10", "--duration",
                  "6", "--record", bag_path.string(), "--record-rate", "1000"}),
      dir / "local.out", dir / "local.err");
  const auto rc = local.wait(60s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  ASSERT_EQ(*rc, 0) << local.stderr_text();
  const auto j = summary_of(local);
  ASSERT_TRUE(j.is_object() && j.contains("record")) << local.stdout_text();
  const auto& rec = j["record"];
  EXPECT_EQ(rec["error"], "");
  EXPECT_EQ(rec["dropped_ticks"], 0) << "a 6 s session fits the 8 s tick queue";
  EXPECT_EQ(rec["dropped_surfaces"], 0);
  EXPECT_EQ(rec["ticks"], j["ticks"]);
  EXPECT_EQ(rec["surfaces"], j["surfaces"]);

  // Every topic, in its standard type, with a message per tick or per surface.
  bag::Reader r(bag_path.string());
  std::map<std::string, bag::TopicInfo> topics;
  for (const auto& t : r.topics()) topics[t.topic] = t;
  const std::uint64_t ticks = j["ticks"], surfaces = j["surfaces"];
  ASSERT_GT(ticks, 4000u);
  auto expect_topic = [&](const std::string& name, const std::string& type, std::uint64_t n) {
    ASSERT_TRUE(topics.count(name)) << name << " missing; the bag holds " << r.describe_topics();
    EXPECT_EQ(topics[name].type, type) << name;
    EXPECT_EQ(topics[name].messages, n) << name;
  };
  expect_topic("/telex/depth/image_raw", "sensor_msgs/Image", surfaces);
  EXPECT_EQ(topics["/telex/depth/image_raw"].encoding, "16UC1");
  expect_topic("/telex/depth/camera_info", "sensor_msgs/CameraInfo", surfaces);
  expect_topic("/telex/fingertips", "geometry_msgs/PoseArray", ticks);
  expect_topic("/telex/config", "std_msgs/String", 1);
  // Which registration the remote ran, as its session said it (a synthetic source: none).
  expect_topic("/telex/remote", "std_msgs/String", 1);
  {
    r.select({"/telex/remote"});
    bag::Message said;
    ASSERT_TRUE(r.next(said));
    const auto remote = nlohmann::json::parse(said.text);
    EXPECT_EQ(remote["registration"], "none") << said.text;
    EXPECT_EQ(remote["depth_pixels"], "sensor depth (IR) camera") << said.text;
  }
  for (const char* f : {"thumb", "index", "middle", "ring", "little"}) {
    expect_topic(std::string("/telex/force/") + f, "geometry_msgs/WrenchStamped", ticks);
    expect_topic(std::string("/telex/display/") + f, "geometry_msgs/WrenchStamped", ticks);
  }
  ASSERT_TRUE(topics.count("/tf"));
  EXPECT_EQ(topics["/tf"].type, "tf2_msgs/TFMessage");

  // The recorded peak wrench of each finger is the peak the station logged (6 decimals).
  const auto logged = csv_peaks(dir / "forces.csv");
  ASSERT_NEAR(logged.at("index"), 5.0, 0.5) << "k 500 N/m x 10 mm";
  for (const auto& [finger, peak] : logged) {
    r.select({"/telex/force/" + finger});
    bag::Message m;
    double recorded = 0;
    while (r.next(m))
      recorded = std::max(recorded, std::hypot(m.force_N[0], m.force_N[1], m.force_N[2]));
    EXPECT_NEAR(recorded, peak, 2e-6) << finger;
  }
  // The display's command: pressure along z of /telex/display/index peaks with the force.
  r.select({"/telex/display/index"});
  bag::Message m;
  double pressure = 0;
  while (r.next(m)) pressure = std::max(pressure, m.force_N[2]);
  EXPECT_NEAR(pressure, j["peak_pressure_N"].get<double>(), 1e-9);

  // ROS's own reference reader (python3-rosbag) sees the same topics, counts and peaks.
  {
    Process py({"/usr/bin/python3",
                std::string(TELEX_SOURCE_DIR) + "/tests/integration/rosbag_reference.py",
                bag_path.string()},
               dir / "reference.out", dir / "reference.err");
    const auto py_rc = py.wait(120s);
    ASSERT_TRUE(py_rc.has_value() && *py_rc == 0) << py.stderr_text();
    const auto ref = summary_of(py);
    ASSERT_TRUE(ref.is_object()) << py.stdout_text();
    for (const auto& [name, t] : topics) {
      EXPECT_EQ(ref["topics"][name]["type"], t.type) << name;
      EXPECT_EQ(ref["topics"][name]["messages"], t.messages) << name;
    }
    EXPECT_EQ(ref["topics"].size(), topics.size());
    for (const auto& [finger, peak] : logged)
      EXPECT_NEAR(ref["peak_force_N"][finger].get<double>(), peak, 2e-6) << finger;
    EXPECT_EQ(ref["depth"]["encoding"], "16UC1");
    EXPECT_EQ(ref["depth"]["bytes"],
              ref["depth"]["step"].get<int>() * ref["depth"]["height"].get<int>());
  }

  // Replayed with the recorded parameters: the same forces; with half the stiffness, half of them.
  const auto same = run_replay(dir, bag_path, {}, "replay_same");
  ASSERT_TRUE(same.is_object());
  EXPECT_EQ(same["rows"], 5 * ticks);
  EXPECT_EQ(same["unmatched"], 0);
  EXPECT_LE(same["rms_diff_N"].get<double>(), 0.01);
  EXPECT_NEAR(same["peak_N"].get<double>(), logged.at("index"), 2e-6);
  EXPECT_EQ(same["recorded_peak_N"], same["peak_N"]);
  const auto soft = run_replay(dir, bag_path, {"--stiffness", "250"}, "replay_soft");
  ASSERT_TRUE(soft.is_object());
  EXPECT_NEAR(soft["peak_N"].get<double>(), 2.5, 0.25);
  EXPECT_GT(soft["rms_diff_N"].get<double>(), 0.1);
}

TEST(Recording, ABagOfMetreDepthServedByTheRemoteIsPressedLikeTheSceneItHolds) {
  TELEX_REQUIRE_BINARIES("telex-local", "telex-remote");
  const auto dir = scratch_dir("recording_bag_source");
  const auto bag_path = dir / "plane_32f.bag";
  {
    // A second of the Kinect-noise plane at 0.8 m, as a TUM-style 32FC1 bag.
    const Intrinsics k = kinect_v1_intrinsics(640, 480);
    const auto scene = synth::Scene::named("plane");
    bag::Writer w(bag_path.string());
    for (int i = 0; i < 30; ++i) {
      const auto depth = synth::render(scene, k, synth::SensorModel{}, i).depth.depth_mm;
      cv::Mat1f m(depth.size());
      for (int y = 0; y < m.rows; ++y)
        for (int x = 0; x < m.cols; ++x)
          m(y, x) = depth(y, x) ? depth(y, x) / 1000.0f : std::numeric_limits<float>::quiet_NaN();
      w.depth_m("/camera/depth/image", "/camera/depth/camera_info",
                1'700'000'000'000'000'000 + i * 33'333'333LL, static_cast<std::uint32_t>(i),
                "camera", m, {k.fx, k.fy, k.cx, k.cy, k.width, k.height});
    }
  }
  RemoteProcess remote(dir, {"--source", "bag:" + bag_path.string() + ",loop"});
  Process local(local_args(remote.port, dir,
                           {"--hand", "script:press", "--stiffness", "500", "--max-force", "10",
                            "--duration", "6"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(60s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  ASSERT_EQ(*rc, 0) << local.stderr_text() << remote.proc.stderr_text();
  EXPECT_NEAR(csv_peaks(dir / "forces.csv").at("index"), 5.0, 0.5) << "k 500 N/m x 10 mm";
  const auto j = summary_of(local);
  ASSERT_TRUE(j.is_object());
  // The remote played the second of recording on a loop at its recorded 30 Hz.
  EXPECT_GT(j["surfaces"].get<int>(), 100 / kSanitizerSlowdown);
  const std::string remote_log = remote.proc.stdout_text() + remote.proc.stderr_text();
  EXPECT_NE(remote_log.find("/camera/depth/image 32FC1, 30 frames, intrinsics from "
                            "/camera/depth/camera_info, recorded pace, loop"),
            std::string::npos)
      << remote_log;
}

TEST(Recording, EveryTrackedBodyIsOnTfAsTheTrackerReportedIt) {
  TELEX_REQUIRE_BINARIES("telex-local", "telex-remote", "telex-sim-natnet");
  const auto dir = scratch_dir("recording_natnet");
  const auto bag_path = dir / "natnet.bag";
  RemoteProcess remote(dir, {"--source", "synthetic:plane"});
  const std::uint16_t cmd_port = free_port();
  Process sim({built_binary("telex-sim-natnet").string(), "--command-port",
               std::to_string(cmd_port), "--duration", "20", "--natnet-version", "4.1"},
              dir / "sim.out", dir / "sim.err");
  Process local(
      local_args(remote.port, dir,
                 {"--hand", "natnet:127.0.0.1,unicast", "--natnet-cmd-port",
                  std::to_string(cmd_port), "--log-tracking", (dir / "tracking.csv").string(),
                  "--duration", "4", "--record", bag_path.string()}),
      dir / "local.out", dir / "local.err");
  ASSERT_EQ(local.wait(30s).value_or(-1), 0) << local.stderr_text();
  sim.signal(SIGINT);
  const auto j = summary_of(local);
  ASSERT_TRUE(j.is_object() && j.contains("record")) << local.stdout_text();
  EXPECT_EQ(j["record"]["dropped_bodies"], 0);

  // The tracking log's valid rows, per body, in order.
  std::map<int, std::vector<std::array<double, 7>>> logged;
  const CsvFile table = read_csv_file(dir / "tracking.csv");
  for (const auto& f : table.rows) {
    ASSERT_EQ(f.size(), 10u) << testing::PrintToString(f);
    if (f[9] != "1") continue;
    std::array<double, 7> pose{};
    for (int k = 0; k < 7; ++k) pose[static_cast<std::size_t>(k)] = std::stod(f[2 + k]);
    logged[std::stoi(f[1])].push_back(pose);
  }
  std::map<int, std::vector<std::array<double, 7>>> recorded;
  bag::Reader r(bag_path.string());
  r.select({"/tf"});
  bag::Message m;
  while (r.next(m))
    for (const auto& t : m.transforms) {
      if (t.child.rfind("optitrack_body_", 0) != 0) continue;
      EXPECT_EQ(t.parent, "optitrack");
      recorded[std::stoi(t.child.substr(15))].push_back({t.pose.p[0], t.pose.p[1], t.pose.p[2],
                                                         t.pose.q[0], t.pose.q[1], t.pose.q[2],
                                                         t.pose.q[3]});
    }
  for (int id : {1, 2, 3}) {
    ASSERT_GT(logged[id].size(), 100u) << "body " << id;
    ASSERT_EQ(recorded[id].size(), logged[id].size()) << "body " << id;
    for (std::size_t i = 0; i < logged[id].size(); ++i)
      for (std::size_t k = 0; k < 7; ++k)
        ASSERT_NEAR(recorded[id][i][k], logged[id][i][k], 1e-6) << "body " << id << " row " << i;
  }
}

}  // namespace
}  // namespace telex::test
