// SPDX-License-Identifier: MIT
// The operator's dead-man input (--deadman): a key or foot pedal that must be held for the robot
// head to move. Its state travels in every HeadCommand (docs/PROTOCOL.md 2.6); the parsing of
// what a device sends is pure, apart from the devices.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "telex/proto/messages.h"

namespace telex::local {

inline constexpr std::string_view kDeadmanSpecForms =
    "evdev:/dev/input/eventN[,key=KEY_SPACE] | hid:VID:PID[,byte=N][,mask=M]";

// A parsed --deadman spec.
struct DeadmanSpec {
  enum class Kind { Evdev, Hid };
  Kind kind = Kind::Evdev;
  // evdev: a Linux input device (a keyboard, or a foot pedal, which shows as one) and the key
  // (or button) code that must be held; KEY_SPACE by default.
  std::string path;
  std::uint16_t key = 57;  // KEY_SPACE
  // hid: the device's USB ids; the input report's byte `byte` (0 = the first byte hidapi returns,
  // the report id on devices that number their reports) and the bits `mask` of it that read
  // non-zero while the pedal is held.
  std::uint16_t vendor_id = 0, product_id = 0;
  std::size_t byte = 0;
  std::uint8_t mask = 0x01;
};

// Throws std::invalid_argument naming the spec, the part that is wrong and the valid forms.
DeadmanSpec parse_deadman_spec(std::string_view spec);

// A key name as linux/input-event-codes.h spells it (KEY_SPACE, KEY_ENTER, KEY_LEFTCTRL, BTN_LEFT,
// KEY_A .. KEY_Z, KEY_F1 .. KEY_F12, BTN_0 ...) or a number; nullopt for an unknown name.
std::optional<std::uint16_t> evdev_key_code(std::string_view name);

// evdev's `struct input_event` records (linux/input.h; 24 bytes on 64-bit Linux: a timeval, u16
// type, u16 code, s32 value) read from an event device, in any split, to one key's state: an
// EV_KEY record of that code with value 1 (press) or 2 (autorepeat) holds it, 0 releases it.
// Pure: bytes in, state out.
class EvdevKeyDecoder {
 public:
  EvdevKeyDecoder(std::uint16_t key, bool pressed) : key_(key), pressed_(pressed) {}
  void feed(std::span<const std::uint8_t> bytes);
  bool pressed() const { return pressed_; }
  std::uint64_t records() const { return records_; }          // whole records taken
  std::uint64_t key_records() const { return key_records_; }  // ... of this key

 private:
  std::uint16_t key_;
  bool pressed_;
  std::array<std::uint8_t, 24> partial_{};  // a record split across reads
  std::size_t have_ = 0;
  std::uint64_t records_ = 0, key_records_ = 0;
};
inline constexpr std::size_t kInputEventBytes = 24;

// A HID input report to the pedal's state: pressed when byte `byte` has a bit of `mask` set;
// nullopt when the report is too short to hold that byte (a different report: not counted).
std::optional<bool> hid_report_pressed(std::span<const std::uint8_t> report, std::size_t byte,
                                       std::uint8_t mask);

struct DeadmanStats {
  std::uint64_t polls = 0;
  std::uint64_t changes = 0;  // pressed <-> released
  std::uint64_t errors = 0;   // failed reads (the device unplugged): released from then on
  std::string last_error;
};

// An open dead-man device, read without blocking from the station's main loop.
class DeadmanInput {
 public:
  virtual ~DeadmanInput() = default;
  // Pressed or Released, reading what the device sent since the last call. Never throws, never
  // blocks; a device that fails (unplugged) reads as Released from then on (fail-safe).
  virtual proto::DeadmanState poll() = 0;
  virtual std::string name() const = 0;
  virtual DeadmanStats stats() const = 0;
};

// Opens the device of a spec and reads its current state. Throws std::runtime_error naming the
// device and what to try (a missing path, the input group, a device without that key, no HID
// device with those ids).
std::unique_ptr<DeadmanInput> open_deadman(const DeadmanSpec& spec);

}  // namespace telex::local
