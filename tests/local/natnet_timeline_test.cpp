// SPDX-License-Identifier: MIT
// The NatNet client's checks on the server's stream (issue 49): a frame's number and stamp must
// move forward and by no more than the time between arrivals here allows (check_frame), the speed
// check's dt is bounded by the arrivals (speed_check_dt_s), and a client fed such frames from the
// server's own endpoint drops and counts them while the others go on.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <thread>

#include "process.h"
#include "telex/local/inputs/natnet_client.h"
#include "telex/sim/natnet_server.h"

namespace telex::local {
namespace {

using namespace ::telex::sim;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The last accepted frame: number 100, stamped 10 s on the server's clock, arrived at 1 s here.
constexpr FrameStamp kPrevious{100, 10.0, 1'000'000'000};
FrameStamp after(std::uint32_t number, double timestamp_s, double arrived_after_s) {
  return {number, timestamp_s, kPrevious.received_ns + std::llround(arrived_after_s * 1e9)};
}

TEST(NatNetFrameCheck, VerdictsAndTheirThresholds) {
  const TimelineLimits lim;
  using V = FrameVerdict;
  // The next frame at 120 Hz; the same frame arriving with others after a stalled network; frames
  // lost on the way, numbers and stamps running on alike.
  EXPECT_EQ(check_frame(kPrevious, after(101, 10.008, 0.008), lim), V::Ok);
  EXPECT_EQ(check_frame(kPrevious, after(101, 10.008, 0.0), lim), V::Ok);
  EXPECT_EQ(check_frame(kPrevious, after(160, 10.49, 0.49), lim), V::Ok);
  // A repeat, a number or a stamp that went back, a stamp that is not a number.
  EXPECT_EQ(check_frame(kPrevious, after(100, 10.008, 0.008), lim), V::Backwards);
  EXPECT_EQ(check_frame(kPrevious, after(99, 10.008, 0.008), lim), V::Backwards);
  EXPECT_EQ(check_frame(kPrevious, after(101, 9.99, 0.008), lim), V::Backwards);
  EXPECT_EQ(check_frame(kPrevious, after(101, kNaN, 0.008), lim), V::Backwards);
  // Ahead of the arrivals by more than 0.25 s: the spoofer, stamped 1e6 s; a stamp 0.26 s
  // ahead of 8 ms of arrivals; a number more than 2000 Hz * 0.258 s = 516 on.
  EXPECT_EQ(check_frame(kPrevious, after(101, 1e6, 0.008), lim), V::TooFarAhead);
  EXPECT_EQ(check_frame(kPrevious, after(101, 10.25, 0.008), lim), V::Ok);
  EXPECT_EQ(check_frame(kPrevious, after(101, 10.27, 0.008), lim), V::TooFarAhead);
  EXPECT_EQ(check_frame(kPrevious, after(100 + 510, 10.01, 0.008), lim), V::Ok);
  EXPECT_EQ(check_frame(kPrevious, after(100 + 530, 10.01, 0.008), lim), V::TooFarAhead);
  EXPECT_EQ(check_frame(kPrevious, after(0x5900'0000, 10.01, 0.008), lim), V::TooFarAhead);
  // The counter wraps in order.
  EXPECT_EQ(check_frame({0xFFFF'FFFF, 10.0, 0}, {0, 10.008, 8'000'000}, lim), V::Ok);
  // Nothing accepted for more than 0.5 s: a restarted server's frame starts a new timeline.
  EXPECT_EQ(check_frame(kPrevious, after(1, 0.0, 0.51), lim), V::NewTimeline);
  EXPECT_EQ(check_frame(kPrevious, after(1, 0.0, 0.49), lim), V::Backwards);
}

TEST(NatNetFrameCheck, TheSpeedChecksDtIsBoundedByTheArrivals) {
  const TimelineLimits lim;
  EXPECT_NEAR(speed_check_dt_s(kPrevious, after(101, 10.008, 0.008), lim), 0.008, 1e-12);
  // Frames that queued in a stalled network arrive together but moved for their stamps' dt.
  EXPECT_NEAR(speed_check_dt_s(kPrevious, after(101, 10.008, 0.0), lim), 0.008, 1e-12);
  // Late: still the stamps' dt, the time the body had to move.
  EXPECT_NEAR(speed_check_dt_s(kPrevious, after(101, 10.008, 0.2), lim), 0.008, 1e-12);
  // A stamp far ahead widens it by 50 ms at most.
  EXPECT_NEAR(speed_check_dt_s(kPrevious, after(101, 1e6, 0.008), lim), 0.058, 1e-12);
  // Stamps that went back (another timeline): the arrivals'.
  EXPECT_NEAR(speed_check_dt_s(kPrevious, after(1, 0.0, 0.6), lim), 0.6, 1e-12);
}

// A server played by the test: one UDP socket on loopback (its command endpoint) that sends the
// client frames in NatNet 3.1 (the client is told the version, so no connect reply is needed).
class FrameSender {
 public:
  FrameSender() : fd_(test::bound_socket(SOCK_DGRAM, port_)) {}
  ~FrameSender() { ::close(fd_); }
  std::uint16_t port() const { return port_; }
  void send(std::uint16_t to_port, std::uint32_t number, double timestamp_s, float hand_z_m) {
    natnet::Frame f;
    natnet_press_motion(0.0, f);
    f.frame_number = number;
    f.timestamp_s = timestamp_s;
    f.rigid_bodies[1].p_m.z = hand_z_m;
    const auto bytes = natnet::encode_frame(f, {3, 1});
    const sockaddr_in to = test::loopback_address(to_port);
    ASSERT_EQ(::sendto(fd_, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to),
                       sizeof to),
              static_cast<ssize_t>(bytes.size()));
  }

 private:
  std::uint16_t port_ = 0;
  int fd_ = -1;
};

// Frames from the server's own endpoint, so the source checks pass them, that jump: a number and
// a stamp far ahead, a number and a stamp gone back. Each is dropped whole and counted, none moves
// the hand (their hand is 0.35 m off) or makes the server's next frames look too fast.
TEST(NatNetStream, FramesThatJumpAreDroppedAndCountedAndTheOthersGoOn) {
  FrameSender server;
  NatNetClientConfig ccfg;
  ccfg.multicast = false;
  ccfg.command_port = server.port();
  ccfg.version = natnet::Version{3, 1};
  ccfg.body_ids = {kSimHeadId, kSimRightHandId};
  NatNetClient client(ccfg);
  const auto to = static_cast<std::uint16_t>(client.command_port());
  for (std::uint32_t n = 1; n <= 10; ++n) server.send(to, n, 0.01 * n, -0.25f);
  server.send(to, 1'000'011, 0.11, -0.6f);  // a number far ahead
  server.send(to, 11, 1e6, -0.6f);          // a stamp far ahead
  server.send(to, 5, 0.115, -0.6f);         // a number gone back
  server.send(to, 11, 0.05, -0.6f);         // a stamp gone back
  for (std::uint32_t n = 11; n <= 20; ++n) server.send(to, n, 0.01 * n, -0.25f);
  // The bound only stops a broken test from hanging.
  NatNetSample s;
  std::uint32_t newest = 0;
  for (int i = 0; i < 2000 && client.stats().frames < 24; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  while (client.latest(s)) newest = s.frame_number;
  const NatNetClientStats st = client.stats();
  std::printf("NatNetStream: %llu frames read, %llu jumps dropped, newest published %u: %s\n",
              static_cast<unsigned long long>(st.frames),
              static_cast<unsigned long long>(st.frame_jumps), newest, client.last_error().c_str());
  EXPECT_EQ(st.frames, 24u);
  EXPECT_EQ(st.frame_jumps, 4u);
  EXPECT_EQ(st.rejected_too_fast, 0u);
  EXPECT_EQ(st.foreign_datagrams, 0u);
  EXPECT_EQ(newest, 20u);
  const auto* hand = s.find(kSimRightHandId);
  ASSERT_NE(hand, nullptr);
  EXPECT_TRUE(hand->valid);
  EXPECT_NEAR(hand->pose.p_m.z, -0.25, 1e-6);
  EXPECT_NE(client.last_error().find("went back"), std::string::npos) << client.last_error();
}

}  // namespace
}  // namespace telex::local
