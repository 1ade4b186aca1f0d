// SPDX-License-Identifier: MIT
// Internal: the head drivers' constructors and the serial port the Dynamixel driver talks through.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "telex/remote/head.h"

namespace telex::remote::detail {

std::unique_ptr<HeadDriver> make_no_head();
std::unique_ptr<HeadDriver> make_sim_head(const HeadSpec& spec, const HeadLimits& limits);
std::unique_ptr<HeadDriver> make_dynamixel_head(const HeadSpec& spec, const HeadLimits& limits);
std::unique_ptr<HeadDriver> make_udp_head(const HeadSpec& spec, const HeadLimits& limits);

// Every driver's first step in command(): a target with a non-finite angle is never sent; it is
// counted and named in `stats`. True when the target may go on.
inline bool admit_target(const HeadAngles& target_rad, HeadStats& stats) {
  if (std::all_of(target_rad.begin(), target_rad.end(), [](double v) { return std::isfinite(v); }))
    return true;
  ++stats.rejected;
  stats.last_error = "a non-finite target was not commanded";
  return false;
}

// A serial port opened raw (8N1, no flow control) at one of kDynamixelBauds, held exclusively.
// Only I/O: the protocol lives in telex/dynamixel/protocol.h.
class SerialPort {
 public:
  // Throws std::runtime_error naming the device and what to try (path, dialout group, in use).
  SerialPort(std::string path, int baud);
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  // Writes every byte, waiting at most `timeout` for room; false (and error()) on failure.
  bool write_all(std::span<const std::uint8_t> bytes, std::chrono::milliseconds timeout);
  // Reads what has arrived, waiting until `deadline` for the first byte: the count, 0 at the
  // deadline, -1 on an error (error()).
  std::ptrdiff_t read_some(std::span<std::uint8_t> out,
                           std::chrono::steady_clock::time_point deadline);
  // Drops bytes received and not read (a late answer to an earlier request).
  void discard_input();

  const std::string& path() const { return path_; }
  int baud() const { return baud_; }
  const std::string& error() const { return error_; }

 private:
  std::string path_;
  int baud_;
  int fd_ = -1;
  std::string error_;
};

}  // namespace telex::remote::detail
