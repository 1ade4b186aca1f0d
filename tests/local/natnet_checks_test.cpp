// SPDX-License-Identifier: MIT
// The station's checks on its own NatNet input: only the configured server is read (a spoofed
// sender on another loopback address is dropped and counted), and poses that are not finite, whose
// quaternion is not of unit length, or that jump faster than a human never reach a published
// sample or the tracker's state.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <glm/gtc/quaternion.hpp>
#include <limits>
#include <thread>

#include "process.h"
#include "telex/local/inputs/natnet_client.h"
#include "telex/local/inputs/tracker_registry.h"
#include "telex/sim/natnet_server.h"

namespace telex::local {
namespace {

using namespace ::telex::sim;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

natnet::RigidBody body_at(std::int32_t id, double x, double y, double z, glm::dquat q) {
  natnet::RigidBody b;
  b.id = id;
  b.p_m = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
  b.qw = static_cast<float>(q.w);
  b.qx = static_cast<float>(q.x);
  b.qy = static_cast<float>(q.y);
  b.qz = static_cast<float>(q.z);
  return b;
}

const glm::dquat kFingersForward = glm::angleAxis(glm::radians(90.0), glm::dvec3(0, 1, 0));

TEST(NatNetPoseCheck, VerdictsAndTheirThresholds) {
  const PoseLimits lim;
  Pose out;
  // Motive's float32 unit quaternion passes and comes out of unit length.
  const natnet::RigidBody good = body_at(2, 0.03, 1.5, -0.3, kFingersForward);
  ASSERT_EQ(check_pose(good, lim, nullptr, 0.0, out), PoseVerdict::Ok);
  EXPECT_NEAR(glm::length(out.q), 1.0, 1e-12);
  EXPECT_NEAR(out.p_m.y, 1.5, 1e-6);
  // Within the tolerance (|q| = 1.0005): normalised, not rejected.
  natnet::RigidBody scaled = good;
  scaled.qw *= 1.0005f;
  scaled.qy *= 1.0005f;
  ASSERT_EQ(check_pose(scaled, lim, nullptr, 0.0, out), PoseVerdict::Ok);
  EXPECT_NEAR(glm::length(out.q), 1.0, 1e-12);
  // Beyond it, and the degenerate ones.
  scaled.qw = good.qw * 1.01f;
  scaled.qy = good.qy * 1.01f;
  EXPECT_EQ(check_pose(scaled, lim, nullptr, 0.0, out), PoseVerdict::BadQuaternion);
  natnet::RigidBody b = good;
  b.qx = kNaN;
  EXPECT_EQ(check_pose(b, lim, nullptr, 0.0, out), PoseVerdict::BadQuaternion);
  b = good;
  b.qw = b.qx = b.qy = b.qz = 0.0f;
  EXPECT_EQ(check_pose(b, lim, nullptr, 0.0, out), PoseVerdict::BadQuaternion);
  b = good;
  b.p_m.z = kNaN;
  EXPECT_EQ(check_pose(b, lim, nullptr, 0.0, out), PoseVerdict::NonFinite);
  b = good;
  b.p_m.x = std::numeric_limits<float>::infinity();
  EXPECT_EQ(check_pose(b, lim, nullptr, 0.0, out), PoseVerdict::NonFinite);
  b = good;
  b.p_m.x = 1000.0f;  // finite, but no capture volume is a kilometre wide
  EXPECT_EQ(check_pose(b, lim, nullptr, 0.0, out), PoseVerdict::NonFinite);
  // Speed against the last accepted pose: 6 m/s over one 120 Hz frame passes, 30 m/s does not,
  // and the same 0.25 m jump after a quarter of a second (1 m/s) passes.
  const Pose prev{{0.03, 1.5, -0.3}, kFingersForward};
  b = good;
  b.p_m.z = -0.35f;
  EXPECT_EQ(check_pose(b, lim, &prev, 1.0 / 120, out), PoseVerdict::Ok);
  b.p_m.z = -0.55f;
  EXPECT_EQ(check_pose(b, lim, &prev, 1.0 / 120, out), PoseVerdict::TooFast);
  EXPECT_EQ(check_pose(b, lim, &prev, 0.25, out), PoseVerdict::Ok);
}

// Waits for a sample without asserting on time: the bound only stops a broken test from hanging.
bool wait_sample(NatNetClient& c, NatNetSample& s) {
  for (int i = 0; i < 2000; ++i) {
    if (c.latest(s)) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

// What a spoofer on 127.0.0.2 sends: server info claiming NatNet 2.0 (the real server streams
// 3.1: believed, it would make every later frame fail to parse or parse wrong) and frames in the
// right layout whose frame numbers mark them.
constexpr std::uint32_t kSpoofFrame = 0x5900'0000;
std::vector<std::vector<std::uint8_t>> spoofed_datagrams(int pings, int frames) {
  std::vector<std::vector<std::uint8_t>> out;
  natnet::ServerInfo info;
  info.app_name = "spoofer";
  info.natnet_version = {2, 0};
  for (int i = 0; i < pings; ++i) out.push_back(natnet::make_server_info(info));
  for (int i = 0; i < frames; ++i) {
    natnet::Frame f;
    natnet_press_motion(0.0, f);
    f.frame_number = kSpoofFrame + static_cast<std::uint32_t>(i);
    f.rigid_bodies[1].p_m.z = -0.6f;  // plausible, close to the real hand: only its source is bad
    out.push_back(natnet::encode_frame(f, {3, 1}));
  }
  return out;
}

// Polls `client` for a while after the spoofed datagrams went out: every sample is the server's.
void expect_only_server_samples(NatNetClient& client, std::uint64_t sent) {
  NatNetSample s;
  int samples = 0;
  for (int i = 0; i < 2000 && (samples < 20 || client.stats().foreign_datagrams < sent); ++i) {
    if (client.latest(s)) {
      ++samples;
      EXPECT_LT(s.frame_number, kSpoofFrame) << "a spoofed frame was published";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_GE(samples, 20) << "the real server's frames stopped";
  const NatNetClientStats st = client.stats();
  std::printf(
      "NatNetSource: %llu spoofed datagrams sent, %llu counted foreign, %llu frames from "
      "the server, %llu parse errors\n",
      static_cast<unsigned long long>(sent), static_cast<unsigned long long>(st.foreign_datagrams),
      static_cast<unsigned long long>(st.frames), static_cast<unsigned long long>(st.parse_errors));
  EXPECT_EQ(st.foreign_datagrams, sent);
  EXPECT_EQ(st.parse_errors, 0u) << "frames were parsed in a spoofed layout";
  const auto info = client.server_info();
  ASSERT_TRUE(info.has_value());
  EXPECT_EQ(info->app_name, "telex-sim-natnet");
  EXPECT_EQ(info->natnet_version, (natnet::Version{3, 1}));
  EXPECT_NE(client.last_error().find("127.0.0.2"), std::string::npos) << client.last_error();
}

TEST(NatNetSource, SpoofedUnicastSenderIsIgnoredAndCountedWhileTheServerWorks) {
  NatNetServerConfig scfg;
  scfg.command_port = 0;
  scfg.version = {3, 1};
  scfg.rate_hz = 200.0;
  NatNetServer server(scfg, natnet_press_motion);
  std::thread srv([&] { server.run_for(30.0); });
  NatNetClientConfig ccfg;
  ccfg.multicast = false;
  ccfg.command_port = server.command_port();
  ccfg.body_ids = {kSimHeadId, kSimRightHandId};
  {
    NatNetClient client(ccfg);
    NatNetSample s;
    ASSERT_TRUE(wait_sample(client, s));  // connected: the layout is the server's
    const std::size_t sent = test::udp_send_from(
        "127.0.0.2", static_cast<std::uint16_t>(client.command_port()), spoofed_datagrams(5, 50));
    ASSERT_EQ(sent, 55u);
    expect_only_server_samples(client, sent);
  }
  server.stop();
  srv.join();
}

TEST(NatNetSource, SpoofedDatagramsOnTheMulticastDataPortAreIgnoredAndCounted) {
  const int data_port = test::free_port();
  NatNetServerConfig scfg;
  scfg.command_port = 0;
  scfg.multicast = true;
  scfg.data_port = data_port;
  scfg.version = {3, 1};
  scfg.rate_hz = 200.0;
  NatNetServer server(scfg, natnet_press_motion);
  std::thread srv([&] { server.run_for(30.0); });
  NatNetClientConfig ccfg;
  ccfg.multicast = true;
  ccfg.local_address = "127.0.0.1";
  ccfg.data_port = data_port;
  ccfg.command_port = server.command_port();
  ccfg.body_ids = {kSimHeadId, kSimRightHandId};
  {
    NatNetClient client(ccfg);
    NatNetSample s;
    ASSERT_TRUE(wait_sample(client, s));
    const std::size_t sent = test::udp_send_from("127.0.0.2", static_cast<std::uint16_t>(data_port),
                                                 spoofed_datagrams(5, 50));
    ASSERT_EQ(sent, 55u);
    expect_only_server_samples(client, sent);
  }
  server.stop();
  srv.join();
}

// Issue 49 (5): a spoofer on the server's own host (127.0.0.1, the server's address) but another
// port sends well-formed frames in the server's layout, the hand 0.35 m from where it is and
// stamped far in the future of the server's clock. The old checks compared the address only and
// took the speed check's dt from the sender's stamps: the spoofed hand was believed, and the real
// frames after it were rejected as too fast. Only the server's own endpoints are read now: every
// spoofed datagram is counted foreign, and the hand follows the server alone. Unicast (the spoofer
// sends to the client's command port; the server streams from its command port) and multicast
// (to the data port; the server streams from another port, which the client learns).
void expect_same_host_spoofer_changes_nothing(bool multicast) {
  const int data_port = test::free_port();
  NatNetServerConfig scfg;
  scfg.command_port = 0;
  scfg.multicast = multicast;
  scfg.data_port = data_port;
  scfg.version = {3, 1};
  scfg.rate_hz = 200.0;
  NatNetServer server(scfg, [](double, natnet::Frame& f) { natnet_press_motion(0.0, f); });
  std::thread srv([&] { server.run_for(30.0); });
  NatNetClientConfig ccfg;
  ccfg.multicast = multicast;
  ccfg.local_address = "127.0.0.1";
  ccfg.data_port = data_port;
  ccfg.command_port = server.command_port();
  ccfg.body_ids = {kSimHeadId, kSimRightHandId};
  {
    NatNetClient client(ccfg);
    NatNetSample s;
    ASSERT_TRUE(wait_sample(client, s));  // connected: the server's frames are arriving
    std::vector<std::vector<std::uint8_t>> spoofed;
    for (int i = 0; i < 50; ++i) {
      natnet::Frame f;
      natnet_press_motion(0.0, f);
      f.frame_number = kSpoofFrame + static_cast<std::uint32_t>(i);
      f.timestamp_s = 1e6 + 0.005 * i;  // eleven days ahead of the server's clock
      f.rigid_bodies[1].p_m.z = -0.6f;  // the real hand is at -0.25 m
      spoofed.push_back(natnet::encode_frame(f, {3, 1}));
    }
    const auto to = static_cast<std::uint16_t>(multicast ? data_port : client.command_port());
    const std::size_t sent = test::udp_send_from("127.0.0.1", to, spoofed);
    ASSERT_EQ(sent, 50u);
    int samples = 0;
    for (int i = 0; i < 2000 && (samples < 20 || client.stats().foreign_datagrams < sent); ++i) {
      if (client.latest(s)) {
        ++samples;
        EXPECT_LT(s.frame_number, kSpoofFrame) << "a spoofed frame was published";
        const auto* hand = s.find(kSimRightHandId);
        ASSERT_NE(hand, nullptr);
        EXPECT_TRUE(hand->valid) << "a real frame was rejected, frame " << s.frame_number;
        if (hand->valid) {
          EXPECT_NEAR(hand->pose.p_m.z, -0.25, 1e-6) << "not the server's hand";
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    const NatNetClientStats st = client.stats();
    std::printf(
        "NatNetSource same host, %s: %llu spoofed frames sent, %llu counted foreign, %llu frames "
        "read, %llu rejected too fast\n",
        multicast ? "multicast" : "unicast", static_cast<unsigned long long>(sent),
        static_cast<unsigned long long>(st.foreign_datagrams),
        static_cast<unsigned long long>(st.frames),
        static_cast<unsigned long long>(st.rejected_too_fast));
    EXPECT_GE(samples, 20) << "the real server's frames stopped";
    EXPECT_EQ(st.foreign_datagrams, sent);
    EXPECT_EQ(st.rejected_too_fast, 0u);
    EXPECT_NE(client.last_error().find("127.0.0.1:"), std::string::npos) << client.last_error();
  }
  server.stop();
  srv.join();
}

TEST(NatNetSource, ASpooferOnTheServersHostButAnotherPortChangesNothing) {
  expect_same_host_spoofer_changes_nothing(false);
}

TEST(NatNetSource, ASpooferOnTheServersHostChangesNothingInMulticastEither) {
  expect_same_host_spoofer_changes_nothing(true);
}

// The hand's pose over each 0.2 s cycle: good, then NaN position, a quaternion of length 1.2, a
// NaN quaternion, a 1 m jump, good again. The good poses carry a quaternion of length 1.0005
// (within the tolerance: normalised).
void glitchy_motion(double t_s, natnet::Frame& f) {
  f.rigid_bodies.clear();
  f.rigid_bodies.push_back(body_at(kSimHeadId, 0.0, 1.6, 0.0, glm::dquat(1, 0, 0, 0)));
  natnet::RigidBody hand = body_at(kSimRightHandId, 0.03, 1.5, -0.3, kFingersForward * 1.0005);
  const double phase = std::fmod(t_s, 0.2);
  if (phase >= 0.04 && phase < 0.06) hand.p_m.x = kNaN;
  if (phase >= 0.06 && phase < 0.08) {
    hand.qw *= 1.2f;
    hand.qy *= 1.2f;
  }
  if (phase >= 0.08 && phase < 0.10) hand.qz = kNaN;
  if (phase >= 0.10 && phase < 0.12) hand.p_m.x += 1.0f;
  f.rigid_bodies.push_back(hand);
}

TEST(NatNetPoseCheck, BadPosesAreCountedAndNeverPublishedAsValid) {
  NatNetServerConfig scfg;
  scfg.command_port = 0;
  scfg.rate_hz = 250.0;
  NatNetServer server(scfg, glitchy_motion);
  std::thread srv([&] { server.run_for(30.0); });
  NatNetClientConfig ccfg;
  ccfg.multicast = false;
  ccfg.command_port = server.command_port();
  ccfg.body_ids = {kSimHeadId, kSimRightHandId};
  int valid = 0, rejected = 0;
  NatNetClientStats st;
  {
    NatNetClient client(ccfg);
    NatNetSample s;
    // Until every reason was seen a few times and good poses came between them.
    for (int i = 0; i < 5000; ++i) {
      st = client.stats();
      if (st.rejected_nonfinite >= 4 && st.rejected_quaternion >= 8 && st.rejected_too_fast >= 4 &&
          valid >= 20)
        break;
      if (!client.latest(s)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        continue;
      }
      const auto* hand = s.find(kSimRightHandId);
      ASSERT_NE(hand, nullptr);
      if (hand->rejected) {
        ++rejected;
        EXPECT_FALSE(hand->valid);
        continue;
      }
      ASSERT_TRUE(hand->valid);
      ++valid;
      // Every pose published as valid is the good one, normalised.
      EXPECT_NEAR(hand->pose.p_m.x, 0.03, 1e-6);
      EXPECT_NEAR(hand->pose.p_m.z, -0.3, 1e-6);
      EXPECT_NEAR(glm::length(hand->pose.q), 1.0, 1e-9);
    }
  }
  server.stop();
  srv.join();
  std::printf(
      "NatNetPoseCheck: %d valid and %d rejected hand samples seen; rejected non-finite "
      "%llu, quaternion %llu, too fast %llu\n",
      valid, rejected, static_cast<unsigned long long>(st.rejected_nonfinite),
      static_cast<unsigned long long>(st.rejected_quaternion),
      static_cast<unsigned long long>(st.rejected_too_fast));
  EXPECT_GE(st.rejected_nonfinite, 4u);
  EXPECT_GE(st.rejected_quaternion, 8u);  // both the long and the NaN quaternions
  EXPECT_GE(st.rejected_too_fast, 4u);
  EXPECT_GE(valid, 20);
  EXPECT_GT(rejected, 0);
}

TEST(NatNetTracker, AFrameWithABadHandIsSetAsideAndTheLastGoodStateAges) {
  // Good for 0.3 s, then the hand's quaternion is NaN in every frame.
  NatNetServerConfig scfg;
  scfg.command_port = 0;
  scfg.rate_hz = 250.0;
  NatNetServer server(scfg, [](double t_s, natnet::Frame& f) {
    natnet_press_motion(0.0, f);
    if (t_s >= 0.3) f.rigid_bodies[1].qx = kNaN;
  });
  std::thread srv([&] { server.run_for(30.0); });
  TrackerConfig cfg;
  cfg.head_body_id = kSimHeadId;
  cfg.right_hand_body_id = kSimRightHandId;
  cfg.right_shoulder_body_id = kSimRightShoulderId;
  auto tracker =
      make_tracker("natnet:127.0.0.1,unicast,cmd=" + std::to_string(server.command_port()), cfg);
  // The poll clock is the test's own (1 ms per poll), so "ageing" needs no wall clock.
  std::int64_t now_ns = 0;
  HandState st, last_good;
  bool any = false;
  for (int i = 0; i < 10000 && tracker->stats().frames_rejected < 20; ++i) {
    now_ns += 1'000'000;
    if (tracker->poll(now_ns, st)) {
      any = true;
      last_good = st;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_TRUE(any) << "no good frame before the bad ones";
  ASSERT_GE(tracker->stats().frames_rejected, 20u);
  // From now on every frame is bad: no poll returns a state, and the last one keeps its time.
  int updates = 0;
  for (int i = 0; i < 100; ++i) {
    now_ns += 1'000'000;
    updates += tracker->poll(now_ns, st) ? 1 : 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const TrackerStats ts = tracker->stats();
  tracker.reset();
  server.stop();
  srv.join();
  std::printf(
      "NatNetTracker: %llu frames set aside (%llu bad quaternions), %d updates after, "
      "last good state %.3f s old at the end\n",
      static_cast<unsigned long long>(ts.frames_rejected),
      static_cast<unsigned long long>(ts.rejected_quaternion), updates,
      static_cast<double>(now_ns - last_good.time_ns) / 1e9);
  EXPECT_EQ(updates, 0);
  EXPECT_GE(ts.rejected_quaternion, ts.frames_rejected);
  EXPECT_GE(now_ns - last_good.time_ns, 100'000'000);  // older than any staleness limit in use
  ASSERT_TRUE(last_good.tips[1].valid);
  for (const auto& tip : last_good.tips)
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isfinite(tip.p_CameraFingertip[k]));
}

}  // namespace
}  // namespace telex::local
