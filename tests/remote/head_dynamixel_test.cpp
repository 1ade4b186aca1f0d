// SPDX-License-Identifier: MIT
// --head dynamixel over a pseudo-terminal: the emulated servos (tools/sim) on the master side, the
// driver on the slave side; start-up errors, running errors counted, the daemon and the CLI.
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <thread>

#include "process.h"
#include "telex/dynamixel/protocol.h"
#include "telex/remote/daemon.h"
#include "telex/remote/head.h"
#include "telex/remote/sources.h"
#include "telex/sim/dynamixel_servos.h"
#include "test_support.h"

namespace telex::remote {
namespace {

using ::telex::test::expect_contains;
using ::telex::test::message_of;

using namespace std::chrono_literals;
namespace xs = telex::dynamixel::xseries;
constexpr double kPi = std::numbers::pi;

// SYNC_WRITE has no answer, so the emulator applies it after command() returns: the goal once it
// is there (polled for at most 2 s, a bound on a hung test, not a measurement).
std::int32_t goal_after_write(sim::DynamixelBus& bus, std::uint8_t id, std::int32_t expected) {
  std::int32_t goal = bus.goal_counts(id);
  for (int i = 0; i < 2000 && goal != expected; ++i) {
    std::this_thread::sleep_for(1ms);
    goal = bus.goal_counts(id);
  }
  return goal;
}

TEST(HeadDynamixel, MovesTheEmulatedServosAndReadsThemBack) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  auto head = make_head_driver("dynamixel:" + servos.device());
  expect_contains(head->name(), "ids 1,2,3 at 57600 baud (models 1030, 1030, 1030)");
  // Start-up: torque on, and each servo's own profile at the rate limit (180 deg/s = 131 units).
  for (const std::uint8_t id : {1, 2, 3}) {
    EXPECT_TRUE(servos.bus().torque_enabled(id));
    EXPECT_EQ(servos.bus().profile_velocity(id), 131u);
  }
  const HeadAngles target{0.5, -0.3, 0.2};
  head->command(target, steady_now_ns());
  for (std::size_t j = 0; j < 3; ++j) {
    const std::int32_t expected = xs::counts_from_rad(target[j]);
    EXPECT_EQ(goal_after_write(servos.bus(), static_cast<std::uint8_t>(j + 1), expected), expected);
  }
  // The servos move at their profile velocity: 0.5 rad takes about 0.16 s. Poll until there
  // (at most 5 s: a bound on a hung test, not a measurement).
  HeadPose p;
  for (int i = 0; i < 500; ++i) {
    p = head->measured(steady_now_ns());
    ASSERT_TRUE(p.valid) << head->stats().last_error;
    bool there = true;
    for (std::size_t j = 0; j < 3; ++j)
      there = there && std::abs(p.joint_rad[j] - target[j]) < 2 * kPi / 4096;
    if (there) break;
    std::this_thread::sleep_for(10ms);
  }
  for (std::size_t j = 0; j < 3; ++j) {
    EXPECT_NEAR(p.joint_rad[j], target[j], 2 * kPi / 4096) << head_joint_name(j);
    EXPECT_DOUBLE_EQ(
        p.joint_rad[j],
        xs::rad_from_counts(servos.bus().present_counts(static_cast<std::uint8_t>(j + 1))));
  }
  // Clamped to the limits before it reaches the bus.
  head->command({3.0, 0.0, -1.0}, steady_now_ns());
  EXPECT_EQ(goal_after_write(servos.bus(), 1, 3072), xs::counts_from_rad(kPi / 2));
  EXPECT_EQ(goal_after_write(servos.bus(), 3, xs::counts_from_rad(-kPi / 6)),
            xs::counts_from_rad(-kPi / 6));
  const HeadStats s = head->stats();
  EXPECT_EQ(s.commands, 2u);
  EXPECT_EQ(s.clamped, 2u);
  EXPECT_EQ(s.timeouts + s.crc_errors + s.bad_packets + s.io_errors, 0u) << s.last_error;
  EXPECT_GT(servos.bus().counters().instructions, 10u);
}

TEST(HeadDynamixel, LeavingHoldsTheHeadWhereItWas) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  auto head = make_head_driver("dynamixel:" + servos.device());
  head->command({1.0, 0.0, 0.0}, steady_now_ns());  // 0.32 s of travel at 180 deg/s
  std::this_thread::sleep_for(100ms);
  const HeadPose p = head->measured(steady_now_ns());
  ASSERT_TRUE(p.valid);
  ASSERT_GT(p.joint_rad[0], 0.0);
  ASSERT_LT(p.joint_rad[0], 1.0);
  head.reset();
  const std::int32_t held = xs::counts_from_rad(p.joint_rad[0]);
  EXPECT_EQ(goal_after_write(servos.bus(), 1, held), held);
  EXPECT_TRUE(servos.bus().torque_enabled(1));
}

