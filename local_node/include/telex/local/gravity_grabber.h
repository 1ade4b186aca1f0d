// SPDX-License-Identifier: MIT
// Gravity Grabber: fingertip pressure/shear -> two belt motors per finger -> HID output report.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>

#include "telex/local/haptic_display.h"

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

// Opens the HID device at `hid_path` (hidapi) with the calibration in `config_path` (empty =
// defaults). Reports go out on a writer thread so write() never waits on USB. Throws
// std::runtime_error naming the path and what to try when the device cannot be opened.
std::unique_ptr<HapticDisplay> open_gravity_grabber(const std::string& hid_path,
                                                    const std::string& config_path);

}  // namespace telex::local
