// SPDX-License-Identifier: MIT
// 5DT data gloves: pure report parsers (USB HID, serial), calibration to finger bends, devices.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <thread>

#include "telex/base/thread_fault.h"
#include "telex/base/triple_buffer.h"
#include "telex/common/rig.h"
#include "telex/haptics/hand_kinematics.h"

namespace telex::local {

// The 5DT formats, from VRPN (github.com/vrpn/vrpn), the public driver that reads these gloves:
// vrpn_Analog_5dtUSB.C for the USB HID gloves (Data Glove 5 Ultra, 14 Ultra, their wireless kit)
// and vrpn_Analog_5dt.C for the serial Data Glove 5 / 5-W. docs/HARDWARE.md cites each line.
inline constexpr std::uint16_t k5dtVendorId = 0x5D70;
inline constexpr std::size_t k5dtUsbReportBytes = 64;
inline constexpr std::size_t k5dtSerialReportBytes = 9;     // wired (19200 baud)
inline constexpr std::size_t k5dtWirelessReportBytes = 10;  // wireless (9600): + capability
inline constexpr std::uint8_t k5dtSerialHeader = 0x80;

enum class GloveModel { Sensors14, Sensors5Right, Sensors5Left, Serial5 };

// One USB product of 5DT's vendor id. VRPN's product-id bits: 0x01 left hand, 0x10 five sensors
// (else fourteen), 0x02 / 0x06 the wireless kit's port A / B (else wired).
struct GloveProduct {
  std::uint16_t product_id;
  GloveModel model;
  bool left_hand;
  const char* link;  // "wired USB", "wireless port A", "wireless port B"
};
// Every product VRPN lists, in one table a lab can extend (local_node/inputs/src/glove.cpp).
std::span<const GloveProduct> glove_products();
// The table's row for `product_id`, or nullptr: not a 5DT glove this project reads.
const GloveProduct* glove_product(std::uint16_t product_id);
std::optional<GloveModel> glove_model_from_product_id(std::uint16_t product_id);
int sensor_count(GloveModel model);

struct GloveRaw {
  int sensor_count = 0;
  std::array<double, 14> sensors{};    // USB: int16 / 4096; serial: byte / 255
  double pitch_deg = 0, roll_deg = 0;  // serial only: 180 * byte / 255 (VRPN's scale)
};

// One 64-byte HID input report: 16 big-endian int16 / 4096; the 5-sensor glove reports its
// sensors at indices 0, 3, 6, 9, 12. Returns nullptr or the reason the report was rejected.
const char* parse_5dt_usb_report(std::span<const std::uint8_t> report, GloveModel model,
                                 GloveRaw& out);

// The byte after the seven data bytes: the low byte of their sum, as this project has assumed.
// VRPN does not check it, so a report is never rejected for it; disagreements are counted.
std::uint8_t serial_5dt_checksum(std::span<const std::uint8_t, 7> data);

// The reply to the glove's 'G' (get info) command: 32 bytes starting "BR", version at 2..3, bit 0
// of byte 4 set for a right hand, bit 4 of byte 5 set when pitch and roll are fitted, the name
// from byte 16 (vrpn_Analog_5dt.C, reset()).
struct Serial5dtInfo {
  int version_major = 0, version_minor = 0;
  bool right_hand = true, pitch_roll = false;
  std::string name;
};
// Returns nullptr or why the bytes are not an info reply.
const char* parse_5dt_serial_info(std::span<const std::uint8_t> reply, Serial5dtInfo& out);

// Incremental parser for the serial stream: 0x80, thumb, index, middle, ring, little, pitch, roll,
// checksum, and for the wireless glove a capability byte 0x40 or 0x01 (0x01: right hand). A report
// that does not start with 0x80, or a wireless one not ending in a capability byte, is skipped up
// to the next 0x80. Pure (no I/O).
class Serial5dtParser {
 public:
  explicit Serial5dtParser(bool wireless = false) : wireless_(wireless) {}
  // Feeds one byte; true and `out` filled when it completes a report.
  bool push(std::uint8_t byte, GloveRaw& out);
  std::uint64_t checksum_mismatches() const { return checksum_mismatches_; }
  std::uint64_t bad_reports() const { return bad_reports_; }
  std::uint64_t skipped_bytes() const { return skipped_; }

