// SPDX-License-Identifier: MIT
// The robot head: limits, --head specs, the controller (clamp, rate and acceleration limits; its
// holds are in head_hold_test.cpp), the sim head against its analytic response, none, and udp
// against a local peer socket.
#include "telex/remote/head.h"

#include <gtest/gtest.h>

#include <boost/asio.hpp>
#include <cmath>
#include <cstdio>
#include <random>
#include <thread>

#include "test_support.h"

namespace telex::remote {
namespace {

using ::telex::test::expect_contains;
using ::telex::test::message_of;

using namespace std::chrono_literals;
constexpr double kPi = std::numbers::pi;
constexpr std::int64_t kMs = 1'000'000;

TEST(HeadLimits, DefaultsAreTheDocumentedOnesAndValid) {
  EXPECT_NO_THROW(kDefaultHeadLimits.validate());
  EXPECT_DOUBLE_EQ(kDefaultHeadLimits.joint[0].max_rad, kPi / 2);
  EXPECT_DOUBLE_EQ(kDefaultHeadLimits.joint[1].min_rad, -kPi / 4);
  EXPECT_DOUBLE_EQ(kDefaultHeadLimits.joint[2].max_rad, kPi / 6);
  for (const auto& j : kDefaultHeadLimits.joint) {
    EXPECT_DOUBLE_EQ(j.max_rate_rad_s, kPi);
    EXPECT_DOUBLE_EQ(j.max_accel_rad_s2, 10 * kPi);  // 1800 deg/s^2
  }
}

TEST(HeadLimits, ABadJointIsNamed) {
  HeadLimits l = kDefaultHeadLimits;
  l.joint[1].min_rad = 0.5;
  l.joint[1].max_rad = 0.2;
  EXPECT_THROW(l.validate(), std::invalid_argument);
  EXPECT_NE(message_of([&] { l.validate(); }).find("head pitch"), std::string::npos);
  l = kDefaultHeadLimits;
  l.joint[2].max_rate_rad_s = 0;
  EXPECT_NE(message_of([&] { l.validate(); }).find("head roll: max_rate"), std::string::npos);
  l = kDefaultHeadLimits;
  l.joint[0].max_rad = 4.0;
  EXPECT_NE(message_of([&] { l.validate(); }).find("head yaw"), std::string::npos);
  l = kDefaultHeadLimits;
  l.joint[0].min_rad = std::nan("");
  EXPECT_THROW(l.validate(), std::invalid_argument);
}

TEST(HeadSpec, ValidForms) {
  EXPECT_EQ(parse_head_spec("none").kind, HeadSpec::Kind::None);
  const HeadSpec sim = parse_head_spec("sim");
  EXPECT_EQ(sim.kind, HeadSpec::Kind::Sim);
  EXPECT_DOUBLE_EQ(sim.sim_tau_s, 0.08);
  EXPECT_DOUBLE_EQ(parse_head_spec("sim,tau_ms=40").sim_tau_s, 0.04);
  const HeadSpec d = parse_head_spec("dynamixel:/dev/ttyUSB0");
  EXPECT_EQ(d.kind, HeadSpec::Kind::Dynamixel);
  EXPECT_EQ(d.device, "/dev/ttyUSB0");
  EXPECT_EQ(d.ids, (std::array<std::uint8_t, 3>{1, 2, 3}));
  EXPECT_EQ(d.baud, 57600);
  const HeadSpec d2 =
      parse_head_spec("dynamixel:/dev/serial/by-id/usb-FTDI-if00,ids=7,8,9,baud=1000000");
  EXPECT_EQ(d2.device, "/dev/serial/by-id/usb-FTDI-if00");
  EXPECT_EQ(d2.ids, (std::array<std::uint8_t, 3>{7, 8, 9}));
  EXPECT_EQ(d2.baud, 1000000);
  EXPECT_EQ(parse_head_spec("dynamixel:/dev/ttyACM0,baud=115200,ids=3,1,2").ids,
            (std::array<std::uint8_t, 3>{3, 1, 2}));
  const HeadSpec u = parse_head_spec("udp:10.0.0.5:9100");
  EXPECT_EQ(u.kind, HeadSpec::Kind::Udp);
  EXPECT_EQ(u.host, "10.0.0.5");
  EXPECT_EQ(u.port, 9100);
  EXPECT_EQ(parse_head_spec("udp:[::1]:9100").host, "::1");
}

TEST(HeadSpec, BadFormsNameThePartAndTheValidForms) {
  const std::pair<const char*, const char*> cases[] = {
      {"servo", "unknown head kind 'servo'"},
      {"", "unknown head kind ''"},
      {"none:x", "'none' takes nothing"},
      {"sim:fast", "takes no ':'"},
      {"sim,tau_ms=0", "tau_ms '0'"},
      {"sim,speed=2", "unknown sim option 'speed=2'"},
      {"dynamixel", "needs the serial port"},
      {"dynamixel:", "serial port is empty"},
      {"dynamixel:/dev/ttyUSB0,baud=12345", "57600"},
      {"dynamixel:/dev/ttyUSB0,ids=1,2", "three servo ids"},
      {"dynamixel:/dev/ttyUSB0,ids=1,2,2", "given twice"},
      {"dynamixel:/dev/ttyUSB0,ids=1,2,300", "outside 0..252"},
      {"dynamixel:/dev/ttyUSB0,4", "unknown dynamixel option '4'"},
      {"udp:host", "HOST:PORT"},
      {"udp:host:0", "port '0'"},
      {"udp:host:70000", "port '70000'"},
  };
  for (const auto& [spec, part] : cases) {
    EXPECT_THROW(parse_head_spec(spec), std::invalid_argument) << spec;
    const std::string m = message_of([&] { parse_head_spec(spec); });
    EXPECT_NE(m.find(part), std::string::npos) << spec << ": " << m;
    EXPECT_NE(m.find("dynamixel:DEV[,ids=1,2,3][,baud=57600]"), std::string::npos) << m;
  }
  EXPECT_THROW(make_head_driver("servo"), std::invalid_argument);
}

TEST(HeadNone, MeasuredIsNeverValid) {
  auto head = make_head_driver("none");
  head->command({0.1, 0.2, 0.3}, 0);
  EXPECT_FALSE(head->measured(10 * kMs).valid);
  EXPECT_EQ(head->name(), "none");
  EXPECT_EQ(head->stats().reads, 1u);
}

TEST(HeadSim, SmallStepIsTheFirstOrderLag) {
  // 0.1 rad is within max_rate * tau (pi * 0.08 = 0.25 rad): no rate limit, x = 0.1 (1 - e^-t/tau).
  auto head = make_head_driver("sim");
  EXPECT_TRUE(head->measured(0).valid);
  head->command({0.1, -0.05, 0.02}, 0);
  for (const double t_s : {0.001, 0.01, 0.04, 0.08, 0.2, 0.5}) {
    const HeadPose p = head->measured(static_cast<std::int64_t>(t_s * 1e9));
    ASSERT_TRUE(p.valid);
    const double k = 1.0 - std::exp(-t_s / 0.08);
    EXPECT_NEAR(p.joint_rad[0], 0.1 * k, 1e-12) << t_s;
    EXPECT_NEAR(p.joint_rad[1], -0.05 * k, 1e-12) << t_s;
    EXPECT_NEAR(p.joint_rad[2], 0.02 * k, 1e-12) << t_s;
    EXPECT_EQ(p.time_ns, static_cast<std::int64_t>(t_s * 1e9));
  }
}

TEST(HeadSim, LargeStepIsRateLimitedThenExponential) {
  const double tau = 0.08, rate = kPi, step = 1.0;
  const double t_linear = (step - rate * tau) / rate;  // 0.238 s at pi rad/s
  auto head = make_head_driver("sim,tau_ms=80");
  head->measured(0);
  head->command({step, 0, 0}, 0);
  double last = 0;
  for (int ms = 1; ms <= 1000; ++ms) {
    const double t = ms * 1e-3;
    const double x = head->measured(ms * kMs).joint_rad[0];
    const double expected =
        t <= t_linear ? rate * t : step - rate * tau * std::exp(-(t - t_linear) / tau);
    ASSERT_NEAR(x, expected, 1e-9) << "t = " << t;
    ASSERT_LE(x - last, rate * 1e-3 + 1e-12) << "faster than the rate limit at t = " << t;
    last = x;
  }
}

TEST(HeadSim, ResultDoesNotDependOnHowTimeIsSplit) {
  auto coarse = make_head_driver("sim");
  auto fine = make_head_driver("sim");
  coarse->measured(0);
  fine->measured(0);
  coarse->command({1.2, -0.7, 0.4}, 0);
  fine->command({1.2, -0.7, 0.4}, 0);
  for (int us = 1; us <= 300'000; us += 7) fine->measured(us * 1000LL);
  const HeadPose a = coarse->measured(300'000'000);
  const HeadPose b = fine->measured(300'000'000);
  for (std::size_t j = 0; j < 3; ++j) EXPECT_NEAR(a.joint_rad[j], b.joint_rad[j], 1e-12);
  // An earlier time leaves the state where it is.
  EXPECT_EQ(coarse->measured(100'000'000).joint_rad, a.joint_rad);
}

TEST(HeadSim, TargetsAreClampedToTheLimits) {
  auto head = make_head_driver("sim");
  head->measured(0);
  head->command({3.0, -2.0, 0.0}, 0);
  const HeadPose p = head->measured(5'000'000'000);
  EXPECT_NEAR(p.joint_rad[0], kPi / 2, 1e-9);
  EXPECT_NEAR(p.joint_rad[1], -kPi / 4, 1e-9);
  EXPECT_EQ(head->stats().clamped, 2u);
  head->command({std::nan(""), 0, 0}, 5'000'000'001);
  EXPECT_EQ(head->stats().rejected, 1u);
}

TEST(HeadSim, JointAdvanceIsExactAtTheBandEdge) {
  // Starting exactly at the edge of the band the motion is exponential at once.
  const double band = kPi * 0.08;
  EXPECT_NEAR(sim_joint_advance(0, band, 0.08, 0.08, kPi), band * (1 - std::exp(-1.0)), 1e-15);
  EXPECT_EQ(sim_joint_advance(0.3, 1.0, 0.0, 0.08, kPi), 0.3);
  EXPECT_EQ(sim_joint_advance(0.3, 1.0, -1.0, 0.08, kPi), 0.3);
}

TEST(HeadController, NothingToCommandUntilAPoseOrTarget) {
  HeadController c;
  EXPECT_FALSE(c.update(HeadPose{}, 0).has_value());
  EXPECT_TRUE(c.holding());
  const auto cmd = c.update(HeadPose{{0.1, 0.0, 0.0}, 1, true}, 1);
  ASSERT_TRUE(cmd.has_value());
  EXPECT_EQ(*cmd, (HeadAngles{0.1, 0.0, 0.0}));  // holds where the head is
}

// A fresh sample from the operator's head: a new id each call, 2 ms old when sent and when it
// arrived (the operator's clock known), no dead-man.
HeadTarget fresh(const HeadAngles& joint_rad) {
  static std::uint32_t id = 0;
  return {joint_rad, ++id, 2 * kMs, Deadman::NotUsed, 0, 2 * kMs};
}

// The limits with an acceleration too high to matter, for the tests of the rate limit alone.
HeadControllerConfig rate_only() {
  HeadControllerConfig cfg;
  for (auto& j : cfg.limits.joint) j.max_accel_rad_s2 = 1e9;
  return cfg;
}

TEST(HeadController, ClampsAndRateLimitsFromThePreviousCommand) {
  HeadController c(rate_only());
  const HeadPose at_zero{{0, 0, 0}, 0, true};
  c.set_target(fresh({1.0, 2.0, -0.1}), 0);  // pitch beyond +45 deg
  EXPECT_EQ(c.stats().clamped, 1u);
  auto cmd = c.update(at_zero, 0);
  ASSERT_TRUE(cmd);
  EXPECT_EQ(*cmd, (HeadAngles{0, 0, 0}));  // dt = 0: no motion yet
  for (int ms = 10; ms <= 100; ms += 10) {
    c.set_target(fresh({1.0, 2.0, -0.1}), ms * kMs);
    cmd = c.update(at_zero, ms * kMs);
  }
  // 100 ms at pi rad/s: 0.314 rad for yaw and pitch; roll reached -0.1 within its first 40 ms.
  EXPECT_NEAR((*cmd)[0], kPi * 0.1, 1e-9);
  EXPECT_NEAR((*cmd)[1], kPi * 0.1, 1e-9);
  EXPECT_NEAR((*cmd)[2], -0.1, 1e-12);
  for (int ms = 110; ms <= 1000; ms += 10) {
    c.set_target(fresh({1.0, 2.0, -0.1}), ms * kMs);
    cmd = c.update(at_zero, ms * kMs);
  }
  EXPECT_DOUBLE_EQ((*cmd)[0], 1.0);
  EXPECT_DOUBLE_EQ((*cmd)[1], kPi / 4);  // clamped
  EXPECT_GT(c.stats().rate_limited, 0u);
  EXPECT_FALSE(c.holding());
}

// Targets that jump about (steps of up to a radian, reversals, a target at a joint limit) at a
// head loop whose period wanders between 7 and 13 ms: the commands' own speed (their difference
// over the loop's dt) never exceeds max_rate and changes by at most max_accel * dt per loop, and a
// target held long enough is reached exactly.
TEST(HeadController, AccelerationAndRateLimitsAreRespected) {
  HeadControllerConfig cfg;                    // the rig's defaults: 180 deg/s, 1800 deg/s^2
  cfg.limits.joint[1].max_accel_rad_s2 = 5.0;  // pitch: a slow one
  HeadController c(cfg);
  std::mt19937 rng(27);
  std::uniform_real_distribution<double> yaw(-1.8, 1.8), pitch(-0.9, 0.9), roll(-0.6, 0.6);
  std::uniform_int_distribution<int> period_ms(7, 13);
  std::int64_t t = 0;
  HeadAngles prev{}, prev_v{};
  HeadAngles goal{0.0, 0.0, 0.0};
  double worst_rate = 0, worst_accel = 0;  // as fractions of the limits
  int loops = 0;
  for (int phase = 0; phase < 40; ++phase) {
    goal = {yaw(rng), pitch(rng), roll(rng)};  // beyond the limits at times: clamped
    const int steps = phase % 5 == 4 ? 600 : 40;
    for (int i = 0; i < steps; ++i) {
      const std::int64_t dt = period_ms(rng) * kMs;
      t += dt;
      c.set_target(fresh(goal), t);
      const auto cmd = c.update(HeadPose{prev, t, true}, t);
      ASSERT_TRUE(cmd);
      ASSERT_FALSE(c.holding());
      if (loops++ > 0) {
        for (std::size_t j = 0; j < kHeadJoints; ++j) {
          const HeadJointLimits& l = cfg.limits.joint[j];
          const double dt_s = static_cast<double>(dt) * 1e-9;
          const double v = ((*cmd)[j] - prev[j]) / dt_s;
          worst_rate = std::max(worst_rate, std::abs(v) / l.max_rate_rad_s);
          const double accel = std::abs(v - prev_v[j]) / dt_s / l.max_accel_rad_s2;
          EXPECT_LE(accel, 1.0 + 1e-6)
              << "joint " << j << " loop " << loops << ": from " << prev[j] << " at " << prev_v[j]
              << " rad/s to " << (*cmd)[j] << " at " << v << " rad/s toward " << goal[j];
          worst_accel = std::max(worst_accel, accel);
          prev_v[j] = v;
        }
      }
      prev = *cmd;
    }
    if (steps == 600) {  // 6 s or more: long enough to arrive anywhere
      HeadAngles want = goal;
      clamp_to_limits(want, cfg.limits);
      EXPECT_EQ(prev, want) << "phase " << phase;
    }
  }
  std::printf(
      "HeadController: %d loops, worst speed %.6f x max_rate, worst speed change %.6f x "
      "max_accel * dt; %llu loops accel-limited, %llu rate-limited\n",
      loops, worst_rate, worst_accel, static_cast<unsigned long long>(c.stats().accel_limited),
      static_cast<unsigned long long>(c.stats().rate_limited));
  EXPECT_LE(worst_rate, 1.0 + 1e-9);
  EXPECT_LE(worst_accel, 1.0 + 1e-6);
  EXPECT_GT(worst_accel, 0.99);  // the limit was reached: the test exercised it
  EXPECT_GT(c.stats().accel_limited, 0u);
  EXPECT_GT(c.stats().rate_limited, 0u);
}

TEST(HeadController, NonFiniteTargetsAreDropped) {
  HeadController c;
  c.set_target(fresh({std::nan(""), 0, 0}), 0);
  c.set_target(fresh({0, std::numeric_limits<double>::infinity(), 0}), 0);
  EXPECT_EQ(c.stats().rejected_targets, 2u);
  EXPECT_EQ(c.stats().targets, 0u);
}

TEST(HeadController, RejectsBadConfig) {
  HeadControllerConfig cfg;
  cfg.link_timeout_s = 0;
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
  cfg = {};
  cfg.limits.joint[0].max_rate_rad_s = -1;
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
  cfg = {};
  cfg.limits.joint[2].max_accel_rad_s2 = 0;
  EXPECT_NE(message_of([&] { HeadController{cfg}; }).find("head roll: max_accel"),
            std::string::npos);
  cfg = {};
  cfg.max_sample_age_s = std::nan("");
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
  cfg = {};
  cfg.max_sample_repeat_s = -0.05;
  EXPECT_THROW(HeadController{cfg}, std::invalid_argument);
}

TEST(HeadDatagram, LayoutIsFixedLittleEndian) {
  HeadDatagram d;
  d.sequence = 0x01020304;
  d.time_ns = 2;
  d.joint_rad = {0.5, -0.25, 0.0};
  const std::vector<std::uint8_t> bytes = encode_head_datagram(d);
  const std::vector<std::uint8_t> expected = {'T',  'H',  'D',  '1',                     // magic
                                              0x04, 0x03, 0x02, 0x01,                    // sequence
                                              0x02, 0,    0,    0,    0, 0, 0,    0,     // time_ns
                                              0,    0,    0,    0,    0, 0, 0xE0, 0x3F,  // 0.5
                                              0,    0,    0,    0,    0, 0, 0xD0, 0xBF,  // -0.25
                                              0,    0,    0,    0,    0, 0, 0,    0};    // 0
  EXPECT_EQ(bytes, expected);
  const auto back = decode_head_datagram(bytes);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->sequence, d.sequence);
  EXPECT_EQ(back->time_ns, 2);
  EXPECT_EQ(back->joint_rad, d.joint_rad);
  auto wrong = bytes;
  wrong[0] = 'X';
  EXPECT_FALSE(decode_head_datagram(wrong));
  EXPECT_FALSE(decode_head_datagram(std::span(bytes).first(39)));
  d.joint_rad[1] = std::nan("");
  EXPECT_FALSE(decode_head_datagram(encode_head_datagram(d)));
}

// A lab's head controller, played by a local UDP socket.
class UdpPeer {
 public:
  UdpPeer()
      : socket_(io_,
                boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0)) {}
  std::uint16_t port() const { return socket_.local_endpoint().port(); }
  // The next datagram from the remote (waits at most 2 s; a failure, not a measurement).
  std::optional<HeadDatagram> receive() {
    socket_.non_blocking(true);
    std::array<std::uint8_t, 2048> buf{};
    for (int i = 0; i < 2000; ++i) {
      boost::system::error_code ec;
      const std::size_t n = socket_.receive_from(boost::asio::buffer(buf), from_, 0, ec);
      if (!ec) return decode_head_datagram(std::span(buf.data(), n));
      std::this_thread::sleep_for(1ms);
    }
    return std::nullopt;
  }
  void send(const std::vector<std::uint8_t>& bytes) {
    socket_.send_to(boost::asio::buffer(bytes), from_);
  }
  void reply(std::uint32_t sequence, const HeadAngles& a) {
    HeadDatagram d;
    d.sequence = sequence;
    d.time_ns = 123;
    d.joint_rad = a;
    send(encode_head_datagram(d));
  }

 private:
  boost::asio::io_context io_;
  boost::asio::ip::udp::socket socket_;
  boost::asio::ip::udp::endpoint from_;
};

// measured() until `done(pose, stats)` says so, for at most 2 s of polling (loopback delivery is
// asynchronous).
template <typename Done>
HeadPose measure_until(HeadDriver& head, std::int64_t now_ns, Done done) {
  HeadPose p;
  for (int i = 0; i < 2000; ++i) {
    p = head.measured(now_ns);
    if (done(p, head.stats())) break;
    std::this_thread::sleep_for(1ms);
  }
  return p;
}

TEST(HeadUdp, SendsClampedTargetsAndReadsPosesBack) {
  UdpPeer peer;
  auto head = make_head_driver("udp:127.0.0.1:" + std::to_string(peer.port()));
  EXPECT_EQ(head->name(), "udp:127.0.0.1:" + std::to_string(peer.port()));
  EXPECT_FALSE(head->measured(0).valid);  // nothing heard yet

  head->command({0.2, 1.5, -0.1}, 1000);
  head->command({0.3, 0.0, 0.0}, 2000);
  const auto first = peer.receive();
  const auto second = peer.receive();
  ASSERT_TRUE(first && second);
  EXPECT_EQ(first->sequence, 0u);
  EXPECT_EQ(second->sequence, 1u);
  EXPECT_EQ(first->time_ns, 1000);
  EXPECT_EQ(first->joint_rad, (HeadAngles{0.2, kPi / 4, -0.1}));  // pitch clamped
  EXPECT_EQ(head->stats().commands, 2u);
  EXPECT_EQ(head->stats().clamped, 1u);

  const std::int64_t t0 = 10 * kMs;
  peer.reply(100, {0.11, 0.22, -0.05});
  HeadPose p =
      measure_until(*head, t0, [](const HeadPose& q, const HeadStats&) { return q.valid; });
  ASSERT_TRUE(p.valid);
  EXPECT_EQ(p.joint_rad, (HeadAngles{0.11, 0.22, -0.05}));
  EXPECT_EQ(p.time_ns, t0);  // this host's clock when taken, not the controller's 123

  // A reordered older reply and a malformed datagram are counted and change nothing.
  peer.reply(99, {9, 9, 9});
  peer.send({1, 2, 3});
  p = measure_until(*head, t0 + kMs, [](const HeadPose&, const HeadStats& s) {
    return s.stale == 1 && s.bad_packets == 1;
  });
  EXPECT_EQ(head->stats().stale, 1u);
  EXPECT_EQ(head->stats().bad_packets, 1u);
  EXPECT_EQ(p.joint_rad, (HeadAngles{0.11, 0.22, -0.05}));
  EXPECT_TRUE(p.valid);

  // A controller that restarted its count (far behind) is believed.
  peer.reply(0, {0.01, 0.02, 0.03});
  p = measure_until(*head, t0 + 2 * kMs,
                    [](const HeadPose& q, const HeadStats&) { return q.joint_rad[0] == 0.01; });
  EXPECT_EQ(p.joint_rad, (HeadAngles{0.01, 0.02, 0.03}));

  // Half a second without a reply: no longer valid.
  EXPECT_TRUE(head->measured(t0 + 2 * kMs + 500 * kMs).valid);
  EXPECT_FALSE(head->measured(t0 + 2 * kMs + 501 * kMs).valid);
}

TEST(HeadUdp, AnUnresolvableHostIsARuntimeError) {
  EXPECT_THROW(make_head_driver("udp:no-such-host.invalid:9100"), std::runtime_error);
  EXPECT_NE(message_of([] {
              make_head_driver("udp:no-such-host.invalid:9100");
            }).find("cannot resolve 'no-such-host.invalid'"),
            std::string::npos);
}

}  // namespace
}  // namespace telex::remote
