// SPDX-License-Identifier: MIT
// Display factory and the recording simulator (preallocated ring drained to CSV by a thread).
#include "telex/local/displays/haptic_display.h"

#include <spdlog/spdlog.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <vector>

#include "telex/base/periodic.h"

namespace telex::local {

HapticDisplay::~HapticDisplay() = default;

void ZeroForceOnExit::release() noexcept {
  std::array<FingerForce, 5> zero{};
  for (int i = 0; i < 5; ++i) zero[static_cast<std::size_t>(i)] = {i, 0.0, 0.0, false};
  try {
    display_.write(monotonic_ns(), zero);
  } catch (...) {
    // write() must not throw; a display that does has nothing more to command here.
  }
}

DisplaySpec parse_display_spec(const std::string& spec, const DisplayConfig& config) {
  DisplaySpec d;
  if (spec == "sim") return d;
  if (spec.rfind("sim:", 0) == 0 && spec.size() > 4) {
    d.target = spec.substr(4);
    return d;
  }
  if (spec.rfind("gravity-grabber:", 0) == 0) {
    d.kind = DisplaySpec::Kind::GravityGrabber;
    d.target = spec.substr(16);
    return d;
  }
  if (spec.rfind("udp:", 0) == 0 && spec.size() > 4) {
    d.kind = DisplaySpec::Kind::Udp;
    const std::string rest = spec.substr(4);
    const auto colon = rest.rfind(':');
    if (colon == std::string::npos) {
      d.host = rest;
      d.port = config.udp_default_port;
      return d;
    }
    const auto r = std::from_chars(rest.data() + colon + 1, rest.data() + rest.size(), d.port);
    if (r.ec != std::errc{} || r.ptr != rest.data() + rest.size() || colon == 0)
      throw std::invalid_argument("display spec '" + spec + "': expected udp:HOST[:PORT]");
    d.host = rest.substr(0, colon);
    return d;
  }
  throw std::invalid_argument(
      "display spec '" + spec +
      "' is not one of sim, sim:CSV, gravity-grabber:HIDPATH|VID:PID[:SERIAL], "
      "udp:HOST[:PORT]");
}

}  // namespace telex::local
