// SPDX-License-Identifier: MIT
// --head udp:HOST:PORT: a lab's own head controller, sent the clamped target and read back over
// one connected UDP socket (docs/PROTOCOL.md, "Head controller datagrams").
// clang-format off
// Boost 1.74's asio/awaitable.hpp uses std::exchange without including <utility>.
#include <utility>
// clang-format on
#include <fmt/format.h>

#include <algorithm>
#include <boost/asio.hpp>
#include <cmath>
#include <stdexcept>

#include "head_impl.h"

namespace telex::remote {

namespace {

namespace asio = boost::asio;
using asio::ip::udp;

// A measured pose not renewed for this long is no longer valid.
constexpr std::int64_t kUdpPoseMaxAgeNs = 500'000'000;
// A reply at most this many sequence numbers behind the newest one taken is a reordered copy and
// dropped; one further behind means the controller restarted its count, and is taken.
constexpr std::int32_t kUdpReorderWindow = 16;

class UdpHead final : public HeadDriver {
 public:
  UdpHead(const HeadSpec& spec, const HeadLimits& limits)
      : limits_(limits), socket_(io_), who_(fmt::format("--head udp:{}:{}", spec.host, spec.port)) {
    boost::system::error_code ec;
    udp::resolver resolver(io_);
    const auto endpoints = resolver.resolve(spec.host, std::to_string(spec.port), ec);
    if (ec || endpoints.empty())
      throw std::runtime_error(who_ + ": cannot resolve '" + spec.host + "': " + ec.message());
    peer_ = endpoints.begin()->endpoint();
    socket_.open(peer_.protocol(), ec);
    // Connected: the kernel delivers only the controller's datagrams to this socket.
    if (!ec) socket_.connect(peer_, ec);
    if (!ec) socket_.non_blocking(true, ec);
    if (ec) throw std::runtime_error(who_ + ": cannot open a UDP socket to it: " + ec.message());
  }

  void command(const HeadAngles& target_rad, std::int64_t now_ns) override {
    if (!detail::admit_target(target_rad, stats_)) return;
    HeadDatagram d;
    d.sequence = sequence_++;
    d.time_ns = now_ns;
    d.joint_rad = target_rad;
    stats_.clamped += clamp_to_limits(d.joint_rad, limits_);
    const std::vector<std::uint8_t> bytes = encode_head_datagram(d);
    boost::system::error_code ec;
    socket_.send(asio::buffer(bytes), 0, ec);
    if (ec) {
      // ECONNREFUSED here is the ICMP answer to an earlier datagram: nothing listens there.
      ++stats_.io_errors;
      stats_.last_error = "send: " + ec.message();
      return;
    }
    ++stats_.commands;
  }

  HeadPose measured(std::int64_t now_ns) override {
    ++stats_.reads;
    std::array<std::uint8_t, 2048> buf{};
    while (true) {
      boost::system::error_code ec;
      const std::size_t n = socket_.receive(asio::buffer(buf), 0, ec);
      if (ec == asio::error::would_block || ec == asio::error::try_again) break;
      if (ec) {
        ++stats_.io_errors;
        stats_.last_error = "receive: " + ec.message();
        break;
      }
      const auto d = decode_head_datagram(std::span(buf.data(), n));
      if (!d) {
        ++stats_.bad_packets;
        stats_.last_error = fmt::format("a {}-byte datagram that is not a head pose", n);
        continue;
      }
      if (have_reply_) {
        const auto ahead = static_cast<std::int32_t>(d->sequence - last_sequence_);
        if (ahead <= 0 && -ahead < kUdpReorderWindow) {
          ++stats_.stale;
          continue;
        }
      }
      have_reply_ = true;
      last_sequence_ = d->sequence;
      // Stamped on this host's clock when taken: the controller's clock is its own.
      pose_ = HeadPose{d->joint_rad, now_ns, true};
    }
    HeadPose p = pose_;
    p.valid = have_reply_ && now_ns - pose_.time_ns <= kUdpPoseMaxAgeNs;
    if (p.valid) ++stats_.reads_valid;
    return p;
  }

  std::string name() const override {
    return fmt::format("udp:{}:{}", peer_.address().to_string(), peer_.port());
  }
  HeadStats stats() const override { return stats_; }

 private:
  HeadLimits limits_;
  asio::io_context io_;
  udp::socket socket_;
  udp::endpoint peer_;
  std::string who_;
  std::uint32_t sequence_ = 0;
  bool have_reply_ = false;
  std::uint32_t last_sequence_ = 0;
  HeadPose pose_;
  HeadStats stats_;
};

}  // namespace

namespace detail {
std::unique_ptr<HeadDriver> make_udp_head(const HeadSpec& spec, const HeadLimits& limits) {
  return std::make_unique<UdpHead>(spec, limits);
}
}  // namespace detail

}  // namespace telex::remote