TEST(HeadDynamixel, IdsAndBaudFromTheSpec) {
  sim::DynamixelPtyServer servos({7, 8, 9});
  auto head = make_head_driver("dynamixel:" + servos.device() + ",ids=9,7,8,baud=1000000");
  expect_contains(head->name(), "ids 9,7,8 at 1000000 baud");
  head->command({0.1, 0.2, 0.3}, steady_now_ns());
  const std::int32_t yaw = xs::counts_from_rad(0.1), pitch = xs::counts_from_rad(0.2),
                     roll = xs::counts_from_rad(0.3);
  EXPECT_EQ(goal_after_write(servos.bus(), 9, yaw), yaw);
  EXPECT_EQ(goal_after_write(servos.bus(), 7, pitch), pitch);
  EXPECT_EQ(goal_after_write(servos.bus(), 8, roll), roll);
}

TEST(HeadDynamixel, GoalsStayWithinOneTurn) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  HeadLimits limits = kDefaultHeadLimits;
  limits.joint[0] = {-kPi, kPi, kPi, 10 * kPi};
  auto head = make_head_driver("dynamixel:" + servos.device(), limits);
  head->command({kPi, 0.0, 0.0}, steady_now_ns());
  EXPECT_EQ(goal_after_write(servos.bus(), 1, 4095), 4095);  // not 4096, which a servo refuses
  head->command({-kPi, 0.0, 0.0}, steady_now_ns());
  EXPECT_EQ(goal_after_write(servos.bus(), 1, 0), 0);
}

TEST(HeadDynamixel, ReadsWhereTheServosAreAtStart) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  servos.bus().set_present_counts(1, 2048 + 512);  // yaw 45 deg, the goal still at 2048
  auto head = make_head_driver("dynamixel:" + servos.device());
  // The goal was set where the head is before torque came on: no jump back to 0.
  EXPECT_EQ(servos.bus().goal_counts(1), 2048 + 512);
  std::this_thread::sleep_for(50ms);
  const HeadPose p = head->measured(steady_now_ns());
  ASSERT_TRUE(p.valid);
  EXPECT_DOUBLE_EQ(p.joint_rad[0], kPi / 4);
  EXPECT_DOUBLE_EQ(p.joint_rad[1], 0.0);
}

TEST(HeadDynamixel, ASilentServoIsNamedWithWhatToTry) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  servos.bus().set_silent(3, true);
  const std::string m =
      message_of([&] { make_head_driver("dynamixel:" + servos.device() + ",baud=115200"); });
  expect_contains(m, "--head dynamixel:" + servos.device());
  expect_contains(m, "servo id 3 (roll) did not answer a ping");
  expect_contains(m, "ids 1, 2 answered");
  expect_contains(m, "115200 baud");
  expect_contains(m, "powered");
  EXPECT_THROW(make_head_driver("dynamixel:" + servos.device()), std::runtime_error);
}

TEST(HeadDynamixel, APtyWithNobodyAnsweringIsASilentDevice) {
  int master = -1, slave = -1;
  char name[256] = {};
  ASSERT_EQ(::openpty(&master, &slave, name, nullptr, nullptr), 0);
  const std::string m = message_of([&] { make_head_driver(std::string("dynamixel:") + name); });
  expect_contains(m, std::string("--head dynamixel:") + name);
  expect_contains(m, "servo id 1 (yaw), servo id 2 (pitch), servo id 3 (roll) did not answer");
  expect_contains(m, "no id answered");
  expect_contains(m, "baud");
  ::close(master);
  ::close(slave);
}

TEST(HeadDynamixel, AMissingOrWrongDeviceIsNamed) {
  const std::string missing = "/dev/ttyTELEX-no-such-adapter";
  EXPECT_THROW(make_head_driver("dynamixel:" + missing), std::runtime_error);
  const std::string m = message_of([&] { make_head_driver("dynamixel:" + missing); });
  expect_contains(m, "no serial port " + missing);
  expect_contains(m, "ls /dev/ttyUSB*");
  expect_contains(message_of([] { make_head_driver("dynamixel:/dev/null"); }),
                  "/dev/null is not a serial port");
}

