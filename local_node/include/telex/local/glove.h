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

#include "telex/base/triple_buffer.h"

namespace telex::local {

inline constexpr std::uint16_t k5dtVendorId = 0x5D70;
inline constexpr std::size_t k5dtUsbReportBytes = 64;
inline constexpr std::size_t k5dtSerialReportBytes = 9;
inline constexpr std::uint8_t k5dtSerialHeader = 0x80;

enum class GloveModel { Sensors14, Sensors5Right, Sensors5Left, Serial5 };

// 0x00-0x07: 14-sensor Ultra; 0x10 / 0x11: 5-sensor right / left. Other ids: not a 5DT glove.
std::optional<GloveModel> glove_model_from_product_id(std::uint16_t product_id);
int sensor_count(GloveModel model);

struct GloveRaw {
  int sensor_count = 0;
  std::array<double, 14> sensors{};  // USB: int16 / 4096; serial: byte / 255
  double pitch = 0, roll = 0;        // serial only: byte / 255
};

// One 64-byte HID input report: 16 big-endian int16; the 5-sensor glove reports its sensors at
// indices 0, 3, 6, 9, 12. Returns nullptr or the reason the report was rejected.
const char* parse_5dt_usb_report(std::span<const std::uint8_t> report, GloveModel model,
                                 GloveRaw& out);

// Checksum of a serial report: low byte of the sum of the 7 data bytes (thumb .. roll).
std::uint8_t serial_5dt_checksum(std::span<const std::uint8_t, 7> data);

// Incremental parser for the serial stream: 0x80, thumb, index, middle, ring, little, pitch, roll,
// checksum. Resynchronises on the next 0x80 after a bad checksum. Pure (no I/O).
class Serial5dtParser {
 public:
  // Feeds one byte; true and `out` filled when it completes a valid report.
  bool push(std::uint8_t byte, GloveRaw& out);
  std::uint64_t bad_checksums() const { return bad_checksums_; }
  std::uint64_t skipped_bytes() const { return skipped_; }

 private:
  std::array<std::uint8_t, k5dtSerialReportBytes> buf_{};
  std::size_t have_ = 0;
  std::uint64_t bad_checksums_ = 0, skipped_ = 0;
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
  void save(const std::filesystem::path& path) const;
  // Auto-calibration: start from an empty range and widen it while the user opens and closes.
  static GloveCalibration empty(int sensor_count);
  void observe(const GloveRaw& raw);
};

// Sensor values -> finger bends 0 (straight) .. 1 (fist), thumb first. The 14-sensor glove's bend
// is the mean of a finger's near and far knuckle sensors; abduction sensors are not used.
std::array<double, 5> finger_bends(const GloveRaw& raw, const GloveCalibration& cal);

struct GloveSample {
  std::array<double, 5> bend{};
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

 protected:
  void publish(const GloveRaw& raw);
  GloveCalibration calibration_;
  TripleBuffer<GloveSample> samples_;
  std::atomic<std::uint64_t> reports_{0}, bad_reports_{0}, read_errors_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// "5dt-usb[:HIDPATH]" (first glove with vendor 0x5D70 when no path) or "5dt-serial:DEV".
// Throws std::invalid_argument for a malformed spec and std::runtime_error naming the device and
// what to try when it cannot be opened. Empty calibration path = full sensor range.
std::unique_ptr<GloveDevice> open_glove(const std::string& spec,
                                        const std::string& calibration_path);

}  // namespace telex::local
