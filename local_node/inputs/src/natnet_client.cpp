// SPDX-License-Identifier: MIT
// NatNet client on Boost.Asio: connect request, server info, FRAMEOFDATA to rigid-body samples.
#include "telex/local/inputs/natnet_client.h"

#include <charconv>
#include <cmath>

// clang-format off
// Boost 1.74's asio/awaitable.hpp uses std::exchange without including <utility>.
#include <utility>
// clang-format on
#include <boost/asio.hpp>
#include <chrono>
#include <mutex>
#include <stdexcept>

#include "telex/base/periodic.h"

namespace telex::local {

namespace asio = boost::asio;
using asio::ip::udp;

const NatNetSample::Body* NatNetSample::find(std::int32_t id) const {
  for (const auto& b : bodies)
    if (b.id == id && b.present) return &b;
  return nullptr;
}

std::int64_t natnet_reported_latency_ns(const natnet::Frame& frame, const natnet::Version& v,
                                        std::uint64_t high_res_clock_hz) {
  constexpr double kMaxS = 1.0;  // beyond this the stamps are not a latency (a restarted clock)
  double latency_s = 0.0;
  if (!v.at_least(3, 0)) {
    latency_s = static_cast<double>(frame.software_latency_s);
  } else if (high_res_clock_hz != 0 && frame.stamp_mid_exposure != 0 &&
             frame.stamp_transmit >= frame.stamp_mid_exposure) {
    latency_s = static_cast<double>(frame.stamp_transmit - frame.stamp_mid_exposure) /
                static_cast<double>(high_res_clock_hz);
  }
  if (!std::isfinite(latency_s) || latency_s <= 0.0 || latency_s > kMaxS) return 0;
  return std::llround(latency_s * 1e9);
}

struct NatNetClient::Impl {
  explicit Impl(NatNetClientConfig c, TripleBuffer<NatNetSample>& out)
      : cfg(std::move(c)), samples(out), command(io), ping_timer(io) {}

  NatNetClientConfig cfg;
  TripleBuffer<NatNetSample>& samples;
  asio::io_context io;
  udp::socket command;
  std::unique_ptr<udp::socket> data;
  udp::endpoint server;
  asio::steady_timer ping_timer;
  std::vector<std::uint8_t> ping;
  std::array<std::uint8_t, natnet::kMaxPacketBytes> cmd_buf{};
  std::array<std::uint8_t, natnet::kMaxPacketBytes> data_buf{};
  udp::endpoint cmd_from, data_from;
  // Who speaks for the server (source_of). `server` is its command endpoint, where the connect
  // request goes and its replies come from; `frame_source` is where its frames come from, once
  // learnt, and `frame_source_seen_ns` when it last sent one (steady clock). Receive thread only.
  asio::ip::address server_addr;
  std::optional<udp::endpoint> frame_source;
  std::int64_t frame_source_seen_ns = 0;
  bool warned_foreign = false;
  int command_port = 0;  // bound, read by any thread
  natnet::Frame frame;   // reused, so the top-level arrays stop reallocating
  // The server's high-resolution clock (Hz; 0 before its SERVERINFO), the unit of a frame's
  // stamps. Receive thread only.
  std::uint64_t clock_hz = 0;
  // Per published body (cfg.body_ids order): its last accepted pose and its frame's stamp and
  // arrival, the reference of the speed check. And the last accepted frame, the reference of the
  // timeline check. Both start afresh with a new frame source.
  struct Accepted {
    bool have = false;
    Pose pose;
    FrameStamp stamp;
  };
  std::array<Accepted, NatNetSample::kMaxBodies> accepted{};
  std::optional<FrameStamp> last_frame;
  const PoseLimits limits{};
  const TimelineLimits timeline{};
  ThreadFault fault{"tracking (telex-natnet)"};

  std::atomic<int> version_major{0}, version_minor{0};
  mutable std::mutex info_mu;  // server info and last error; never touched by the haptic thread
  std::optional<natnet::ServerInfo> info;
  std::string last_error;

  std::atomic<std::uint64_t> datagrams{0}, frames{0}, parse_errors{0}, before_version{0},
      pings_sent{0}, io_errors{0}, foreign_datagrams{0}, frame_jumps{0}, rejected_nonfinite{0},
      rejected_quaternion{0}, rejected_too_fast{0};

