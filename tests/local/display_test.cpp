// SPDX-License-Identifier: MIT
// Haptic displays: Gravity Grabber motor mix and report bytes, UDP sink over loopback, sim CSV.
#include <gtest/gtest.h>
#include <unistd.h>

#include <boost/asio.hpp>
#include <fstream>
#include <functional>
#include <mutex>
#include <sstream>
#include <thread>

#include "process.h"
#include "telex/local/displays/display_registry.h"
#include "telex/local/displays/gravity_grabber.h"
#include "telex/local/displays/haptic_display.h"
#include "telex/local/displays/udp_sink.h"

namespace telex::local {
namespace {

std::filesystem::path temp_path(const std::string& name) {
  return ::telex::test::scratch_file(name);
}

TEST(DisplayGravityGrabber, OppositeMotorsForPressureSameForShear) {
  GravityGrabberConfig cfg;  // 3 N, 1.5 N full scale, motor limit 0.8
  std::array<FingerForce, 1> f{FingerForce{1, 1.5, 0.0, true}};
  auto m = gravity_grabber_motors(f, cfg);
  EXPECT_DOUBLE_EQ(m[2], 0.5);
  EXPECT_DOUBLE_EQ(m[3], -0.5);
  f[0] = {1, 0.0, 0.75, true};
  m = gravity_grabber_motors(f, cfg);
  EXPECT_DOUBLE_EQ(m[2], 0.5);
  EXPECT_DOUBLE_EQ(m[3], 0.5);
  f[0] = {1, 0.0, -0.75, true};
  m = gravity_grabber_motors(f, cfg);
  EXPECT_DOUBLE_EQ(m[2], -0.5);
  EXPECT_DOUBLE_EQ(m[3], -0.5);
  // Both: A = 1.0, B = 0 exceeds the 0.8 limit; scaled together, the mix stays.
  f[0] = {1, 1.5, 0.75, true};
  m = gravity_grabber_motors(f, cfg);
  EXPECT_DOUBLE_EQ(m[2], 0.8);
  EXPECT_DOUBLE_EQ(m[3], 0.0);
  // Far beyond full scale saturates at the limit.
  f[0] = {1, 50.0, 0.0, true};
  m = gravity_grabber_motors(f, cfg);
  EXPECT_DOUBLE_EQ(m[2], 0.8);
  EXPECT_DOUBLE_EQ(m[3], -0.8);
  // No contact, NaN force, disabled finger: motors off.
  f[0] = {1, 2.0, 0.5, false};
  EXPECT_EQ(gravity_grabber_motors(f, cfg), (std::array<double, 10>{}));
  f[0] = {1, std::nan(""), std::nan(""), true};
  EXPECT_EQ(gravity_grabber_motors(f, cfg), (std::array<double, 10>{}));
  cfg.fingers[1].enabled = false;
  f[0] = {1, 1.5, 0.0, true};
  EXPECT_EQ(gravity_grabber_motors(f, cfg), (std::array<double, 10>{}));
}

TEST(DisplayGravityGrabber, CalibrationSignsAndDeadZone) {
  GravityGrabberConfig cfg;
  cfg.fingers[0].motor_b_sign = -1;
  cfg.fingers[0].dead_zone = 0.1;
  cfg.fingers[0].gain_pressure = 0.5;
  std::array<FingerForce, 1> f{FingerForce{0, 3.0, 0.0, true}};  // p = 0.5 after the gain
  const auto m = gravity_grabber_motors(f, cfg);
  EXPECT_DOUBLE_EQ(m[0], 0.1 + 0.9 * 0.5);
  EXPECT_DOUBLE_EQ(m[1], 0.1 + 0.9 * 0.5);  // -0.55 flipped by the mounting sign
}

TEST(DisplayGravityGrabber, ReportBytesForKnownForces) {
  GravityGrabberConfig cfg;
  const std::array<FingerForce, 2> f{FingerForce{1, 1.5, 0.0, true},
                                     FingerForce{4, 0.0, 0.75, true}};
  const auto r = gravity_grabber_report(f, cfg, 0x2A);
  // 0.5 * 32767 = 16383.5 -> 16384 = 0x4000; -16384 = 0xC000 little-endian.
  std::array<std::uint8_t, 32> want{};
  want[0] = 0x01;                    // report id
  want[1] = 0x2A;                    // sequence
  want[2] = 0x01 | 0x04 | 0x20;      // enabled, index (bit 2), little (bit 5)
  want[7] = 0x00, want[8] = 0x40;    // index motor A +0.5
  want[9] = 0x00, want[10] = 0xC0;   // index motor B -0.5
  want[19] = 0x00, want[20] = 0x40;  // little motor A +0.5
  want[21] = 0x00, want[22] = 0x40;  // little motor B +0.5
  want[23] = static_cast<std::uint8_t>(0x2A + 0x25 + 0x40 + 0xC0 + 0x40 + 0x40);
  EXPECT_EQ(r, want);
  // Released: all zero except id, sequence and checksum.
  const auto off = gravity_grabber_report({}, cfg, 3);
  EXPECT_EQ(off[2], 0);
  EXPECT_EQ(off[23], 3);
}

// The keep-alive (docs/HARDWARE.md, "Keep-alive and watchdog") on its own clock: the unchanged
// report again every 50 ms, byte for byte, while the haptic thread wrote it less than 200 ms ago;
// then the motors-off report once, and silence until the next write.
TEST(DisplayGravityGrabber, KeepAliveResendsTheUnchangedReportUntilTheHoldThenMotorsOff) {
  GravityGrabberConfig cfg;
  GravityGrabberKeepAlive ka(cfg, GravityGrabberTiming{});
  const std::int64_t ms = 1'000'000, t0 = 5'000 * ms;
  const std::array<FingerForce, 1> press{FingerForce{1, 1.5, 0.0, true}};
  const auto r = gravity_grabber_report(press, cfg, 9);
  EXPECT_EQ(ka.idle(t0), nullptr) << "nothing written yet: nothing to keep alive";
  EXPECT_EQ(ka.fresh(t0, r), r);
  EXPECT_EQ(ka.idle(t0 + 50 * ms - 1), nullptr);
  for (const std::int64_t t : {50, 100, 150}) {
    const GravityGrabberReport* again = ka.idle(t0 + t * ms);
    ASSERT_NE(again, nullptr) << t << " ms";
    EXPECT_EQ(*again, r) << t << " ms: the same bytes, sequence included";
    EXPECT_EQ(ka.idle(t0 + t * ms + 49 * ms), nullptr) << t << " ms";
  }
  const GravityGrabberReport* off = ka.idle(t0 + 200 * ms);
  ASSERT_NE(off, nullptr);
  EXPECT_EQ(*off, gravity_grabber_report({}, cfg, 10)) << "motors off, the next sequence number";
  EXPECT_EQ(ka.idle(t0 + 250 * ms), nullptr);
  EXPECT_EQ(ka.idle(t0 + 10'000 * ms), nullptr);
  // A fresh report starts it again.
  const auto r2 = gravity_grabber_report(press, cfg, 11);
  EXPECT_EQ(ka.fresh(t0 + 20'000 * ms, r2), r2);
  ASSERT_NE(ka.idle(t0 + 20'050 * ms), nullptr);
  EXPECT_EQ(*ka.idle(t0 + 20'100 * ms), r2);
}

// The display's writer thread over a recording HID writer: one write, then the same report again
// as keep-alives, then motors off when the writes stop; closing sends motors off once more.
TEST(DisplayGravityGrabber, WriterThreadKeepsTheUnchangedReportAliveThenReleases) {
  struct Recorded {
    std::mutex m;
    std::vector<GravityGrabberReport> reports;
  };
  struct RecordingWriter final : HidReportWriter {
    explicit RecordingWriter(std::shared_ptr<Recorded> r) : rec(std::move(r)) {}
    int write(std::span<const std::uint8_t> report) override {
      GravityGrabberReport copy{};
      if (report.size() != copy.size()) return -1;
      std::copy(report.begin(), report.end(), copy.begin());
      std::lock_guard lock(rec->m);
      rec->reports.push_back(copy);
      return static_cast<int>(report.size());
    }
    std::string name() const override { return "recorder"; }
    std::shared_ptr<Recorded> rec;
  };
  auto rec = std::make_shared<Recorded>();
  GravityGrabberConfig cfg;
  auto display = make_gravity_grabber_display(std::make_unique<RecordingWriter>(rec), cfg);
  EXPECT_EQ(display->name(), "gravity-grabber:recorder");
  const std::array<FingerForce, 1> press{FingerForce{1, 1.5, 0.0, true}};
  display->write(0, press);
  const auto pressed = gravity_grabber_report(press, cfg, 1);  // the display's first sequence
  const auto off = gravity_grabber_report({}, cfg, 2);
  const auto snapshot = [&] {
    std::lock_guard lock(rec->m);
    return rec->reports;
  };
  ASSERT_TRUE(std::invoke([&] {
    for (int i = 0; i < 400; ++i) {
      const auto got = snapshot();
      if (!got.empty() && got.back() == off) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  })) << "no motors-off report after the writes stopped";
  const auto got = snapshot();
  ASSERT_GE(got.size(), 3u) << "the report, at least one keep-alive, motors off";
  for (std::size_t i = 0; i + 1 < got.size(); ++i) EXPECT_EQ(got[i], pressed) << i;
  std::this_thread::sleep_for(std::chrono::milliseconds(120));
  EXPECT_EQ(snapshot().size(), got.size()) << "motors off is not kept alive";
  EXPECT_EQ(display->stats().sent, got.size());
  display.reset();
  const auto closed = snapshot();
  ASSERT_EQ(closed.size(), got.size() + 1);
  EXPECT_EQ(closed.back()[2], 0) << "closing releases the belts";
}

TEST(DisplayGravityGrabber, ConfigFileLoadsAndRejectsWithTheKey) {
  const auto good = temp_path("gg.json");
  std::ofstream(good) << R"({"max_pressure_N": 2.0, "max_command": 0.5, "report_id": 2,
      "fingers": [{"finger": 1, "motor_a_sign": -1, "dead_zone": 0.05}, {"finger": 3, "enabled": false}]})";
  const auto cfg = GravityGrabberConfig::load(good);
  EXPECT_DOUBLE_EQ(cfg.max_pressure_N, 2.0);
  EXPECT_DOUBLE_EQ(cfg.max_shear_N, 1.5);  // default kept
  EXPECT_EQ(cfg.report_id, 2);
  EXPECT_EQ(cfg.fingers[1].motor_a_sign, -1);
  EXPECT_DOUBLE_EQ(cfg.fingers[1].dead_zone, 0.05);
  EXPECT_FALSE(cfg.fingers[3].enabled);
  auto error_of = [&](const std::string& json) {
    const auto p = temp_path("bad.json");
    std::ofstream(p) << json;
    try {
      GravityGrabberConfig::load(p);
    } catch (const std::runtime_error& e) {
      std::filesystem::remove(p);
      return std::string(e.what());
    }
    std::filesystem::remove(p);
    return std::string();
  };
  EXPECT_NE(error_of(R"({"max_presure_N": 2})").find("unknown key \"max_presure_N\""),
            std::string::npos);
  EXPECT_NE(error_of(R"({"max_command": 3})").find("\"max_command\" must be a number in"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"fingers": [{"finger": 1, "motor_b_sign": 2}]})").find("motor_b_sign"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"fingers": [{"finger": 9}]})").find("0..4"), std::string::npos);
  EXPECT_NE(error_of("{oops").find("not JSON"), std::string::npos);
  std::filesystem::remove(good);
}

TEST(DisplayGravityGrabber, MissingDeviceSaysWhatToTry) {
  DisplayConfig cfg;
  try {
    make_display("gravity-grabber:/dev/hidraw-telex-missing", cfg);
    FAIL();
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/dev/hidraw-telex-missing"), std::string::npos) << what;
    EXPECT_NE(what.find("udev"), std::string::npos) << what;
    EXPECT_NE(what.find("sim"), std::string::npos) << what;
  }
  EXPECT_THROW(make_display("gravity-grabber:", cfg), std::invalid_argument);
  // By USB ids: this machine has no such controller, and the error says what hidapi found.
  try {
    make_display("gravity-grabber:16c0:fff7", cfg);
    FAIL();
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no HID device 16c0:fff7"), std::string::npos) << what;
    EXPECT_NE(what.find("lsusb -d 16c0:fff7"), std::string::npos) << what;
  }
  EXPECT_THROW(make_display("gravity-grabber:16c0", cfg), std::invalid_argument);
}

TEST(DisplayGravityGrabber, TargetIsAPathOrUsbIdsFoundByEnumeration) {
  const HidTarget p = parse_hid_target("/dev/hidraw3");
  EXPECT_FALSE(p.by_ids());
  EXPECT_EQ(p.path, "/dev/hidraw3");
  const HidTarget ids = parse_hid_target("16C0:05df");
  EXPECT_TRUE(ids.by_ids());
  EXPECT_EQ(ids.vendor_id, 0x16c0);
  EXPECT_EQ(ids.product_id, 0x05df);
  EXPECT_TRUE(ids.serial.empty());
  EXPECT_EQ(parse_hid_target("16c0:05df:GG-0042").serial, "GG-0042");
  for (const char* bad : {"", "16c0", "16c0:", ":05df", "16c0:05dfx", "12345:0001",
                          "16c0:05df:", "hidraw3", "g6c0:05df"}) {
    try {
      parse_hid_target(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("VID:PID"), std::string::npos) << e.what();
    }
  }
  // An enumeration as hidapi lists it: a keyboard, then the controller twice (two units).
  const std::vector<HidCandidate> seen = {
      {"/dev/hidraw0", 0x046d, 0xc31c, "", "USB Keyboard", "Logitech"},
      {"/dev/hidraw4", 0x16c0, 0x05df, "GG-0007", "Gravity Grabber", "lab"},
      {"/dev/hidraw5", 0x16c0, 0x05df, "GG-0042", "Gravity Grabber", "lab"},
  };
  EXPECT_EQ(choose_hid_device(parse_hid_target("16c0:05df"), seen), "/dev/hidraw4");
  EXPECT_EQ(choose_hid_device(parse_hid_target("16c0:05df:GG-0042"), seen), "/dev/hidraw5");
  EXPECT_FALSE(choose_hid_device(parse_hid_target("16c0:05df:GG-9999"), seen).has_value());
  EXPECT_FALSE(choose_hid_device(parse_hid_target("16c0:05de"), seen).has_value());
  EXPECT_EQ(choose_hid_device(parse_hid_target("/dev/hidraw0"), seen), "/dev/hidraw0");
  EXPECT_FALSE(choose_hid_device(parse_hid_target("/dev/hidraw9"), seen).has_value());
}

TEST(DisplayUdp, FormatIsEighteenIntegersTimesThousand) {
  const std::array<FingerForce, 2> f{FingerForce{1, 1.2345, -0.5, true},
                                     FingerForce{3, 9.0, 9.0, false}};
  std::array<char, kUdpSinkMaxBytes> buf{};
  const std::size_t n = format_udp_sink(udp_sink_channels(f), buf);
  EXPECT_EQ(std::string(buf.data(), n), "0 0 1235 -500 0 0 0 0 0 0 0 1000 0 0 0 0 0 0");
  std::array<double, kUdpSinkChannels> ch{};
  ch[0] = 1e12;
  ch[1] = std::nan("");
  ch[2] = -1e12;
  const std::size_t m = format_udp_sink(ch, buf);
  std::array<double, kUdpSinkChannels> back{};
  ASSERT_TRUE(parse_udp_sink(std::string_view(buf.data(), m), back));
  EXPECT_DOUBLE_EQ(back[0], 2147483.647);
  EXPECT_DOUBLE_EQ(back[1], 0.0);
  EXPECT_DOUBLE_EQ(back[2], -2147483.647);
  EXPECT_FALSE(parse_udp_sink("1 2 3", back));
  EXPECT_FALSE(parse_udp_sink("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0", back));
}

TEST(DisplayUdp, DatagramsArriveOnALoopbackSocket) {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::udp::socket rx(io, asio::ip::udp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  const int port = rx.local_endpoint().port();
  DisplayConfig cfg;
  auto display = make_display("udp:127.0.0.1:" + std::to_string(port), cfg);
  EXPECT_EQ(display->name(), "udp:127.0.0.1:" + std::to_string(port));
  const std::array<FingerForce, 3> f{FingerForce{0, 0.25, 0.0, true},
                                     FingerForce{1, 2.0, 0.125, true},
                                     FingerForce{2, 0.0, 0.0, false}};
  display->write(1000, f);
  display->write(2000, std::span<const FingerForce>{});
  std::array<char, 2048> buf{};
  asio::ip::udp::endpoint from;
  std::size_t n = rx.receive_from(asio::buffer(buf), from);
  std::array<double, kUdpSinkChannels> ch{};
  ASSERT_TRUE(parse_udp_sink(std::string_view(buf.data(), n), ch));
  EXPECT_DOUBLE_EQ(ch[0], 0.25);
  EXPECT_DOUBLE_EQ(ch[2], 2.0);
  EXPECT_DOUBLE_EQ(ch[3], 0.125);
  EXPECT_DOUBLE_EQ(ch[10], 1.0);
  EXPECT_DOUBLE_EQ(ch[11], 1.0);
  EXPECT_DOUBLE_EQ(ch[12], 0.0);
  n = rx.receive_from(asio::buffer(buf), from);  // the release write: all zero
  ASSERT_TRUE(parse_udp_sink(std::string_view(buf.data(), n), ch));
  EXPECT_EQ(ch, (std::array<double, kUdpSinkChannels>{}));
  EXPECT_EQ(display->stats().sent, 2u);
  EXPECT_DOUBLE_EQ(display->stats().max_pressure_N, 2.0);

  auto default_port = make_display("udp:127.0.0.1", cfg);
  EXPECT_EQ(default_port->name(), "udp:127.0.0.1:1234");
  EXPECT_THROW(make_display("udp:127.0.0.1:http", cfg), std::invalid_argument);
  EXPECT_THROW(make_display("udp:no-such-host.invalid:1234", cfg), std::runtime_error);
}

TEST(DisplaySim, CsvRecordsEveryWrite) {
  const auto path = temp_path("sim.csv");
  DisplayConfig cfg;
  cfg.sim_ring_capacity = 100000;  // no drops even if the writer thread never runs until the end
  {
    auto d = make_display("sim:" + path.string(), cfg);
    for (int i = 0; i < 500; ++i) {
      const std::array<FingerForce, 2> f{FingerForce{1, 0.001 * i, -0.0005 * i, i % 2 == 0},
                                         FingerForce{4, 1.0, 0.0, true}};
      d->write(1'000'000LL * i, f);
    }
    const auto s = d->stats();
    EXPECT_EQ(s.writes, 500u);
    EXPECT_DOUBLE_EQ(s.max_pressure_N, 1.0);
    EXPECT_DOUBLE_EQ(s.max_shear_N, 0.0005 * 499);
  }
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line.substr(0, 50), "time_ns,thumb_pressure_N,thumb_shear_N,thumb_conta");
  int rows = 0;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::vector<double> v;
    std::string cell;
    while (std::getline(ss, cell, ',')) v.push_back(std::stod(cell));
    ASSERT_EQ(v.size(), 16u);
    EXPECT_EQ(static_cast<long long>(v[0]), 1'000'000LL * rows);
    EXPECT_NEAR(v[4], 0.001 * rows, 1e-6);    // index pressure
    EXPECT_NEAR(v[5], -0.0005 * rows, 1e-6);  // index shear
    EXPECT_EQ(v[6], rows % 2 == 0 ? 1.0 : 0.0);
    EXPECT_EQ(v[1], 0.0);   // thumb absent
    EXPECT_EQ(v[13], 1.0);  // little pressure
    ++rows;
  }
  EXPECT_EQ(rows, 500);
  std::filesystem::remove(path);
}

TEST(DisplaySim, SmallRingCountsEveryWriteAsRecordedOrDropped) {
  const auto path = temp_path("small.csv");
  DisplayConfig cfg;
  cfg.sim_ring_capacity = 4;
  DisplayStats s;
  {
    auto d = make_display("sim:" + path.string(), cfg);
    const std::array<FingerForce, 1> f{FingerForce{1, 0.5, 0.0, true}};
    for (int i = 0; i < 1000; ++i) d->write(i, f);
    s = d->stats();
  }
  EXPECT_EQ(s.writes, 1000u);
  EXPECT_LE(s.sent + s.dropped, 1000u);  // the rest is flushed when the display closes
  std::ifstream in(path);
  int lines = -1;  // header
  for (std::string l; std::getline(in, l);) ++lines;
  EXPECT_EQ(static_cast<std::uint64_t>(lines) + s.dropped, 1000u);
  std::filesystem::remove(path);
}

TEST(DisplaySim, BadSpecsAndPaths) {
  DisplayConfig cfg;
  auto plain = make_display("sim", cfg);
  EXPECT_EQ(plain->name(), "sim");
  try {
    make_display("sim:/nonexistent-dir/x.csv", cfg);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.csv"), std::string::npos);
  }
  EXPECT_THROW(make_display("phantom", cfg), std::invalid_argument);
}

}  // namespace
}  // namespace telex::local
