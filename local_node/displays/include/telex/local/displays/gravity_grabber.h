// SPDX-License-Identifier: MIT
// Gravity Grabber: fingertip pressure/shear -> two belt motors per finger -> HID output report.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "telex/local/displays/haptic_display.h"
#include "telex/local/displays/hid.h"

namespace telex::local {

inline constexpr std::size_t kGravityGrabberReportBytes = 32;

struct GravityGrabberFinger {
  bool enabled = true;       // finger has a unit mounted
  double gain_pressure = 1;  // scales the normalised pressure command
  double gain_shear = 1;
  int motor_a_sign = 1;  // mounting direction of each motor (+1 / -1)
  int motor_b_sign = 1;
  double dead_zone = 0.0;  // fraction of full command a motor needs before it turns
};

// Calibration and limits (JSON, docs/HARDWARE.md).
struct GravityGrabberConfig {
  double max_pressure_N = 3.0;  // pressure that maps to a full command
  double max_shear_N = 1.5;
  double max_command = 0.8;  // motor limit, fraction of full scale
  std::uint8_t report_id = 0x01;
  std::array<GravityGrabberFinger, 5> fingers{};

  // Missing keys keep their defaults; unknown keys and out-of-range values throw
  // std::runtime_error naming the file and the key.
  static GravityGrabberConfig load(const std::filesystem::path& path);
  // The same keys from a JSON object (the rig's gravity_grabber); errors start with `where`.
  static GravityGrabberConfig from_json(const nlohmann::json& j, const std::string& where);
};

// Motor commands in [-1, 1], finger-major: {A0, B0, A1, B1, ...}. Motors turning opposite ways
// tighten the belt (pressure), the same way move it (shear): A = s + p, B = s - p before the
// mounting signs. When one motor would exceed max_command both are scaled together so the
// pressure/shear mix is kept.
std::array<double, 10> gravity_grabber_motors(std::span<const FingerForce> forces,
                                              const GravityGrabberConfig& config);

// The output report (docs/HARDWARE.md): id, sequence, contact flags, 10 int16 LE motor commands
// (x 32767), checksum of bytes 1..22, zero padding to 32 bytes.
std::array<std::uint8_t, kGravityGrabberReportBytes> gravity_grabber_report(
    std::span<const FingerForce> forces, const GravityGrabberConfig& config, std::uint8_t sequence);

// Which HID device the display spec names: a hidraw path ("/dev/hidraw3"), or the controller's
// USB ids "VID:PID" in hex, optionally ":SERIAL" (e.g. "16c0:05df:GG-0042"), found by hidapi's
// enumeration, so the display is found whatever hidraw number it got.
struct HidTarget {
  std::string path;  // set for a path
  std::uint16_t vendor_id = 0, product_id = 0;
  std::string serial;  // empty: any
  bool by_ids() const { return path.empty(); }
};
// Throws std::invalid_argument naming the text and the two accepted forms.
HidTarget parse_hid_target(std::string_view text);

// The path of the first candidate matching `target` (ids and, when given, serial); nullopt when
// none does. Pure, so the choice is tested on recorded enumerations.
std::optional<std::string> choose_hid_device(const HidTarget& target,
                                             std::span<const HidCandidate> candidates);

using GravityGrabberReport = std::array<std::uint8_t, kGravityGrabberReportBytes>;

// The keep-alive and watchdog contract (docs/HARDWARE.md, "Keep-alive and watchdog"): the host
// sends a report at least every keep-alive period, even when it is unchanged; the firmware turns
// every motor off when no valid report has arrived for its watchdog time. The host re-sends a
// report only while the haptic thread wrote it less than `hold` ago, so a station whose haptic loop
// hangs releases the belts itself instead of feeding the watchdog with a stale force.
struct GravityGrabberTiming {
  std::int64_t keepalive_period_ns = 50'000'000;
  std::int64_t hold_ns = 200'000'000;
};
inline constexpr std::int64_t kGravityGrabberWatchdogNs = 200'000'000;  // the firmware's

// The writer thread's choice of what to send, pure, with the time passed in.
class GravityGrabberKeepAlive {
 public:
  GravityGrabberKeepAlive(const GravityGrabberConfig& config, GravityGrabberTiming timing)
      : config_(config), timing_(timing) {}
  // The haptic thread wrote `report` (taken at now_ns): send it.
  const GravityGrabberReport& fresh(std::int64_t now_ns, const GravityGrabberReport& report);
  // Nothing new: the report to send now, or nullptr. The last report again once a keep-alive
  // period has passed since the last send, while it is younger than `hold`; after that the
  // motors-off report once, and then nothing until a fresh report.
  const GravityGrabberReport* idle(std::int64_t now_ns);

 private:
  GravityGrabberConfig config_;
  GravityGrabberTiming timing_;
  GravityGrabberReport last_{};
  std::int64_t written_ns_ = 0, sent_ns_ = 0;
  bool holding_ = false;  // a report is being kept alive
};

// Where the reports go: the device through hidapi, or a test's recorder.
class HidReportWriter {
 public:
  virtual ~HidReportWriter();
  // The bytes written, or < 0 on error. Called from the display's writer thread only.
  virtual int write(std::span<const std::uint8_t> report) = 0;
  virtual std::string name() const = 0;  // for the display's name: the hidraw path
};

// The display over any writer: write() encodes and hands the report to a writer thread (newest
// wins), which sends it and keeps it alive (GravityGrabberTiming); closing sends motors off.
std::unique_ptr<HapticDisplay> make_gravity_grabber_display(std::unique_ptr<HidReportWriter> writer,
                                                            const GravityGrabberConfig& config,
                                                            GravityGrabberTiming timing = {});

// Opens the display `target` names (parse_hid_target) through hidapi, with the calibration in
// `config_path`, else the rig's object `rig_config` (null = defaults). Reports go out on a writer
// thread so write() never waits on USB. Throws std::runtime_error naming the path or the ids, what
// was found, and what to try.
std::unique_ptr<HapticDisplay> open_gravity_grabber(const std::string& target,
                                                    const std::string& config_path,
                                                    const nlohmann::json& rig_config = nullptr);

// What the display supervisor (display_supervisor.h) holds for a Gravity Grabber: its own handle
// on the same hidraw node, opened before the station forks it, and the motors-off report.
struct GravityGrabberZero {
  std::string path;  // the hidraw node
  int fd = -1;       // open for writing; the caller owns it
  GravityGrabberReport report{};
};
// Resolves `target` and loads the calibration as open_gravity_grabber does, with its errors.
GravityGrabberZero open_gravity_grabber_zero(const std::string& target,
                                             const std::string& config_path,
                                             const nlohmann::json& rig_config = nullptr);

}  // namespace telex::local
