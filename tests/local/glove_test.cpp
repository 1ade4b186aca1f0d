// SPDX-License-Identifier: MIT
// 5DT glove report parsing on byte-level reports, serial resync, calibration, open failures.
#include "telex/local/inputs/glove.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <vector>

#include "process.h"
#include "telex/local/inputs/tracker_registry.h"

namespace telex::local {
namespace {

// A 64-byte report with big-endian int16 `values` at the start, the rest zero.
std::vector<std::uint8_t> usb_report(const std::vector<std::int16_t>& values) {
  std::vector<std::uint8_t> r(64, 0);
  for (std::size_t i = 0; i < values.size(); ++i) {
    r[2 * i] = static_cast<std::uint8_t>((static_cast<std::uint16_t>(values[i]) >> 8) & 0xFF);
    r[2 * i + 1] = static_cast<std::uint8_t>(values[i] & 0xFF);
  }
  return r;
}

std::vector<std::uint8_t> serial_report(std::array<std::uint8_t, 7> d) {
  std::vector<std::uint8_t> r(k5dtSerialReportBytes);
  r[0] = k5dtSerialHeader;
  std::copy(d.begin(), d.end(), r.begin() + 1);
  r[8] = serial_5dt_checksum(d);
  return r;
}

// Each row of the product table against VRPN's masks (vrpn_Analog_5dtUSB.C): 0x01 left, 0x10 five
// sensors, 0x02 / 0x06 wireless port A / B. Ids VRPN does not list are not gloves.
TEST(Glove, ProductIdsSelectTheModelAsVrpnsMasksDo) {
  ASSERT_EQ(glove_products().size(), 12u);
  for (const auto& p : glove_products()) {
    SCOPED_TRACE(p.product_id);
    const bool five = (p.product_id & 0x10) != 0;
    const bool left = (p.product_id & 0x01) != 0;
    EXPECT_EQ(sensor_count(p.model), five ? 5 : 14);
    EXPECT_EQ(p.left_hand, left);
    if (five) {
      EXPECT_EQ(p.model, left ? GloveModel::Sensors5Left : GloveModel::Sensors5Right);
    }
    const int port = p.product_id & 0x06;
    EXPECT_STREQ(p.link, port == 0x06   ? "wireless port B"
                         : port == 0x02 ? "wireless port A"
                                        : "wired USB");
    EXPECT_EQ(glove_model_from_product_id(p.product_id), p.model);
  }
  for (std::uint16_t pid : {0x04, 0x05, 0x08, 0x0f, 0x14, 0x15, 0x18, 0x20, 0xffff})
    EXPECT_FALSE(glove_model_from_product_id(pid).has_value()) << pid;
}

TEST(Glove, UsbReportIsBigEndianOver4096) {
  // Bytes as the glove sends them: 0x0800 = 2048 -> 0.5, 0x0FFF = 4095, 0x0400 -> 0.25.
  const auto r = usb_report({0x0800, 0x0FFF, 0x0400, 0x0001, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x0C00});
  EXPECT_EQ(r[0], 0x08);
  EXPECT_EQ(r[1], 0x00);
  GloveRaw raw;
  ASSERT_EQ(parse_5dt_usb_report(r, GloveModel::Sensors14, raw), nullptr);
  EXPECT_EQ(raw.sensor_count, 14);
  EXPECT_DOUBLE_EQ(raw.sensors[0], 0.5);
  EXPECT_DOUBLE_EQ(raw.sensors[1], 4095.0 / 4096.0);
  EXPECT_DOUBLE_EQ(raw.sensors[2], 0.25);
  EXPECT_DOUBLE_EQ(raw.sensors[3], 1.0 / 4096.0);
  EXPECT_DOUBLE_EQ(raw.sensors[13], 0.75);
}

TEST(Glove, FiveSensorGloveReadsIndicesZeroThreeSixNineTwelve) {
  std::vector<std::int16_t> v(16, 0x0100);  // decoys everywhere else
  v[0] = 0x0400;
  v[3] = 0x0800;
  v[6] = 0x0C00;
  v[9] = 0x0200;
  v[12] = 0x0A00;
  GloveRaw raw;
  ASSERT_EQ(parse_5dt_usb_report(usb_report(v), GloveModel::Sensors5Right, raw), nullptr);
  EXPECT_EQ(raw.sensor_count, 5);
  EXPECT_DOUBLE_EQ(raw.sensors[0], 0.25);
  EXPECT_DOUBLE_EQ(raw.sensors[1], 0.5);
  EXPECT_DOUBLE_EQ(raw.sensors[2], 0.75);
  EXPECT_DOUBLE_EQ(raw.sensors[3], 0.125);
  EXPECT_DOUBLE_EQ(raw.sensors[4], 0.625);
  const std::vector<std::uint8_t> shorty(31, 0);
  EXPECT_STREQ(parse_5dt_usb_report(shorty, GloveModel::Sensors5Left, raw),
               "5DT USB report shorter than 16 int16 values (32 bytes)");
}

// The wired Data Glove 5 stream as vrpn_Analog_5dt.C reads it: 0x80, five fingers, pitch, roll,
// checksum. VRPN does not check the checksum, so a report with another one is kept (and counted).
TEST(Glove, SerialStreamResynchronisesOnTheHeader) {
  std::vector<std::uint8_t> stream{0x12, 0x34};                // line noise
  auto good1 = serial_report({10, 20, 30, 40, 50, 128, 255});  // 0x80 inside the data
  auto odd = serial_report({1, 2, 3, 4, 5, 6, 7});
  odd.back() ^= 0x55;  // another checksum
  auto good2 = serial_report({255, 0, 0, 0, 0, 0, 0});
  for (const auto* r : {&good1, &odd, &good2}) stream.insert(stream.end(), r->begin(), r->end());
  Serial5dtParser p;
  std::vector<GloveRaw> got;
  GloveRaw raw;
  for (auto b : stream)
    if (p.push(b, raw)) got.push_back(raw);
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0].sensor_count, 5);
  EXPECT_DOUBLE_EQ(got[0].sensors[1], 20 / 255.0);
  EXPECT_DOUBLE_EQ(got[0].pitch_deg, 180.0 * 128 / 255.0);
  EXPECT_DOUBLE_EQ(got[0].roll_deg, 180.0);
  EXPECT_DOUBLE_EQ(got[1].sensors[4], 5 / 255.0);
  EXPECT_DOUBLE_EQ(got[2].sensors[0], 1.0);
  EXPECT_EQ(p.checksum_mismatches(), 1u);
  EXPECT_EQ(p.skipped_bytes(), 2u);
}

