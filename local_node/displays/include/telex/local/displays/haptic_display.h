// SPDX-License-Identifier: MIT
// Haptic display interface: per-fingertip pressure and shear to a device, a network sink or a log.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>

#include "telex/base/thread_fault.h"

namespace telex::local {

struct FingerForce {
  int finger = 0;           // 0 thumb .. 4 little
  double pressure_N = 0.0;  // into the finger pad, >= 0
  double shear_N = 0.0;     // along the finger axis, + toward the fingertip
  bool contact = false;
};

struct DisplayStats {
  std::uint64_t writes = 0;
  std::uint64_t sent = 0;     // reports / datagrams / records handed to the device or file
  std::uint64_t dropped = 0;  // writes that could not be delivered (full ring, EAGAIN, I/O error)
  std::uint64_t errors = 0;   // device or socket errors
  double max_pressure_N = 0.0;
  double max_shear_N = 0.0;
};

// The counters behind DisplayStats, shared by the displays: updated on the haptic thread and read
// from any other without a lock.
struct DisplayCounters {
  std::atomic<std::uint64_t> writes{0}, sent{0}, dropped{0}, errors{0};
  std::atomic<double> max_pressure_N{0.0}, max_shear_N{0.0};
  DisplayStats snapshot() const {
    DisplayStats s;
    s.writes = writes;
    s.sent = sent;
    s.dropped = dropped;
    s.errors = errors;
    s.max_pressure_N = max_pressure_N;
    s.max_shear_N = max_shear_N;
    return s;
  }
};

struct DisplayConfig {
  // Gravity Grabber calibration and limits (JSON, docs/HARDWARE.md); empty = defaults.
  std::string gravity_grabber_config_path;
  nlohmann::json gravity_grabber;  // the rig's object, used when no path is given (null = none)
  int udp_default_port = 1234;
  std::size_t sim_ring_capacity = 8192;  // records buffered between the haptic and writer threads
};

class HapticDisplay {
 public:
  virtual ~HapticDisplay();
  // Called from the 1 kHz haptic thread: must not block, allocate or throw. Fingers missing from
  // `forces` are released (zero force).
  virtual void write(std::int64_t now_ns, std::span<const FingerForce> forces) = 0;
  virtual std::string name() const = 0;
  virtual DisplayStats stats() const = 0;
  // A display with a writer thread: that thread's fault (it stopped on an exception; the owner
  // stops the station, whose last write() and destructor still command zero force).
  virtual std::optional<ThreadFaultReport> thread_fault() const { return std::nullopt; }
};

// The safety duty as an object: commands zero force on every finger when it goes out of scope,
// whatever the exit path (return, exception, stop). Declare it right after the display it guards
// and before any thread that writes to that display, so it runs after those threads are joined.
class ZeroForceOnExit {
 public:
  explicit ZeroForceOnExit(HapticDisplay& display) : display_(display) {}
  ZeroForceOnExit(const ZeroForceOnExit&) = delete;
  ZeroForceOnExit& operator=(const ZeroForceOnExit&) = delete;
  ~ZeroForceOnExit() { release(); }
  // Zero force now (also called by the owner of the writing thread when that thread ends).
  void release() noexcept;

 private:
  HapticDisplay& display_;
};

// The spec taken apart, as make_display reads it (and with its std::invalid_argument), for what
// else needs the display's channel: the display supervisor (display_supervisor.h).
struct DisplaySpec {
  enum class Kind { Sim, GravityGrabber, Udp };
  Kind kind = Kind::Sim;
  std::string target;  // Sim: the CSV path (empty: none); GravityGrabber: HIDPATH|VID:PID[:SERIAL]
  std::string host;    // Udp
  int port = 0;        // Udp (the config's default when the spec has none)
};
DisplaySpec parse_display_spec(const std::string& spec, const DisplayConfig& config);

}  // namespace telex::local