TEST(HeadDynamixel, AServoNotInPositionModeIsRefused) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  servos.bus().set_operating_mode(2, 1);  // velocity control
  expect_contains(message_of([&] { make_head_driver("dynamixel:" + servos.device()); }),
                  "servo id 2 (pitch) is in Operating Mode 1");
}

// Multi-turn modes ignore the servo's own position limits: refused, naming the servo and the mode.
TEST(HeadDynamixel, ExtendedPositionModeIsRefusedNamingTheServoAndTheMode) {
  for (const auto& [mode, name] : {std::pair<std::uint8_t, const char*>{4, "Extended Position"},
                                   {5, "Current-based Position"}}) {
    sim::DynamixelPtyServer servos({1, 2, 3});
    servos.bus().set_operating_mode(3, mode);
    const std::string m = message_of([&] { make_head_driver("dynamixel:" + servos.device()); });
    std::printf("mode %d: %s\n", int{mode}, m.c_str());
    expect_contains(m,
                    "servo id 3 (roll) is in Operating Mode " + std::to_string(mode) + ": " + name);
    expect_contains(m, "ignores the Min/Max Position Limits");
    expect_contains(m, "set it to 3 (Position Control Mode)");
    EXPECT_FALSE(servos.bus().torque_enabled(3));  // refused before anything was written
    EXPECT_EQ(servos.bus().register_value(3, xs::kProfileVelocity, 4), 0u);
  }
}

// At start the rig's limits go into the servos' own registers, read back from the emulator: the
// joint limits as Min/Max Position Limit, the rate as Profile Velocity, the acceleration as
// Profile Acceleration. A goal beyond them is then refused by the servo itself, as a real one
// refuses it, whoever sends it.
TEST(HeadDynamixel, TheRigsLimitsAndProfileAreProgrammedIntoTheServos) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  HeadLimits limits;
  limits.joint[0] = {-60 * kPi / 180, 60 * kPi / 180, 90 * kPi / 180, 900 * kPi / 180};
  limits.joint[1] = {-30 * kPi / 180, 20 * kPi / 180, 45 * kPi / 180, 450 * kPi / 180};
  limits.joint[2] = {-15 * kPi / 180, 15 * kPi / 180, 30 * kPi / 180, 300 * kPi / 180};
  auto head = make_head_driver("dynamixel:" + servos.device(), limits);
  sim::DynamixelBus& bus = servos.bus();
  // 60 deg = 682.67 counts, so 2048 +- 683; 20 deg = 227.6 -> 2276; -30 deg = -341.3 -> 1707.
  const std::uint32_t expect_max[] = {2731, 2276, 2219}, expect_min[] = {1365, 1707, 1877};
  // 90 deg/s = 15 rev/min = 65.5 units -> 66; 900 deg/s^2 = 9000 rev/min^2 = 41.9 units -> 41
  // (rounded down: never harder than asked).
  const std::uint32_t expect_pv[] = {66, 33, 22}, expect_pa[] = {41, 20, 13};
  for (std::uint8_t id = 1; id <= 3; ++id) {
    const std::size_t j = id - 1u;
    std::printf("servo %d: Min/Max Position Limit %u..%u, Profile Velocity %u, Acceleration %u\n",
                int{id}, bus.register_value(id, xs::kMinPositionLimit, 4),
                bus.register_value(id, xs::kMaxPositionLimit, 4),
                bus.register_value(id, xs::kProfileVelocity, 4),
                bus.register_value(id, xs::kProfileAcceleration, 4));
    EXPECT_EQ(bus.register_value(id, xs::kMaxPositionLimit, 4), expect_max[j]) << int{id};
    EXPECT_EQ(bus.register_value(id, xs::kMinPositionLimit, 4), expect_min[j]) << int{id};
    EXPECT_EQ(bus.register_value(id, xs::kProfileVelocity, 4), expect_pv[j]) << int{id};
    EXPECT_EQ(bus.register_value(id, xs::kProfileAcceleration, 4), expect_pa[j]) << int{id};
    EXPECT_TRUE(bus.torque_enabled(id));
  }
  // The driver's own goals stay inside (clamped), so the servos take them.
  head->command({2.0, -2.0, 0.1}, steady_now_ns());
  EXPECT_EQ(goal_after_write(bus, 1, 2731), 2731);
  EXPECT_EQ(goal_after_write(bus, 2, 1707), 1707);
  EXPECT_EQ(bus.counters().goals_refused, 0u);
  // A goal beyond a programmed limit from anyone else on the bus: Data Limit Error, not taken.
  const std::int32_t before = bus.goal_counts(1);
  const std::vector<std::uint8_t> answer =
      bus.handle(dynamixel::write_packet(1, xs::kGoalPosition, dynamixel::le_bytes(2731 + 1, 4)),
                 steady_now_ns());
  dynamixel::PacketParser parser(dynamixel::PacketKind::Status);
  ASSERT_EQ(parser.feed(answer), answer.size());
  const auto status = parser.next();
  ASSERT_TRUE(status && status->error == dynamixel::ParseError::None);
  EXPECT_EQ(status->packet.error, static_cast<std::uint8_t>(dynamixel::ErrorNumber::DataLimit));
  EXPECT_EQ(bus.goal_counts(1), before);
  EXPECT_EQ(bus.counters().goals_refused, 1u);
  // The limits are EEPROM: locked while torque is on.
  const std::vector<std::uint8_t> locked =
      bus.handle(dynamixel::write_packet(1, xs::kMaxPositionLimit, dynamixel::le_bytes(4095, 4)),
                 steady_now_ns());
  ASSERT_EQ(parser.feed(locked), locked.size());
  const auto refused = parser.next();
  ASSERT_TRUE(refused && refused->error == dynamixel::ParseError::None);
  EXPECT_EQ(refused->packet.error, static_cast<std::uint8_t>(dynamixel::ErrorNumber::Access));
  EXPECT_EQ(bus.register_value(1, xs::kMaxPositionLimit, 4), 2731u);
  // A restart finds the limits already there and leaves torque on throughout: the head does not
  // drop while the remote restarts.
  head.reset();
  auto again = make_head_driver("dynamixel:" + servos.device(), limits);
  EXPECT_TRUE(bus.torque_enabled(1));
  EXPECT_EQ(bus.register_value(1, xs::kMaxPositionLimit, 4), 2731u);
}