// The wireless 5-W: ten bytes, the last a capability byte 0x40 or 0x01 (right hand). A frame
// that does not end in one is out of step and is dropped up to the next header.
TEST(Glove, WirelessReportsEndInACapabilityByte) {
  auto r1 = serial_report({1, 2, 3, 4, 5, 6, 7});
  r1.push_back(0x01);
  auto r2 = serial_report({9, 9, 9, 9, 9, 0x80, 9});  // a header value inside the data
  r2.push_back(0x40);
  std::vector<std::uint8_t> stream;
  stream.insert(stream.end(), r1.begin() + 3, r1.end());  // joined mid-report
  stream.insert(stream.end(), r1.begin(), r1.end());
  stream.insert(stream.end(), r2.begin(), r2.end());
  auto broken = serial_report({7, 7, 7, 7, 7, 7, 7});
  broken.push_back(0x33);  // no capability byte
  stream.insert(stream.end(), broken.begin(), broken.end());
  stream.insert(stream.end(), r1.begin(), r1.end());
  Serial5dtParser p(/*wireless=*/true);
  std::vector<GloveRaw> got;
  GloveRaw raw;
  for (auto b : stream)
    if (p.push(b, raw)) got.push_back(raw);
  ASSERT_EQ(got.size(), 3u);
  EXPECT_DOUBLE_EQ(got[0].sensors[0], 1 / 255.0);
  EXPECT_DOUBLE_EQ(got[1].sensors[0], 9 / 255.0);
  EXPECT_DOUBLE_EQ(got[2].sensors[4], 5 / 255.0);
  EXPECT_GE(p.bad_reports(), 1u);
}

// The reply to 'G' as vrpn_Analog_5dt.C decodes it.
TEST(Glove, SerialInfoReply) {
  std::vector<std::uint8_t> reply(32, 0);
  reply[0] = 'B';
  reply[1] = 'R';
  reply[2] = 2;
  reply[3] = 1;
  reply[4] = 0x01;  // right hand
  reply[5] = 0x10;  // pitch and roll fitted
  const std::string name = "DG5 right";
  std::copy(name.begin(), name.end(), reply.begin() + 16);
  Serial5dtInfo info;
  ASSERT_EQ(parse_5dt_serial_info(reply, info), nullptr);
  EXPECT_EQ(info.version_major, 2);
  EXPECT_EQ(info.version_minor, 1);
  EXPECT_TRUE(info.right_hand);
  EXPECT_TRUE(info.pitch_roll);
  EXPECT_EQ(info.name, "DG5 right");
  reply[4] = 0;
  reply[5] = 0;
  ASSERT_EQ(parse_5dt_serial_info(reply, info), nullptr);
  EXPECT_FALSE(info.right_hand);
  EXPECT_FALSE(info.pitch_roll);
  reply[1] = 'X';
  EXPECT_NE(parse_5dt_serial_info(reply, info), nullptr);
  EXPECT_NE(parse_5dt_serial_info(std::span(reply.data(), 31), info), nullptr);
}