  void open() {
    boost::system::error_code ec;
    const auto server_addr = asio::ip::make_address(cfg.server_ip, ec);
    if (ec)
      throw std::runtime_error("NatNet server address '" + cfg.server_ip +
                               "' is not an IPv4/IPv6 address (give the Motive PC's IP)");
    server = udp::endpoint(server_addr, static_cast<unsigned short>(cfg.command_port));
    this->server_addr = server_addr;
    command.open(udp::v4());
    command.bind(udp::endpoint(udp::v4(), 0), ec);
    if (ec) throw std::runtime_error("NatNet command socket: cannot bind: " + ec.message());
    command_port = command.local_endpoint().port();
    // Motive bursts large frames; a bigger receive buffer rides them out (capped by rmem_max).
    command.set_option(asio::socket_base::receive_buffer_size(1 << 20), ec);
    if (cfg.multicast) {
      data = std::make_unique<udp::socket>(io);
      data->open(udp::v4());
      data->set_option(asio::socket_base::reuse_address(true));
      data->bind(udp::endpoint(udp::v4(), static_cast<unsigned short>(cfg.data_port)), ec);
      if (ec)
        throw std::runtime_error("NatNet data port " + std::to_string(cfg.data_port) +
                                 ": cannot bind: " + ec.message() +
                                 " (another client without SO_REUSEADDR? try unicast)");
      const auto group = asio::ip::make_address_v4(cfg.multicast_group, ec);
      if (ec || !group.is_multicast())
        throw std::runtime_error(
            "NatNet multicast group '" + cfg.multicast_group +
            "' is not an IPv4 multicast address (Motive default 239.255.42.99)");
      const auto iface = asio::ip::make_address_v4(cfg.local_address, ec);
      if (ec)
        throw std::runtime_error("NatNet local interface '" + cfg.local_address +
                                 "' is not an IPv4 address");
      data->set_option(asio::ip::multicast::join_group(group, iface), ec);
      if (ec)
        throw std::runtime_error("NatNet: cannot join " + cfg.multicast_group + " on " +
                                 cfg.local_address + ": " + ec.message() +
                                 " (check the interface address, or use unicast)");
      data->set_option(asio::socket_base::receive_buffer_size(1 << 20), ec);
    }
    if (cfg.version) {
      version_major = cfg.version->major;
      version_minor = cfg.version->minor;
    }
    ping = natnet::make_ping(cfg.app_name);
  }

  void start() {
    send_ping();
    receive_command();
    if (data) receive_data();
  }

  // The connect request is repeated until the server answers, so a client started before Motive
  // still connects; in unicast the repeats also keep the server sending to us.
  void send_ping() {
    if (!info_known() || !cfg.multicast) {
      boost::system::error_code ec;
      command.send_to(asio::buffer(ping), server, 0, ec);
      if (ec)
        ++io_errors;
      else
        ++pings_sent;
    }
    ping_timer.expires_after(std::chrono::seconds(1));
    ping_timer.async_wait([this](boost::system::error_code ec) {
      if (!ec) send_ping();
    });
  }

  bool info_known() {
    std::lock_guard lock(info_mu);
    return info.has_value();
  }

  void receive_command() {
    command.async_receive_from(asio::buffer(cmd_buf), cmd_from,
                               [this](boost::system::error_code ec, std::size_t n) {
                                 if (ec == asio::error::operation_aborted) return;
                                 if (ec)
                                   ++io_errors;
                                 else
                                   handle(cmd_from, std::span(cmd_buf.data(), n));
                                 receive_command();
                               });
  }

  void receive_data() {
    data->async_receive_from(asio::buffer(data_buf), data_from,
                             [this](boost::system::error_code ec, std::size_t n) {
                               if (ec == asio::error::operation_aborted) return;
                               if (ec)
                                 ++io_errors;
                               else
                                 handle(data_from, std::span(data_buf.data(), n));
                               receive_data();
                             });
  }

  void count(PoseVerdict verdict) {
    switch (verdict) {
      case PoseVerdict::NonFinite:
        ++rejected_nonfinite;
        break;
      case PoseVerdict::BadQuaternion:
        ++rejected_quaternion;
        break;
      case PoseVerdict::TooFast:
        ++rejected_too_fast;
        break;
      case PoseVerdict::Ok:
        break;
    }
  }