// The emulator's trapezoid: from rest, a servo's speed grows at its Profile Acceleration; a
// 0.5 rad move at 180 deg/s and 1800 deg/s^2 (the rig's defaults) takes 0.26 s, not the 0.16 s
// of the velocity alone, and its speed changes by at most the acceleration's 203 counts/s per
// 10 ms (+-200 for the whole counts the position is read in). Checked on the emulator's clock (its
// now_ns argument), not the wall's.
TEST(HeadDynamixel, TheEmulatedServosAccelerateAtTheirProfileAcceleration) {
  sim::DynamixelBus bus({1});
  const auto write = [&](std::uint16_t address, std::uint32_t v, std::size_t n, std::int64_t t) {
    bus.handle(dynamixel::write_packet(1, address, dynamixel::le_bytes(v, n)), t);
  };
  write(xs::kProfileVelocity, xs::profile_velocity_from_rad_s(kPi), 4, 0);
  write(xs::kProfileAcceleration, xs::profile_acceleration_from_rad_s2(10 * kPi), 4, 0);
  write(xs::kTorqueEnable, 1, 1, 0);
  write(xs::kGoalPosition, static_cast<std::uint32_t>(xs::counts_from_rad(0.5)), 4, 0);
  const double a_counts = 83 * 214.577 / 3600.0 * 4096;  // 83 units, in counts/s^2
  double prev = 2048, prev_v = 0;
  std::int64_t t_arrived = -1;
  for (std::int64_t ms = 10; ms <= 600; ms += 10) {
    bus.handle({}, ms * 1'000'000);
    const double x = bus.present_counts(1);
    const double v = (x - prev) / 0.01;
    EXPECT_LE(std::abs(v - prev_v), a_counts * 0.01 + 200.0) << ms;
    prev = x;
    prev_v = v;
    if (t_arrived < 0 && bus.present_counts(1) == xs::counts_from_rad(0.5)) t_arrived = ms;
  }
  std::printf("0.5 rad at Profile Velocity %u, Acceleration %u: arrived after %lld ms\n",
              bus.profile_velocity(1), bus.register_value(1, xs::kProfileAcceleration, 4),
              static_cast<long long>(t_arrived));
  EXPECT_GE(t_arrived, 240);
  EXPECT_LE(t_arrived, 300);
}

TEST(HeadDynamixel, AHardwareErrorAtStartSaysToReboot) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  servos.bus().set_hardware_error(1, 0x20);  // overload
  const std::string m = message_of([&] { make_head_driver("dynamixel:" + servos.device()); });
  expect_contains(m, "servo id 1 (yaw) refused Torque Enable");
  expect_contains(m, "hardware alert");
  expect_contains(m, "rebooted");
}