 private:
  bool wireless_ = false;
  std::array<std::uint8_t, k5dtWirelessReportBytes> buf_{};
  std::size_t have_ = 0;
  std::uint64_t checksum_mismatches_ = 0, bad_reports_ = 0, skipped_ = 0;
};

// Per-sensor range seen with the hand open (min) and closed (max).
struct GloveCalibration {
  std::array<double, 14> min{};
  std::array<double, 14> max{};
  int sensor_count = 0;

  static GloveCalibration full_range(int sensor_count);  // 0 .. 1
  // JSON {"min": [...], "max": [...]} with sensor_count entries each; throws std::runtime_error
  // naming the file and the problem.
  static GloveCalibration load(const std::filesystem::path& path, int sensor_count);
  // The rig's range (operator.gloves.SIDE); throws std::runtime_error naming `where` when it does
  // not hold sensor_count sensors.
  static GloveCalibration from_range(const GloveRange& range, int sensor_count,
                                     const std::string& where);
  void save(const std::filesystem::path& path) const;
  // Auto-calibration: start from an empty range and widen it while the user opens and closes.
  static GloveCalibration empty(int sensor_count);
  void observe(const GloveRaw& raw);
};

// Sensor values -> finger bends 0 (straight) .. 1 (fist), thumb first. The 14-sensor glove's bend
// is the mean of a finger's near and far knuckle sensors; abduction sensors are not used.
std::array<double, 5> finger_bends(const GloveRaw& raw, const GloveCalibration& cal);

// Sensor values -> each joint's bend, thumb first: the 14-sensor glove's near-knuckle sensor bends
// the MCP joint and its far-knuckle sensor the PIP joint, and the DIP joint follows the PIP (the
// glove has no DIP sensor; the joints are coupled in a real finger); a 5-sensor glove's one sensor
// per finger bends all three.
JointBends joint_bends(const GloveRaw& raw, const GloveCalibration& cal);

struct GloveSample {
  std::array<double, 5> bend{};
  JointBends joints{};  // joint_bends() of the same report
  std::int64_t received_ns = 0;
};

// A glove read on its own thread; latest() never blocks.
class GloveDevice {
 public:
  virtual ~GloveDevice();
  bool latest(GloveSample& out) { return samples_.take(out); }
  virtual std::string name() const = 0;
  std::uint64_t reports() const { return reports_; }
  std::uint64_t bad_reports() const { return bad_reports_; }
  std::uint64_t read_errors() const { return read_errors_; }
  std::uint64_t overwritten() const { return samples_.overwritten(); }
  // The reading thread's fault, named with the glove (empty while it runs).
  std::optional<ThreadFaultReport> thread_fault() const;
  std::uint64_t thread_faults() const { return fault_.count(); }

 protected:
  void publish(const GloveRaw& raw);
  ThreadFault fault_{"glove"};  // the reading thread runs through it
  GloveCalibration calibration_;
  TripleBuffer<GloveSample> samples_;
  std::atomic<std::uint64_t> reports_{0}, bad_reports_{0}, read_errors_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// "5dt-usb[:HIDPATH]" (first glove with vendor 0x5D70 when no path), "5dt-serial:DEV" (the wired
// Data Glove 5: 19200 baud, reset 'A', info 'G', stream 'D') or "5dt-serial:DEV,wireless" (the
// send-only 5-W: 9600 baud, 10-byte reports).
// Throws std::invalid_argument for a malformed spec and std::runtime_error naming the device and
// what to try when it cannot be opened. The calibration: the file at calibration_path, else the
// rig's range, else the full sensor range.
std::unique_ptr<GloveDevice> open_glove(const std::string& spec,
                                        const std::string& calibration_path,
                                        const std::optional<GloveRange>& range = std::nullopt);

// open_glove's spec grammar alone, before anything starts (no device is opened): throws
// std::invalid_argument as open_glove would.
void check_glove_spec(const std::string& spec);

}  // namespace telex::local