  void reject(const char* why) {
    ++parse_errors;
    std::lock_guard lock(info_mu);
    last_error = why;
  }

  void note(std::string what) {
    std::lock_guard lock(info_mu);
    last_error = std::move(what);
  }

  // Who speaks for the server. Its replies come from its command socket, the endpoint the connect
  // request goes to (SERVER_IP:cmd): only that endpoint's replies are read. Its frames come from
  // whichever socket it streams on, and NatNet names no source port: telex-sim-natnet sends
  // unicast frames from its command socket and multicast ones from an unbound socket (an
  // ephemeral port), and Motive streams from a data socket of its own, whose port may differ from
  // its command port. So the frames' source is learnt, then pinned:
  // - a frame from the command endpoint pins it, whatever was pinned before: no other process can
  //   send from the port the server has bound, so a sender that got in first is displaced by the
  //   server's next frame;
  // - else the first frame from another port of the server's address pins that port, once the
  //   layout is known (the server answered the connect request, or version= was given: before,
  //   its frames are counted before_version, unread);
  // - from then on any other port of that address is foreign, unless the pinned source has sent
  //   nothing for resync_s (a restarted Motive binds anew).
  // What this cannot tell apart: a sender on the server's host whose frame is the first after the
  // connect reply, to a server streaming from another port than its command port, holds the pin
  // while it keeps sending (the server's frames are then counted foreign, and the stream checks
  // below still hold its frames to one timeline and human speeds).
  enum class Source { Foreign, Command, Frames, Candidate };
  Source source_of(const udp::endpoint& from, std::int64_t now_ns) const {
    if (from.address() != server_addr) return Source::Foreign;
    if (from == server) return Source::Command;
    if (frame_source && from == *frame_source) return Source::Frames;
    const bool pinned_alive =
        frame_source &&
        static_cast<double>(now_ns - frame_source_seen_ns) * 1e-9 <= timeline.resync_s;
    return pinned_alive ? Source::Foreign : Source::Candidate;
  }

  // A datagram from anyone but the server is dropped before it is believed: neither its server
  // info (which sets the layout every later frame is parsed in) nor its poses.
  void foreign(const udp::endpoint& from, const char* why) {
    ++foreign_datagrams;
    std::string what = "datagram from " + from.address().to_string() + ":" +
                       std::to_string(from.port()) + " dropped: " + why + " (the server is " +
                       server.address().to_string() + ":" + std::to_string(server.port());
    if (frame_source && *frame_source != server)
      what += ", its frames come from port " + std::to_string(frame_source->port());
    what += ")";
    if (!warned_foreign && from.address() != server_addr) {
      warned_foreign = true;
      // Once: a Motive PC multicasting from a second interface shows up here too.
      what += "; if Motive sends from that address, give it as the server's";
    }
    note(std::move(what));
  }

  void handle(const udp::endpoint& from, std::span<const std::uint8_t> datagram) {
    ++datagrams;
    const std::int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::steady_clock::now().time_since_epoch())
                                    .count();
    const Source src = source_of(from, now_ns);
    if (src == Source::Foreign) return foreign(from, "not the server's address or port");
    if (cfg.receive_hook) cfg.receive_hook();
    natnet::PacketView pkt;
    if (auto st = natnet::parse_packet(datagram, pkt); !st.ok())
      return src == Source::Candidate ? foreign(from, "unreadable, from an unknown port")
                                      : reject(st.reason);
    if (pkt.message_id == natnet::kPingResponse) {
      if (src != Source::Command) return foreign(from, "server info not from its command port");
      return on_server_info(pkt.payload);
    }
    if (pkt.message_id == natnet::kFrameOfData) return on_frame(from, src, pkt.payload, now_ns);
    // Model definitions, messages: not needed, and believed from nowhere else either.
    if (src == Source::Candidate) foreign(from, "not a frame, from an unknown port");
  }

  void on_server_info(std::span<const std::uint8_t> payload) {
    natnet::ServerInfo si;
    if (auto st = natnet::parse_server_info(payload, si); !st.ok()) return reject(st.reason);
    if (!cfg.version) {
      version_major = si.natnet_version.major;
      version_minor = si.natnet_version.minor;
    }
    // 3.0+: the connection fields, with the rate of the clock the frames' stamps count; a
    // server whose info does not parse so has its frames' arrivals as their mid-exposure.
    if (natnet::ServerInfo full; natnet::parse_server_info(payload, si.natnet_version, full).ok())
      si = std::move(full);
    clock_hz = si.has_connection_info ? si.high_res_clock_hz : 0;
    std::lock_guard lock(info_mu);
    info = std::move(si);
  }

