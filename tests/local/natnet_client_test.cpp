// SPDX-License-Identifier: MIT
// NatNet client against the in-process server simulator on loopback, unicast and multicast.
#include "telex/local/inputs/natnet_client.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <thread>

#include "process.h"
#include "telex/local/inputs/tracker_registry.h"
#include "telex/local/view/stereo_view.h"
#include "telex/sim/natnet_server.h"

namespace telex::local {
namespace {

using namespace ::telex::sim;  // the simulators of the other end

// Waits for a sample without asserting on time: the bound only stops a broken test from hanging.
bool wait_sample(NatNetClient& c, NatNetSample& s, int max_wait_ms = 10000) {
  for (int i = 0; i < max_wait_ms / 5; ++i) {
    if (c.latest(s)) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

void expect_matches_motion(const NatNetSample& s) {
  natnet::Frame truth;
  natnet_press_motion(s.timestamp_s, truth);
  for (std::int32_t id : {kSimHeadId, kSimRightHandId, kSimRightShoulderId}) {
    const auto* b = s.find(id);
    ASSERT_NE(b, nullptr) << "body " << id;
    EXPECT_TRUE(b->valid);
    const auto* t = truth.find_body(id);
    EXPECT_NEAR(b->pose.p_m.x, t->p_m.x, 1e-6);
    EXPECT_NEAR(b->pose.p_m.y, t->p_m.y, 1e-6);
    EXPECT_NEAR(b->pose.p_m.z, t->p_m.z, 1e-6);
    EXPECT_NEAR(b->pose.q.w, t->qw, 1e-6);
    EXPECT_NEAR(b->pose.q.y, t->qy, 1e-6);
  }
}

class NatNetLoopback : public ::testing::TestWithParam<natnet::Version> {};

TEST_P(NatNetLoopback, UnicastPosesArriveAndMatchTheScriptedMotion) {
  NatNetServerConfig scfg;
  scfg.command_port = 0;
  scfg.version = GetParam();
  scfg.rate_hz = 200.0;
  NatNetServer server(scfg, natnet_press_motion);
  std::thread srv([&] { server.run_for(20.0); });

  NatNetClientConfig ccfg;
  ccfg.multicast = false;
  ccfg.command_port = server.command_port();
  ccfg.body_ids = {kSimHeadId, kSimRightHandId, kSimRightShoulderId};
  {
    NatNetClient client(ccfg);
    NatNetSample s1, s2;
    ASSERT_TRUE(wait_sample(client, s1));
    expect_matches_motion(s1);
    ASSERT_TRUE(wait_sample(client, s2));
    EXPECT_GT(s2.frame_number, s1.frame_number);
    EXPECT_GT(s2.timestamp_s, s1.timestamp_s);
    expect_matches_motion(s2);
    // The cameras' mid-exposure: the arrival less the latency the frame reports.
    EXPECT_EQ(s2.received_ns - s2.mid_exposure_ns,
              std::llround(NatNetServerConfig{}.reported_latency_s * 1e9));
    const auto info = client.server_info();
    ASSERT_TRUE(info.has_value());
    EXPECT_EQ(info->natnet_version, GetParam());
    EXPECT_EQ(info->app_name, "telex-sim-natnet");
    EXPECT_EQ(client.stats().parse_errors, 0u);
    EXPECT_GE(client.stats().frames, 2u);
  }
  server.stop();
  srv.join();
  EXPECT_GE(server.stats().pings_answered, 1u);
  EXPECT_EQ(server.stats().clients, 1u);
}

INSTANTIATE_TEST_SUITE_P(Versions, NatNetLoopback,
                         ::testing::Values(natnet::Version{2, 11}, natnet::Version{3, 1},
                                           natnet::Version{4, 1}),
                         [](const auto& info) {
                           return "v" + std::to_string(info.param.major) + "_" +
                                  std::to_string(info.param.minor);
                         });

TEST(NatNetLoopbackMulticast, GroupOnLoopbackDeliversFrames) {
  // A per-process data port keeps concurrent test runs on this machine apart.
  const int data_port = 30000 + static_cast<int>(getpid() % 20000);
  NatNetServerConfig scfg;
  scfg.command_port = 0;
  scfg.multicast = true;
  scfg.data_port = data_port;
  scfg.version = {4, 1};
  NatNetServer server(scfg, natnet_press_motion);
  std::thread srv([&] { server.run_for(20.0); });
  NatNetClientConfig ccfg;
  ccfg.multicast = true;
  ccfg.local_address = "127.0.0.1";
  ccfg.data_port = data_port;
  ccfg.command_port = server.command_port();
  ccfg.body_ids = {kSimHeadId, kSimRightHandId, kSimRightShoulderId};
  {
    NatNetClient client(ccfg);
    NatNetSample s;
    // Frames sent before the server info arrived are dropped; the first parsed one is checked.
    ASSERT_TRUE(wait_sample(client, s));
    expect_matches_motion(s);
  }
  server.stop();
  srv.join();
}

TEST(NatNetClientErrors, BadAddressesNameTheProblem) {
  NatNetClientConfig c;
  c.server_ip = "motive.local";
  try {
    NatNetClient client(c);
    FAIL() << "accepted a host name";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("motive.local"), std::string::npos);
  }
  c.server_ip = "127.0.0.1";
  c.multicast_group = "10.0.0.1";
  c.data_port = 30000 + static_cast<int>((getpid() + 7) % 20000);
  EXPECT_THROW(NatNetClient{c}, std::runtime_error);
}

TEST(NatNetRecording, CsvPlaysBackAndRejectsBadLines) {
  const auto dir = ::telex::test::scratch_dir("natnet");
  std::filesystem::create_directories(dir);
  const auto good = dir / "good.csv";
  std::ofstream(good) << "time_s,body_id,x,y,z,qx,qy,qz,qw\n"
                         "0.0,1,0,1.6,0,0,0,0,1\n"
                         "0.0,2,0.1,1.5,-0.3,0,0,0,1\n"
                         "0.5,2,0.1,1.5,-0.4,0,0,0,1\n";
  auto motion = load_natnet_csv(good, false);
  natnet::Frame f;
  motion(0.25, f);
  ASSERT_EQ(f.rigid_bodies.size(), 2u);
  EXPECT_FLOAT_EQ(f.find_body(2)->p_m.z, -0.3f);
  motion(0.75, f);
  EXPECT_FLOAT_EQ(f.find_body(2)->p_m.z, -0.4f);
  auto looped = load_natnet_csv(good, true);
  looped(0.75, f);  // 0.75 mod 0.5 = 0.25
  EXPECT_FLOAT_EQ(f.find_body(2)->p_m.z, -0.3f);

  const auto bad = dir / "bad.csv";
  std::ofstream(bad) << "time_s,body_id,x,y,z,qx,qy,qz,qw\n0,1,0,0,0,0,0,0,1\n0.1,1,0,0,zero\n";
  try {
    load_natnet_csv(bad, false);
    FAIL() << "accepted a bad line";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(load_natnet_csv(dir / "missing.csv", false), std::runtime_error);
  std::filesystem::remove_all(dir);
}

// A NatNet server on loopback streaming one fixed pose per body (a recording of one instant), so
// the ground truth does not depend on which frame a poll picks up.
class PoseServer {
 public:
  PoseServer(const std::string& name, const std::string& csv_text)
      : dir_(::telex::test::scratch_dir(name)) {
    std::filesystem::create_directories(dir_);
    std::ofstream(dir_ / "pose.csv") << "time_s,body_id,x,y,z,qx,qy,qz,qw\n" << csv_text;
    load_natnet_csv(dir_ / "pose.csv", false)(0.0, truth_);
    NatNetServerConfig scfg;
    scfg.command_port = 0;
    scfg.version = {3, 1};
    server_ = std::make_unique<NatNetServer>(scfg, load_natnet_csv(dir_ / "pose.csv", false));
    thread_ = std::thread([this] { server_->run_for(20.0); });
  }
  ~PoseServer() {
    server_->stop();
    thread_.join();
    std::filesystem::remove_all(dir_);
  }
  std::string spec() const {
    return "natnet:127.0.0.1,unicast,cmd=" + std::to_string(server_->command_port());
  }
  Pose pose_of(int id) const {
    const auto* b = truth_.find_body(id);
    return Pose{{b->p_m.x, b->p_m.y, b->p_m.z},
                glm::normalize(glm::dquat(b->qw, b->qx, b->qy, b->qz))};
  }

 private:
  std::filesystem::path dir_;
  natnet::Frame truth_;
  std::unique_ptr<NatNetServer> server_;
  std::thread thread_;
};

TEST(NatNetTracker, FingertipsInTheCameraFrameMatchTheHandModel) {
  PoseServer server("nntrk",
                    "0,1,0.1,1.6,0.2,0,0.258819,0,0.965926\n"      // head yawed 30 deg
                    "0,2,-0.05,1.45,-0.2,0,0.707107,0,0.707107\n"  // fingers forward
                    "0,3,0.2,1.45,0.25,0,0,0,1\n");

  TrackerConfig cfg;
  cfg.head_body_id = 1;
  cfg.right_hand_body_id = 2;
  cfg.right_shoulder_body_id = 3;
  auto tracker = make_tracker(server.spec(), cfg);
  EXPECT_EQ(tracker->name(), "natnet:127.0.0.1");
  HandState st;
  bool got = false;
  for (int i = 0; i < 2000 && !got; ++i) {
    got = tracker->poll(i, st) && st.tips[1].valid;
    if (!got) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(got);

  const auto pose_of = [&](int id) { return server.pose_of(id); };

  const HandPoints h = hand_forward(cfg.hand, pose_of(2), cfg.default_bend);
  for (int f = 0; f < kFingerCount; ++f) {
    const glm::dvec3 want = world_to_camera(cfg.hand, pose_of(1), h.joints[f][3]);
    EXPECT_NEAR(st.tips[f].p_CameraFingertip.x, want.x, 1e-6);
    EXPECT_NEAR(st.tips[f].p_CameraFingertip.y, want.y, 1e-6);
    EXPECT_NEAR(st.tips[f].p_CameraFingertip.z, want.z, 1e-6);
    EXPECT_NEAR(glm::length(st.tips[f].v_CameraFingertip), 0.0, 1e-9);  // the pose does not move
  }
  // The hand is in front of the camera (positive depth) and the shoulder was mapped too.
  EXPECT_GT(st.tips[1].p_CameraFingertip.z, 0.0);
  EXPECT_TRUE(st.shoulder_valid);
  EXPECT_TRUE(st.skeleton_valid);
  EXPECT_GE(tracker->stats().frames_in, 1u);
  EXPECT_EQ(tracker->stats().parse_errors, 0u);
}

TEST(NatNetTracker, BothArmsWithShouldersAndElbowsReachTheViewsBody) {
  // Head at 1.6 m looking along -z; both hands forward, shoulders and elbow markers where an
  // operator's would be.
  PoseServer server("nnarms",
                    "0,1,0,1.6,0,0,0,0,1\n"
                    "0,2,0.15,1.3,-0.35,0,0.707107,0,0.707107\n"
                    "0,3,0.2,1.45,0.05,0,0,0,1\n"
                    "0,4,-0.15,1.3,-0.35,0,0.707107,0,0.707107\n"
                    "0,5,-0.2,1.45,0.05,0,0,0,1\n"
                    "0,6,0.3,1.2,-0.1,0,0,0,1\n"
                    "0,7,-0.3,1.2,-0.1,0,0,0,1\n");

  TrackerConfig cfg;
  cfg.head_body_id = 1;
  cfg.right_hand_body_id = 2;
  cfg.right_shoulder_body_id = 3;
  cfg.left_hand_body_id = 4;
  cfg.left_shoulder_body_id = 5;
  cfg.right_elbow_body_id = 6;
  cfg.left_elbow_body_id = 7;
  auto tracker = make_tracker(server.spec(), cfg);
  HandState st;
  bool got = false;
  for (int i = 0; i < 2000 && !got; ++i) {
    got = tracker->poll(i, st) && st.arms[0].wrist_valid && st.arms[1].elbow_valid;
    if (!got) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(got);
  tracker.reset();
  const auto pose_of = [&](int id) { return server.pose_of(id); };
  const Pose head = pose_of(1);
  const auto near = [](const glm::dvec3& a, const glm::dvec3& b) {
    return glm::length(a - b) < 1e-5;
  };
  for (const Side side : kSides) {
    const ArmTrack& a = st.arms[index_of(side)];
    const int hand_id = side == Side::Left ? 4 : 2, shoulder_id = side == Side::Left ? 5 : 3,
              elbow_id = side == Side::Left ? 7 : 6;
    ASSERT_TRUE(a.wrist_valid && a.wrist_orientation && a.shoulder_valid && a.elbow_valid);
    EXPECT_TRUE(
        near(a.p_CameraShoulder, world_to_camera(cfg.hand, head, pose_of(shoulder_id).p_m)));
    EXPECT_TRUE(near(a.p_CameraElbow, world_to_camera(cfg.hand, head, pose_of(elbow_id).p_m)));
    EXPECT_TRUE(near(a.X_CameraWrist.p_m, world_to_camera(cfg.hand, head, pose_of(hand_id).p_m)));
    // The wrist's orientation maps its axes as the world pose does, seen from the camera.
    const glm::dvec3 x_world = pose_of(hand_id).q * glm::dvec3(1, 0, 0);
    EXPECT_TRUE(near(a.X_CameraWrist.q * glm::dvec3(1, 0, 0),
                     world_dir_to_camera(cfg.hand, head, x_world)));
    // Each hand is chained with its own side's geometry (a left hand is mirrored).
    HandGeometry g = side == Side::Left ? cfg.left_hand : static_cast<HandGeometry>(cfg.hand);
    g.left = side == Side::Left;
    const HandPoints h = hand_forward(g, pose_of(hand_id), cfg.default_bend);
    for (std::size_t f = 0; f < kFingerCount; ++f)
      EXPECT_TRUE(near(a.joints_camera[f][3], world_to_camera(cfg.hand, head, h.joints[f][3])))
          << f;
  }
  // The two hands are mirror images about the head's midline (x = 0 in the world), so their
  // thumbs are on opposite sides: the left thumb right of the left little finger, and vice versa.
  EXPECT_GT(st.arms[0].joints_camera[0][3].x, st.arms[0].joints_camera[4][3].x);
  EXPECT_LT(st.arms[1].joints_camera[0][3].x, st.arms[1].joints_camera[4][3].x);

  // The view's body takes both arms, its elbows from the markers, and draws both.
  Body body(BodyDims{});
  StereoViewInputs in;
  in.hand = st;
  const auto capsules = view_capsules(body, in);
  const BodyState& bs = body.state();
  for (const Side side : kSides) {
    const ArmState& arm = bs.arms[index_of(side)];
    EXPECT_TRUE(arm.visible);
    EXPECT_EQ(arm.elbow_from, ElbowFrom::Marker) << elbow_from_name(arm.elbow_from);
    EXPECT_LT(glm::length(arm.elbow - st.arms[index_of(side)].p_CameraElbow), 0.06);
  }
  // Two arms: the upper arm and the forearm in two, and per finger its palm capsule, three
  // phalanges and three joint balls.
  EXPECT_EQ(capsules.size(), 2u * (3 + 5 * 7));
}

TEST(NatNetTracker, SpecErrors) {
  TrackerConfig cfg;
  EXPECT_THROW(make_tracker("natnet:", cfg), std::invalid_argument);
  EXPECT_THROW(make_tracker("natnet:127.0.0.1,cmd=99999", cfg), std::invalid_argument);
  EXPECT_THROW(make_tracker("natnet:127.0.0.1,turbo", cfg), std::invalid_argument);
  EXPECT_THROW(make_tracker("natnet:127.0.0.1,version=7.0", cfg), std::invalid_argument);
}

}  // namespace
}  // namespace telex::local