TEST(Glove, CalibrationMapsToBends) {
  GloveCalibration cal = GloveCalibration::empty(5);
  GloveRaw open, fist;
  open.sensor_count = fist.sensor_count = 5;
  for (int i = 0; i < 5; ++i) {
    open.sensors[i] = 0.2 + 0.01 * i;
    fist.sensors[i] = 0.7 + 0.02 * i;
  }
  cal.observe(open);
  cal.observe(fist);
  GloveRaw mid = open;
  for (int i = 0; i < 5; ++i) mid.sensors[i] = 0.5 * (open.sensors[i] + fist.sensors[i]);
  const auto b_open = finger_bends(open, cal);
  const auto b_fist = finger_bends(fist, cal);
  const auto b_mid = finger_bends(mid, cal);
  for (int i = 0; i < 5; ++i) {
    EXPECT_DOUBLE_EQ(b_open[i], 0.0);
    EXPECT_DOUBLE_EQ(b_fist[i], 1.0);
    EXPECT_NEAR(b_mid[i], 0.5, 1e-12);
  }
  GloveRaw beyond = fist;
  beyond.sensors[2] = 5.0;
  EXPECT_DOUBLE_EQ(finger_bends(beyond, cal)[2], 1.0);  // clamped

  // 14 sensors: near and far knuckle sensors average; abduction sensors (2, 5, ...) ignored.
  GloveRaw r14;
  r14.sensor_count = 14;
  r14.sensors[3] = 1.0;  // index near
  r14.sensors[4] = 0.0;  // index far
  r14.sensors[5] = 1.0;  // index/middle abduction
  const auto b14 = finger_bends(r14, GloveCalibration::full_range(14));
  EXPECT_DOUBLE_EQ(b14[1], 0.5);
  EXPECT_DOUBLE_EQ(b14[2], 0.0);

  // Per joint: the near sensor bends the MCP, the far one the PIP and (coupled) the DIP.
  r14.sensors[9] = 0.25;   // ring near
  r14.sensors[10] = 0.75;  // ring far
  const JointBends j14 = joint_bends(r14, GloveCalibration::full_range(14));
  EXPECT_EQ(j14[1], (std::array<double, 3>{1.0, 0.0, 0.0}));
  EXPECT_EQ(j14[3], (std::array<double, 3>{0.25, 0.75, 0.75}));
  EXPECT_EQ(j14[2], (std::array<double, 3>{0.0, 0.0, 0.0}));  // abduction ignored
  // Five sensors: one bend for all three joints, the same as finger_bends.
  const JointBends j5 = joint_bends(mid, cal);
  for (std::size_t f = 0; f < 5; ++f)
    for (double b : j5[f]) EXPECT_DOUBLE_EQ(b, finger_bends(mid, cal)[f]);
}

TEST(Glove, CalibrationFileRoundTripAndErrors) {
  const auto dir = ::telex::test::scratch_dir("glove");
  std::filesystem::create_directories(dir);
  GloveCalibration c = GloveCalibration::full_range(5);
  c.min[1] = 0.1;
  c.max[1] = 0.9;
  c.save(dir / "cal.json");
  const auto back = GloveCalibration::load(dir / "cal.json", 5);
  EXPECT_DOUBLE_EQ(back.min[1], 0.1);
  EXPECT_DOUBLE_EQ(back.max[1], 0.9);
  EXPECT_THROW(GloveCalibration::load(dir / "cal.json", 14), std::runtime_error);
  std::ofstream(dir / "bad.json") << R"({"min":[0,0,0,0,0],"max":[1,1,0,1,1]})";
  try {
    GloveCalibration::load(dir / "bad.json", 5);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("sensor 2 has max <= min"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos);
  }
  std::ofstream(dir / "notjson.json") << "min: 0";
  EXPECT_THROW(GloveCalibration::load(dir / "notjson.json", 5), std::runtime_error);
  std::filesystem::remove_all(dir);
}

std::string open_error(const std::string& spec) {
  try {
    open_glove(spec, "");
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(Glove, MissingDevicesNameThemselvesAndSayWhatToTry) {
  const std::string usb = open_error("5dt-usb:/dev/hidraw-telex-missing");
  EXPECT_NE(usb.find("/dev/hidraw-telex-missing"), std::string::npos) << usb;
  EXPECT_NE(usb.find("udev"), std::string::npos) << usb;
  const std::string any = open_error("5dt-usb");
  EXPECT_NE(any.find("0x5D70"), std::string::npos) << any;
  const std::string serial = open_error("5dt-serial:/dev/ttyTELEXMISSING");
  EXPECT_NE(serial.find("/dev/ttyTELEXMISSING"), std::string::npos) << serial;
  EXPECT_NE(serial.find("dialout"), std::string::npos) << serial;
  const std::string not_tty = open_error("5dt-serial:/dev/null");
  EXPECT_NE(not_tty.find("not a serial port"), std::string::npos) << not_tty;
  EXPECT_THROW(open_glove("5dt-bluetooth", ""), std::invalid_argument);
  // The tracker factory passes the device's message through.
  TrackerConfig cfg;
  try {
    make_tracker("5dt-usb:/dev/hidraw-telex-missing", cfg);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/hidraw-telex-missing"), std::string::npos);
  }
}

}  // namespace
}  // namespace telex::local