  // A new source of frames: its frames start their own timeline, and no pose from the old one is
  // a reference for the speed check.
  void pin_frame_source(const udp::endpoint& from) {
    if (frame_source == from) return;
    frame_source = from;
    last_frame.reset();
    accepted = {};
  }

  void on_frame(const udp::endpoint& from, Source src, std::span<const std::uint8_t> payload,
                std::int64_t now_ns) {
    const natnet::Version v{version_major.load(), version_minor.load()};
    if (v.major == 0) {
      ++before_version;
      return;
    }
    if (auto st = natnet::parse_frame(payload, v, frame); !st.ok())
      return src == Source::Candidate ? foreign(from, "unreadable frame, from an unknown port")
                                      : reject(st.reason);
    if (src != Source::Frames) pin_frame_source(from);
    frame_source_seen_ns = now_ns;
    ++frames;
    NatNetSample s;
    s.frame_number = frame.frame_number;
    s.received_ns = now_ns;
    s.mid_exposure_ns = s.received_ns - natnet_reported_latency_ns(frame, v, clock_hz);
    // Servers before NatNet 2.6 send no frame timestamp: their frames are stamped on arrival.
    s.timestamp_s =
        v.at_least(2, 6) ? frame.timestamp_s : static_cast<double>(s.received_ns) * 1e-9;
    if (!std::isfinite(s.timestamp_s)) {  // velocities are taken over these stamps
      ++rejected_nonfinite;
      return;
    }
    const FrameStamp stamp{s.frame_number, s.timestamp_s, s.received_ns};
    if (last_frame) {
      const FrameVerdict verdict = check_frame(*last_frame, stamp, timeline);
      if (verdict == FrameVerdict::Backwards || verdict == FrameVerdict::TooFarAhead) {
        ++frame_jumps;
        note("frame " + std::to_string(stamp.frame_number) + " at " +
             std::to_string(stamp.timestamp_s) + " s after frame " +
             std::to_string(last_frame->frame_number) + " at " +
             std::to_string(last_frame->timestamp_s) + " s: " + std::string(to_string(verdict)) +
             ", dropped");
        return;
      }
    }
    last_frame = stamp;
    publish(s, stamp);
  }

  void publish(NatNetSample& s, const FrameStamp& stamp) {
    const std::size_t n = std::min<std::size_t>(cfg.body_ids.size(), NatNetSample::kMaxBodies);
    for (std::size_t i = 0; i < n; ++i) {
      auto& b = s.bodies[i];
      b.id = cfg.body_ids[i];
      const natnet::RigidBody* rb = frame.find_body(b.id);
      if (rb == nullptr) continue;
      b.present = true;
      if (!rb->tracking_valid) {
        // Untracked: not used, so neither counted nor a speed reference; its pose is kept for the
        // tracking log when it is finite and unit, as Motive sent it.
        Pose raw;
        if (check_pose(*rb, limits, nullptr, 0.0, raw) == PoseVerdict::Ok) b.pose = raw;
        continue;
      }
      Accepted& last = accepted[i];
      // The time since the last accepted pose, bounded by the arrivals' (speed_check_dt_s): a
      // sender's stamps alone never widen it.
      const double dt_s = last.have ? speed_check_dt_s(last.stamp, stamp, timeline) : 0.0;
      const PoseVerdict verdict =
          check_pose(*rb, limits, last.have ? &last.pose : nullptr, dt_s, b.pose);
      if (verdict != PoseVerdict::Ok) {
        b.rejected = true;
        b.pose = Pose{};
        count(verdict);
        continue;
      }
      b.valid = true;
      last = {true, b.pose, stamp};
    }
    samples.publish(s);
  }
};

