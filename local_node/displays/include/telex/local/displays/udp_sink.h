// SPDX-License-Identifier: MIT
// UDP haptic sink: 18 channels x 1000 as space-separated ASCII integers, one datagram per write.
#pragma once

#include <netinet/in.h>

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "telex/local/displays/haptic_display.h"

namespace telex::local {

inline constexpr int kUdpSinkChannels = 18;
inline constexpr int kUdpSinkDefaultPort = 1234;

// Channel map (docs/HARDWARE.md): 2f = pressure_N of finger f, 2f+1 = shear_N (f = 0 thumb ..
// 4 little), 10+f = contact (0 or 1), 15..17 unused (0). Fingers not in contact send 0 force.
std::array<double, kUdpSinkChannels> udp_sink_channels(std::span<const FingerForce> forces);

// Formats channels x 1000, rounded, into `out` without allocating; returns the text's length.
// `out` must hold kUdpSinkMaxBytes.
inline constexpr std::size_t kUdpSinkMaxBytes = kUdpSinkChannels * 12;
std::size_t format_udp_sink(const std::array<double, kUdpSinkChannels>& channels,
                            std::span<char, kUdpSinkMaxBytes> out);

// Parses a datagram back into channel values (divided by 1000); false when it does not hold
// exactly 18 integers. For tests and for receivers written against this format.
bool parse_udp_sink(std::string_view text, std::array<double, kUdpSinkChannels>& channels);

// Resolves host (name or address) once at start-up; throws std::runtime_error naming it.
std::unique_ptr<HapticDisplay> open_udp_sink(const std::string& host, int port);

// What the display supervisor (display_supervisor.h) holds for a UDP sink: its own socket, the
// destination resolved as open_udp_sink resolves it, and the zero-force datagram.
struct UdpSinkZero {
  std::string name;  // udp:HOST:PORT
  int fd = -1;       // an IPv4 datagram socket; the caller owns it
  sockaddr_in to{};
  std::string datagram;
};
// Throws as open_udp_sink does.
UdpSinkZero open_udp_sink_zero(const std::string& host, int port);

}  // namespace telex::local
