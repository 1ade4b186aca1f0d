// SPDX-License-Identifier: MIT
// --deadman: the spec, evdev's input_event records and HID reports to a pressed state (recorded
// bytes, split at every boundary), and the open path's errors, which name the device and what to
// try. No device is needed: none exists where these tests run.
#include "telex/local/inputs/deadman.h"

#include <gtest/gtest.h>
#include <linux/input.h>

#include <cstring>
#include <fstream>
#include <vector>

#include "process.h"
#include "test_support.h"

namespace telex::local {
namespace {

using ::telex::test::expect_contains;
using ::telex::test::message_of;

TEST(DeadmanSpec, EvdevAndHidForms) {
  DeadmanSpec s = parse_deadman_spec("evdev:/dev/input/event3");
  EXPECT_EQ(s.kind, DeadmanSpec::Kind::Evdev);
  EXPECT_EQ(s.path, "/dev/input/event3");
  EXPECT_EQ(s.key, KEY_SPACE);
  s = parse_deadman_spec("evdev:/dev/input/by-id/usb-pedal-event-kbd,key=KEY_B");
  EXPECT_EQ(s.path, "/dev/input/by-id/usb-pedal-event-kbd");
  EXPECT_EQ(s.key, KEY_B);
  EXPECT_EQ(parse_deadman_spec("evdev:/dev/input/event0,key=BTN_LEFT").key, BTN_LEFT);
  EXPECT_EQ(parse_deadman_spec("evdev:/dev/input/event0,key=30").key, 30);
  EXPECT_EQ(parse_deadman_spec("evdev:/dev/input/event0,key=0x110").key, BTN_LEFT);
  s = parse_deadman_spec("hid:0c45:7403");
  EXPECT_EQ(s.kind, DeadmanSpec::Kind::Hid);
  EXPECT_EQ(s.vendor_id, 0x0c45);
  EXPECT_EQ(s.product_id, 0x7403);
  EXPECT_EQ(s.byte, 0u);
  EXPECT_EQ(s.mask, 0x01);
  s = parse_deadman_spec("hid:3553:b001,byte=2,mask=0x0c");
  EXPECT_EQ(s.byte, 2u);
  EXPECT_EQ(s.mask, 0x0c);
  EXPECT_EQ(parse_deadman_spec("hid:3553:b001,mask=4").mask, 4);
}

TEST(DeadmanSpec, BadFormsNameThePartAndTheValidForms) {
  const std::pair<const char*, const char*> cases[] = {
      {"pedal", "no device"},
      {"joystick:/dev/input/js0", "unknown kind 'joystick'"},
      {"evdev:", "evdev needs the device's path"},
      {"evdev:event3", "evdev needs the device's path"},
      {"evdev:/dev/input/event3,key=KEY_NOPE", "unknown key 'KEY_NOPE'"},
      {"evdev:/dev/input/event3,key=0", "unknown key '0'"},
      {"evdev:/dev/input/event3,key=KEY_A,key=KEY_B", "key= is given twice"},
      {"evdev:/dev/input/event3,repeat=1", "unknown evdev option 'repeat=1'"},
      {"hid:0c45", "hid needs the USB ids VID:PID in hex"},
      {"hid:0c45:zz", "hid needs the USB ids VID:PID in hex"},
      {"hid:10c45:7403", "hid needs the USB ids VID:PID in hex"},
      {"hid:0c45:7403,byte=64", "byte '64' is not a report byte 0..63"},
      {"hid:0c45:7403,mask=0", "mask '0' is not a bit mask"},
      {"hid:0c45:7403,mask=0x100", "mask '0x100' is not a bit mask"},
      {"hid:0c45:7403,byte=1,byte=2", "unknown or repeated hid option 'byte=2'"},
  };
  for (const auto& [spec, part] : cases) {
    const std::string m = message_of([&] { parse_deadman_spec(spec); });
    EXPECT_THROW(parse_deadman_spec(spec), std::invalid_argument) << spec;
    expect_contains(m, std::string("--deadman '") + spec + "'");
    expect_contains(m, part);
    expect_contains(m, std::string(kDeadmanSpecForms));
  }
}

// What a USB keyboard's event device gives for one tap of the space bar, held long enough to
// autorepeat: MSC_SCAN, the key, SYN_REPORT per change (as `evtest` shows it). Little-endian
// struct input_event: tv_sec, tv_usec (8 bytes each), type, code (2), value (4).
std::vector<std::uint8_t> record(std::int64_t sec, std::int64_t usec, std::uint16_t type,
                                 std::uint16_t code, std::int32_t value) {
  input_event e{};
  e.input_event_sec = sec;
  e.input_event_usec = usec;
  e.type = type;
  e.code = code;
  e.value = value;
  std::vector<std::uint8_t> out(sizeof e);
  std::memcpy(out.data(), &e, sizeof e);
  return out;
}

std::vector<std::uint8_t> space_tap() {
  std::vector<std::uint8_t> bytes;
  const auto add = [&](std::vector<std::uint8_t> r) {
    bytes.insert(bytes.end(), r.begin(), r.end());
  };
  add(record(1764150000, 100000, EV_MSC, MSC_SCAN, 0x7002c));
  add(record(1764150000, 100000, EV_KEY, KEY_SPACE, 1));
  add(record(1764150000, 100000, EV_SYN, SYN_REPORT, 0));
  add(record(1764150000, 600000, EV_KEY, KEY_SPACE, 2));  // autorepeat: still held
  add(record(1764150000, 600000, EV_SYN, SYN_REPORT, 0));
  add(record(1764150000, 633000, EV_KEY, KEY_A, 1));  // another key: not the dead-man
  add(record(1764150000, 633000, EV_SYN, SYN_REPORT, 0));
  add(record(1764150001, 200000, EV_MSC, MSC_SCAN, 0x7002c));
  add(record(1764150001, 200000, EV_KEY, KEY_SPACE, 0));
  add(record(1764150001, 200000, EV_SYN, SYN_REPORT, 0));
  return bytes;
}

TEST(DeadmanEvdev, RecordsOfAKeyTapPressHoldAndRelease) {
  const std::vector<std::uint8_t> bytes = space_tap();
  ASSERT_EQ(bytes.size(), 10 * kInputEventBytes);
  // The layout this reads, byte by byte, for the press (record 1): type 1 (EV_KEY), code 57
  // (KEY_SPACE), value 1 after the 16-byte timeval.
  const std::uint8_t press_tail[] = {0x01, 0x00, 0x39, 0x00, 0x01, 0x00, 0x00, 0x00};
  EXPECT_EQ(std::memcmp(bytes.data() + kInputEventBytes + 16, press_tail, 8), 0);
  // The state after each record, fed whole.
  const bool after[] = {false, true, true, true, true, true, true, true, false, false};
  EvdevKeyDecoder d(KEY_SPACE, false);
  for (std::size_t i = 0; i < 10; ++i) {
    d.feed(std::span(bytes).subspan(i * kInputEventBytes, kInputEventBytes));
    EXPECT_EQ(d.pressed(), after[i]) << "after record " << i;
  }
  EXPECT_EQ(d.records(), 10u);
  EXPECT_EQ(d.key_records(), 3u);
  // The same bytes split at every boundary, as reads may deliver them: the same states.
  for (std::size_t cut = 1; cut < bytes.size(); ++cut) {
    EvdevKeyDecoder s(KEY_SPACE, false);
    s.feed(std::span(bytes).first(cut));
    EXPECT_EQ(s.pressed(), cut >= 2 * kInputEventBytes && cut < 9 * kInputEventBytes)
        << "cut " << cut;
    s.feed(std::span(bytes).subspan(cut));
    EXPECT_FALSE(s.pressed()) << "cut " << cut;
    EXPECT_EQ(s.records(), 10u) << "cut " << cut;
  }
  // Another key's decoder sees only its own: KEY_A pressed and never released here.
  EvdevKeyDecoder a(KEY_A, false);
  a.feed(bytes);
  EXPECT_TRUE(a.pressed());
  EXPECT_EQ(a.key_records(), 1u);
  // A key held when the device was opened (EVIOCGKEY) stays held until its release record.
  EvdevKeyDecoder held(KEY_SPACE, true);
  held.feed(std::span(bytes).subspan(7 * kInputEventBytes));
  EXPECT_FALSE(held.pressed());
}

TEST(DeadmanHid, AReportsBitsAreThePedal) {
  // A 3-pedal USB foot switch's 8-byte reports: byte 2 holds one bit per pedal.
  const std::uint8_t idle[] = {0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00};
  const std::uint8_t middle[] = {0x01, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00};
  const std::uint8_t left_and_right[] = {0x01, 0x00, 0x05, 0x00, 0x00, 0x00, 0x00, 0x00};
  EXPECT_EQ(hid_report_pressed(idle, 2, 0x02), false);
  EXPECT_EQ(hid_report_pressed(middle, 2, 0x02), true);
  EXPECT_EQ(hid_report_pressed(left_and_right, 2, 0x02), false);
  EXPECT_EQ(hid_report_pressed(left_and_right, 2, 0x04), true);
  EXPECT_EQ(hid_report_pressed(left_and_right, 2, 0x05), true);
  // A report too short for the byte is another report, not a release.
  EXPECT_EQ(hid_report_pressed(std::span(middle, 2), 2, 0x02), std::nullopt);
}

TEST(DeadmanOpen, AMissingOrWrongDeviceIsNamedWithWhatToTry) {
  const std::string missing = "/dev/input/event-telex-deadman-missing";
  std::string m = message_of([&] { open_deadman(parse_deadman_spec("evdev:" + missing)); });
  expect_contains(m, "--deadman evdev:" + missing);
  expect_contains(m, "No such file or directory");
  expect_contains(m, "ls -l /dev/input/by-id/");
  // Something that is not an event device: its ioctls fail.
  const auto dir = test::scratch_dir("deadman_open");
  const auto file = dir / "event-not-a-device";
  std::ofstream(file) << "not a device";
  m = message_of([&] { open_deadman(parse_deadman_spec("evdev:" + file.string())); });
  expect_contains(m, "--deadman evdev:" + file.string() + ": not an input event device");
  m = message_of([] { open_deadman(parse_deadman_spec("evdev:/dev/null")); });
  expect_contains(m, "/dev/null: not an input event device");
  // A HID pedal that is not there: named by its ids, with lsusb to check.
  m = message_of([] { open_deadman(parse_deadman_spec("hid:fffe:fffd")); });
  expect_contains(m, "--deadman hid:fffe:fffd");
  expect_contains(m, "lsusb -d fffe:fffd");
  EXPECT_THROW(open_deadman(parse_deadman_spec("evdev:" + missing)), std::runtime_error);
}

}  // namespace
}  // namespace telex::local