NatNetClient::NatNetClient(NatNetClientConfig config)
    : impl_(std::make_unique<Impl>(std::move(config), samples_)) {
  impl_->open();
  impl_->start();
  // Nothing may escape the receive thread: a fault stops it and waits in thread_fault() for the
  // owner (the station polls it and stops with zero force).
  thread_ = std::thread([this] { impl_->fault.run([this] { impl_->io.run(); }); });
  name_thread(thread_.native_handle(), "telex-natnet");
  scheduling_ = try_realtime(thread_.native_handle(), impl_->cfg.realtime_priority);
}

NatNetClient::~NatNetClient() {
  impl_->io.stop();
  if (thread_.joinable()) thread_.join();
}

std::optional<natnet::ServerInfo> NatNetClient::server_info() const {
  std::lock_guard lock(impl_->info_mu);
  return impl_->info;
}

std::string NatNetClient::last_error() const {
  std::lock_guard lock(impl_->info_mu);
  return impl_->last_error;
}

int NatNetClient::command_port() const { return impl_->command_port; }

std::optional<ThreadFaultReport> NatNetClient::thread_fault() const {
  return impl_->fault.report();
}

NatNetClientStats NatNetClient::stats() const {
  NatNetClientStats s;
  s.datagrams = impl_->datagrams;
  s.frames = impl_->frames;
  s.parse_errors = impl_->parse_errors;
  s.before_version = impl_->before_version;
  s.pings_sent = impl_->pings_sent;
  s.io_errors = impl_->io_errors;
  s.foreign_datagrams = impl_->foreign_datagrams;
  s.frame_jumps = impl_->frame_jumps;
  s.rejected_nonfinite = impl_->rejected_nonfinite;
  s.rejected_quaternion = impl_->rejected_quaternion;
  s.rejected_too_fast = impl_->rejected_too_fast;
  s.thread_faults = impl_->fault.count();
  return s;
}

void check_multicast_group(const std::string& group) {
  boost::system::error_code ec;
  const auto address = asio::ip::make_address_v4(group, ec);
  if (ec || !address.is_multicast())
    throw std::invalid_argument("'" + group +
                                "' is not an IPv4 multicast address (Motive's default is " +
                                natnet::kMulticastGroup + ")");
}

NatNetClientConfig parse_natnet_spec(std::string_view text, const std::string& what,
                                     NatNetClientConfig c) {
  const auto port = [&](std::string_view p) {
    int v = 0;
    const auto r = std::from_chars(p.data(), p.data() + p.size(), v);
    if (r.ec != std::errc{} || r.ptr != p.data() + p.size() || v < 1 || v > 65535)
      throw std::invalid_argument(what + ": '" + std::string(p) + "' is not a port (1-65535)");
    return v;
  };
  std::string_view rest = text;
  bool first = true;
  while (!rest.empty() || first) {
    const auto comma = rest.find(',');
    const std::string_view item = rest.substr(0, comma);
    rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
    if (first) {
      if (item.empty())
        throw std::invalid_argument(what +
                                    ": give the Motive server's IP first, e.g. 192.168.1.10");
      c.server_ip = std::string(item);
      boost::system::error_code ec;
      asio::ip::make_address(c.server_ip, ec);
      if (ec)
        throw std::invalid_argument(what + ": '" + c.server_ip +
                                    "' is not an IPv4 or IPv6 address (give the Motive PC's IP, "
                                    "e.g. 192.168.1.10)");
      first = false;
    } else if (item == "multicast") {
      c.multicast = true;
    } else if (item == "unicast") {
      c.multicast = false;
    } else if (item.rfind("local=", 0) == 0) {
      c.local_address = std::string(item.substr(6));
      boost::system::error_code ec;
      asio::ip::make_address_v4(c.local_address, ec);
      if (ec)
        throw std::invalid_argument(what + ": local=" + c.local_address +
                                    " is not an IPv4 address (the address of this station's "
                                    "interface facing the Motive PC)");
    } else if (item.rfind("cmd=", 0) == 0) {
      c.command_port = port(item.substr(4));
    } else if (item.rfind("data=", 0) == 0) {
      c.data_port = port(item.substr(5));
    } else if (item.rfind("version=", 0) == 0) {
      c.version = natnet::parse_version(item.substr(8));
    } else {
      throw std::invalid_argument(
          what + ": unknown option '" + std::string(item) +
          "' (valid: multicast, unicast, local=IP, cmd=PORT, data=PORT, version=X.Y)");
    }
  }
  return c;
}

}  // namespace telex::local
