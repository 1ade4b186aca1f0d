// SPDX-License-Identifier: MIT
// UDP haptic sink: fixed-buffer ASCII formatting and a non-blocking datagram socket.
#include "telex/local/displays/udp_sink.h"

// clang-format off
// Boost 1.74's asio/awaitable.hpp uses std::exchange without including <utility>.
#include <utility>
// clang-format on
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <boost/asio.hpp>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace telex::local {

namespace asio = boost::asio;
using asio::ip::udp;

std::array<double, kUdpSinkChannels> udp_sink_channels(std::span<const FingerForce> forces) {
  std::array<double, kUdpSinkChannels> ch{};
  for (const FingerForce& f : forces) {
    if (f.finger < 0 || f.finger > 4 || !f.contact) continue;
    ch[2 * f.finger] = f.pressure_N;
    ch[2 * f.finger + 1] = f.shear_N;
    ch[10 + f.finger] = 1.0;
  }
  return ch;
}

std::size_t format_udp_sink(const std::array<double, kUdpSinkChannels>& channels,
                            std::span<char, kUdpSinkMaxBytes> out) {
  char* p = out.data();
  char* const end = out.data() + out.size();
  for (int i = 0; i < kUdpSinkChannels; ++i) {
    if (i > 0) *p++ = ' ';
    // Saturate instead of overflowing; NaN sends 0 so a receiver never sees garbage.
    const double scaled = std::isfinite(channels[i]) ? channels[i] * 1000.0 : 0.0;
    const double lim = static_cast<double>(std::numeric_limits<std::int32_t>::max());
    const auto v = static_cast<std::int32_t>(std::lround(std::clamp(scaled, -lim, lim)));
    p = std::to_chars(p, end, v).ptr;  // 11 chars max per value: fits 12 per channel
  }
  return static_cast<std::size_t>(p - out.data());
}

bool parse_udp_sink(std::string_view text, std::array<double, kUdpSinkChannels>& channels) {
  const char* p = text.data();
  const char* const end = text.data() + text.size();
  for (int i = 0; i < kUdpSinkChannels; ++i) {
    if (i > 0) {
      if (p == end || *p != ' ') return false;
      ++p;
    }
    std::int32_t v = 0;
    const auto r = std::from_chars(p, end, v);
    if (r.ec != std::errc{}) return false;
    channels[i] = v / 1000.0;
    p = r.ptr;
  }
  return p == end;
}

namespace {

std::string sink_name(const std::string& host, int port) {
  return "udp:" + host + ":" + std::to_string(port);
}

udp::endpoint resolve_sink(asio::io_context& io, const std::string& host, int port) {
  if (port <= 0 || port > 65535)
    throw std::invalid_argument("display spec " + sink_name(host, port) +
                                ": port must be 1..65535");
  boost::system::error_code ec;
  udp::resolver resolver(io);
  const auto results = resolver.resolve(udp::v4(), host, std::to_string(port), ec);
  if (ec || results.empty())
    throw std::runtime_error("UDP haptic sink: cannot resolve host '" + host +
                             "': " + ec.message() + " (give an IPv4 address such as 127.0.0.1)");
  return *results.begin();
}

class UdpSink final : public HapticDisplay {
 public:
  UdpSink(const std::string& host, int port)
      : socket_(io_), target_(resolve_sink(io_, host, port)), name_(sink_name(host, port)) {
    boost::system::error_code ec;
    socket_.open(udp::v4(), ec);
    if (ec) throw std::runtime_error("UDP haptic sink: cannot open a socket: " + ec.message());
    // A full send buffer must cost a datagram, never a wait on the haptic thread.
    socket_.non_blocking(true);
  }
  void write(std::int64_t, std::span<const FingerForce> forces) override {
    ++counters_.writes;
    const auto ch = udp_sink_channels(forces);
    for (int f = 0; f < 5; ++f) {
      if (ch[2 * f] > counters_.max_pressure_N) counters_.max_pressure_N = ch[2 * f];
      if (std::abs(ch[2 * f + 1]) > counters_.max_shear_N)
        counters_.max_shear_N = std::abs(ch[2 * f + 1]);
    }
    const std::size_t n = format_udp_sink(ch, buf_);
    boost::system::error_code ec;
    socket_.send_to(asio::buffer(buf_.data(), n), target_, 0, ec);
    if (!ec) {
      ++counters_.sent;
    } else if (ec == asio::error::would_block) {
      ++counters_.dropped;
    } else {
      ++counters_.dropped;
      ++counters_.errors;
    }
  }
  std::string name() const override { return name_; }
  DisplayStats stats() const override { return counters_.snapshot(); }

 private:
  asio::io_context io_;
  udp::socket socket_;
  udp::endpoint target_;
  std::string name_;
  std::array<char, kUdpSinkMaxBytes> buf_{};
  DisplayCounters counters_;
};

}  // namespace

std::unique_ptr<HapticDisplay> open_udp_sink(const std::string& host, int port) {
  return std::make_unique<UdpSink>(host, port);
}

UdpSinkZero open_udp_sink_zero(const std::string& host, int port) {
  asio::io_context io;
  const udp::endpoint to = resolve_sink(io, host, port);
  UdpSinkZero z;
  z.name = sink_name(host, port);
  std::memcpy(&z.to, to.data(), sizeof z.to);
  std::array<char, kUdpSinkMaxBytes> buf{};
  z.datagram.assign(buf.data(), format_udp_sink({}, buf));
  z.fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (z.fd < 0)
    throw std::runtime_error(std::string("UDP haptic sink: cannot open a socket: ") +
                             std::strerror(errno));
  return z;
}

}  // namespace telex::local