TEST(HeadDynamixel, RunningErrorsAreCountedNotThrown) {
  auto servos = std::make_unique<sim::DynamixelPtyServer>(std::vector<std::uint8_t>{1, 2, 3});
  auto head = make_head_driver("dynamixel:" + servos->device());
  ASSERT_TRUE(head->measured(steady_now_ns()).valid);

  // A corrupted answer: that servo's reading is missing (CRC error, then its timeout).
  servos->bus().corrupt_next_answers(1);
  HeadPose p = head->measured(steady_now_ns());
  EXPECT_FALSE(p.valid);
  EXPECT_EQ(head->stats().crc_errors, 1u);
  EXPECT_EQ(head->stats().timeouts, 1u);
  EXPECT_TRUE(head->measured(steady_now_ns()).valid);

  // A hardware error: the alert bit is counted, the position still read.
  servos->bus().set_hardware_error(2, 0x04);  // overheating
  p = head->measured(steady_now_ns());
  EXPECT_TRUE(p.valid);
  EXPECT_EQ(head->stats().hardware_errors, 1u);
  expect_contains(head->stats().last_error, "servo id 2: no error, hardware alert");

  // A servo that stops answering.
  servos->bus().set_silent(3, true);
  p = head->measured(steady_now_ns());
  EXPECT_FALSE(p.valid);
  EXPECT_EQ(head->stats().timeouts, 2u);
  expect_contains(head->stats().last_error, "servo id 3 did not answer");

  // The adapter unplugged: the port hangs up; reads and writes fail and are counted.
  servos.reset();
  EXPECT_FALSE(head->measured(steady_now_ns()).valid);
  head->command({0.1, 0.1, 0.1}, steady_now_ns());
  const HeadStats s = head->stats();
  EXPECT_GE(s.io_errors + s.timeouts, 3u) << s.last_error;
  EXPECT_EQ(s.reads, 7u);  // with the start-up's first reading
  EXPECT_EQ(s.reads_valid, 4u);
}

TEST(HeadDynamixel, DaemonFailsAtStartNamingAMissingHead) {
  DaemonConfig c;
  c.depth_source = "synthetic:plane";
  c.server.port = 0;
  c.stats_line = false;
  c.head = "dynamixel:/dev/ttyTELEX-no-such-adapter";
  RemoteDaemon d(c);
  EXPECT_THROW(d.start(), std::runtime_error);
  expect_contains(message_of([&] { d.start(); }), "/dev/ttyTELEX-no-such-adapter");
  c.head = "servo";
  EXPECT_THROW(validate(c), std::invalid_argument);
  c.head = "sim";
  c.head_limits.joint[1].max_rad = -1;
  EXPECT_THROW(validate(c), std::invalid_argument);
}

TEST(HeadDynamixel, DaemonMakesTheHeadAtStart) {
  sim::DynamixelPtyServer servos({1, 2, 3});
  DaemonConfig c;
  c.depth_source = "synthetic:plane";
  c.source_options.width = 160;
  c.source_options.height = 120;
  c.server.port = 0;
  c.stats_line = false;
  c.head = "dynamixel:" + servos.device();
  RemoteDaemon d(c);
  EXPECT_EQ(d.head(), nullptr);
  d.start();
  ASSERT_NE(d.head(), nullptr);
  EXPECT_TRUE(servos.bus().torque_enabled(2));
  // The daemon's head loop reads the servos (the driver is that loop's alone while it runs).
  EXPECT_TRUE(telex::test::eventually(std::chrono::seconds(5), [&] {
    return d.stats().head.reads_valid > 0;
  })) << d.stats().head.last_error;
  d.stop();
}

int run_remote(const std::string& args) { return telex::test::exit_code_of("telex-remote", args); }

TEST(TelexRemoteCli, HeadFlag) {
  ASSERT_TRUE(std::filesystem::exists(telex::test::built_binary("telex-remote")));
  EXPECT_EQ(run_remote("--head servo"), 2);
  EXPECT_EQ(run_remote("--head dynamixel:/dev/ttyUSB0,baud=12345"), 2);
  const std::string quick =
      " --source synthetic:plane --size 160x120 --listen 127.0.0.1:0 "
      "--no-stats --duration 0.3";
  EXPECT_EQ(run_remote("--head dynamixel:/dev/ttyTELEX-no-such-adapter" + quick), 1);
  EXPECT_EQ(run_remote("--head sim" + quick), 0);
  sim::DynamixelPtyServer servos({1, 2, 3});
  EXPECT_EQ(run_remote("--head dynamixel:" + servos.device() + quick), 0);
  EXPECT_TRUE(servos.bus().torque_enabled(1));
}

}  // namespace
}  // namespace telex::remote
