// SPDX-License-Identifier: MIT
// NatNet server simulator: Asio timer-driven frame stream, built-in and recorded motions.
#include "telex/sim/natnet_server.h"

// clang-format off
// Boost 1.74's asio/awaitable.hpp uses std::exchange without including <utility>.
#include <utility>
// clang-format on
#include <algorithm>
#include <array>
#include <boost/asio.hpp>
#include <charconv>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <mutex>
#include <numbers>
#include <stdexcept>

#include "telex/base/byte_cursor.h"
#include "telex/haptics/hand_kinematics.h"
#include "telex/sim/head_turns.h"

namespace telex::sim {

namespace asio = boost::asio;
using asio::ip::udp;

std::string body_name(std::int32_t id) {
  switch (id) {
    case kSimHeadId:
      return "head";
    case kSimRightHandId:
      return "right_hand";
    case kSimRightShoulderId:
      return "right_shoulder";
    default:
      return "body_" + std::to_string(id);
  }
}

namespace {
natnet::RigidBody body(std::int32_t id, double x, double y, double z, double qx, double qy,
                       double qz, double qw) {
  natnet::RigidBody b;
  b.id = id;
  b.p_m = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
  b.qx = static_cast<float>(qx);
  b.qy = static_cast<float>(qy);
  b.qz = static_cast<float>(qz);
  b.qw = static_cast<float>(qw);
  b.mean_error_m = 0.0003f;
  return b;
}
}  // namespace

namespace {
// The press motion's fixed bodies and hand orientation: hand frame x (fingers) -> world -z, y (back
// of the hand) -> world +y, 90 deg about +y.
const double kPressS = std::sin(std::numbers::pi / 4), kPressC = std::cos(std::numbers::pi / 4);

void press_frame(double hand_z_m, natnet::Frame& frame) {
  frame.rigid_bodies.clear();
  frame.rigid_bodies.push_back(body(kSimHeadId, 0.0, 1.6, 0.0, 0, 0, 0, 1));
  frame.rigid_bodies.push_back(body(kSimRightHandId, 0.03, 1.5, hand_z_m, 0, kPressS, 0, kPressC));
  frame.rigid_bodies.push_back(body(kSimRightShoulderId, 0.2, 1.45, 0.05, 0, 0, 0, 1));
}
}  // namespace

void natnet_press_motion(double t_s, natnet::Frame& frame) {
  const double reach_m = 0.25 + 0.15 * (1.0 - std::cos(2.0 * std::numbers::pi * t_s / 4.0));
  press_frame(-reach_m, frame);
}

double press_index_tip_ahead_of_hand_m() {
  const Pose X_WorldWrist{{0.0, 0.0, 0.0}, glm::dquat(kPressC, 0.0, kPressS, 0.0)};
  const std::array<double, 5> straight{};
  const HandPoints pts = hand_forward(HandGeometry{}, X_WorldWrist, std::span(straight));
  return -pts.joints[1][3].z;  // the index tip, world -z being forward
}

NatNetMotion natnet_press_toward(double surface_depth_m) {
  if (!std::isfinite(surface_depth_m) || surface_depth_m < 0.35 || surface_depth_m > 5.0)
    throw std::invalid_argument("--reach must be in [0.35, 5] m (the surface's depth)");
  const double tip_ahead_m = press_index_tip_ahead_of_hand_m();
  return [surface_depth_m, tip_ahead_m](double t_s, natnet::Frame& frame) {
    const double tip_depth_m = surface_depth_m - kPressTipStartM +
                               0.5 * (kPressTipStartM + kPressTipPastM) *
                                   (1.0 - std::cos(2.0 * std::numbers::pi * t_s / 4.0));
    // The camera sits kPressEyesAheadOfHeadM in front of the head body (looking along -z).
    press_frame(-(tip_depth_m + kPressEyesAheadOfHeadM) + tip_ahead_m, frame);
  };
}

NatNetMotion natnet_hold_toward(double surface_depth_m) {
  if (!std::isfinite(surface_depth_m) || surface_depth_m < 0.35 || surface_depth_m > 5.0)
    throw std::invalid_argument("--reach must be in [0.35, 5] m (the surface's depth)");
  const double tip_ahead_m = press_index_tip_ahead_of_hand_m();
  const double tip_depth_m = surface_depth_m + 0.5 * kPressTipPastM;
  return [tip_depth_m, tip_ahead_m](double, natnet::Frame& frame) {
    press_frame(-(tip_depth_m + kPressEyesAheadOfHeadM) + tip_ahead_m, frame);
  };
}

NatNetMotion natnet_head_turns(double reported_latency_s) {
  return [reported_latency_s](double t_s, natnet::Frame& frame) {
    natnet_press_motion(t_s, frame);
    // The frame goes out now; it says its cameras saw it reported_latency_s ago.
    const double sampled_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count() -
        reported_latency_s;
    const SimPose X_NatNetBody = head_turns_body_in_natnet(sampled_s);
    const glm::dquat& q = X_NatNetBody.q;
    const glm::dvec3& p = X_NatNetBody.p_m;
    frame.rigid_bodies.front() = body(kSimHeadId, p.x, p.y, p.z, q.x, q.y, q.z, q.w);
  };
}

NatNetMotion load_natnet_csv(const std::filesystem::path& path, bool loop) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("NatNet recording " + path.string() + ": cannot open");
  struct Key {
    double t_s;
    natnet::RigidBody b;
  };
  std::map<std::int32_t, std::vector<Key>> tracks;
  std::string line;
  int line_no = 0;
  double t_end = 0.0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    if (!header) {
      if (line.rfind("time_s,body_id,x,y,z,qx,qy,qz,qw", 0) != 0)
        throw std::runtime_error("NatNet recording " + path.string() + " line " +
                                 std::to_string(line_no) +
                                 ": expected header time_s,body_id,x,y,z,qx,qy,qz,qw");
      header = true;
      continue;
    }
    // from_chars, not a stream: "nan" and "inf" are read too, so a recording can replay a faulty
    // stream (the station's pose checks are tested with one).
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    std::array<double, 9> v{};
    std::size_t n = 0;
    bool ok = true;
    for (std::size_t pos = 0; ok && pos <= line.size(); ++n) {
      const std::size_t end = std::min(line.find(',', pos), line.size());
      const char* first = line.data() + pos;
      while (first < line.data() + end && *first == ' ') ++first;
      ok = n < v.size() &&
           std::from_chars(first, line.data() + end, v[n]).ptr == line.data() + end &&
           first != line.data() + end;
      pos = end + 1;
    }
    const double t = v[0], x = v[2], y = v[3], z = v[4], qx = v[5], qy = v[6], qz = v[7], qw = v[8];
    if (!ok || n != v.size() || !std::isfinite(t) || t < t_end || !(std::abs(v[1]) < 2e9) ||
        v[1] != std::trunc(v[1]))
      throw std::runtime_error("NatNet recording " + path.string() + " line " +
                               std::to_string(line_no) +
                               ": expected 9 numbers with non-decreasing time_s");
    const auto id = static_cast<std::int32_t>(v[1]);
    t_end = t;
    tracks[id].push_back({t, body(id, x, y, z, qx, qy, qz, qw)});
  }
  if (tracks.empty()) throw std::runtime_error("NatNet recording " + path.string() + ": no poses");
  return [tracks = std::move(tracks), t_end, loop](double t_s, natnet::Frame& frame) {
    frame.rigid_bodies.clear();
    const double t = (loop && t_end > 0.0) ? std::fmod(t_s, t_end) : t_s;
    for (const auto& [id, keys] : tracks) {
      auto it = std::upper_bound(keys.begin(), keys.end(), t,
                                 [](double v, const Key& k) { return v < k.t_s; });
      if (it == keys.begin()) continue;  // body not seen yet at this time
      frame.rigid_bodies.push_back(std::prev(it)->b);
    }
  };
}

struct NatNetServer::Impl {
  Impl(NatNetServerConfig c, NatNetMotion m)
      : cfg(std::move(c)), motion(std::move(m)), command(io), data(io), tick(io), deadline(io) {}

  NatNetServerConfig cfg;
  NatNetMotion motion;
  asio::io_context io;
  udp::socket command;
  udp::socket data;
  udp::endpoint group;
  asio::steady_timer tick, deadline;
  std::array<std::uint8_t, 2048> buf{};
  udp::endpoint from;
  std::vector<udp::endpoint> clients;
  natnet::Frame frame;
  std::chrono::steady_clock::time_point start;
  std::uint32_t frame_number = 0;
  mutable std::mutex mu;
  NatNetServerStats stats;

  void open() {
    boost::system::error_code ec;
    const auto addr = asio::ip::make_address(cfg.bind_address, ec);
    if (ec) throw std::runtime_error("NatNet server: bad bind address '" + cfg.bind_address + "'");
    command.open(udp::v4());
    command.bind(udp::endpoint(addr, static_cast<unsigned short>(cfg.command_port)), ec);
    if (ec)
      throw std::runtime_error("NatNet server: cannot bind " + cfg.bind_address + ":" +
                               std::to_string(cfg.command_port) + ": " + ec.message() +
                               " (is Motive or another simulator running? pick --command-port)");
    if (cfg.multicast) {
      const auto g = asio::ip::make_address_v4(cfg.multicast_group, ec);
      if (ec || !g.is_multicast())
        throw std::runtime_error("NatNet server: '" + cfg.multicast_group +
                                 "' is not an IPv4 multicast group");
      group = udp::endpoint(g, static_cast<unsigned short>(cfg.data_port));
      data.open(udp::v4());
      data.set_option(asio::ip::multicast::outbound_interface(
          asio::ip::make_address_v4(cfg.multicast_interface)));
      data.set_option(asio::ip::multicast::enable_loopback(true));
      data.set_option(asio::ip::multicast::hops(1));
    }
  }

  void receive() {
    command.async_receive_from(asio::buffer(buf), from,
                               [this](boost::system::error_code ec, std::size_t n) {
                                 if (ec == asio::error::operation_aborted) return;
                                 if (!ec) on_command(n);
                                 receive();
                               });
  }

  // Motive's answers, in the layout of the version streamed: server info to a connect, the
  // rigid bodies' descriptions to a model request, an echo (3.0+; unrecognised before).
  void on_command(std::size_t n) {
    natnet::PacketView pkt;
    if (!natnet::parse_packet(std::span(buf.data(), n), pkt).ok()) return;
    if (pkt.message_id == natnet::kRequestModelDef) {
      reply(make_model_defs(), stats.model_defs_answered);
    } else if (pkt.message_id == natnet::kEchoRequest) {
      std::uint64_t client_stamp = 0;
      ByteReader r(pkt.payload);
      if (!r.get(client_stamp)) return;
      reply(natnet::make_echo_reply(client_stamp, stamp_now(), cfg.version), stats.echoes_answered);
    } else if (pkt.message_id == natnet::kPing) {
      on_connect();
    }
  }

  // The stamps of the frames and the echo: ticks of kSimClockHz since the start.
  std::uint64_t stamp_now() const {
    const double t_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return static_cast<std::uint64_t>(t_s * static_cast<double>(kSimClockHz));
  }

  std::vector<std::uint8_t> make_model_defs() {
    natnet::Frame first;
    motion(0.0, first);
    natnet::ModelDefs defs;
    for (const auto& b : first.rigid_bodies)
      defs.rigid_bodies.push_back({body_name(b.id), b.id, -1, {}});
    return natnet::make_model_defs(defs, cfg.version);
  }

  void reply(const std::vector<std::uint8_t>& bytes, std::uint64_t& answered) {
    boost::system::error_code ec;
    command.send_to(asio::buffer(bytes), from, 0, ec);
    std::lock_guard lock(mu);
    ec ? ++stats.send_errors : ++answered;
  }

  void on_connect() {
    natnet::ServerInfo info;
    info.app_name = cfg.app_name;
    info.app_version = {1, 0, 0, 0};
    info.natnet_version = cfg.version;
    info.high_res_clock_hz = kSimClockHz;
    info.data_port = static_cast<std::uint16_t>(cfg.data_port);
    info.multicast = cfg.multicast;
    boost::system::error_code group_ec;
    const auto group = asio::ip::make_address_v4(cfg.multicast_group, group_ec);
    if (!group_ec) info.multicast_group = group.to_bytes();
    const auto reply = natnet::make_server_info(info);
    boost::system::error_code ec;
    command.send_to(asio::buffer(reply), from, 0, ec);
    std::lock_guard lock(mu);
    if (ec) {
      ++stats.send_errors;
      return;
    }
    ++stats.pings_answered;
    if (std::find(clients.begin(), clients.end(), from) == clients.end()) {
      clients.push_back(from);
      ++stats.clients;
    }
  }

  void schedule(std::chrono::steady_clock::time_point when) {
    tick.expires_at(when);
    tick.async_wait([this, when](boost::system::error_code ec) {
      if (ec) return;
      send_frame(when);
      // Absolute deadlines keep the mean rate exact even when one send runs late.
      const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(1.0 / cfg.rate_hz));
      schedule(when + period);
    });
  }

  void send_frame(std::chrono::steady_clock::time_point when) {
    const double t_s = std::chrono::duration<double>(when - start).count();
    frame.clear();
    motion(t_s, frame);
    frame.frame_number = ++frame_number;
    frame.timestamp_s = t_s;
    frame.stamp_transmit = static_cast<std::uint64_t>(t_s * static_cast<double>(kSimClockHz));
    const auto latency =
        static_cast<std::uint64_t>(cfg.reported_latency_s * static_cast<double>(kSimClockHz));
    frame.stamp_mid_exposure = frame.stamp_transmit > latency ? frame.stamp_transmit - latency : 0;
    frame.software_latency_s = static_cast<float>(cfg.reported_latency_s);
    const auto bytes = natnet::encode_frame(frame, cfg.version);
    boost::system::error_code ec;
    std::lock_guard lock(mu);
    if (cfg.multicast) {
      data.send_to(asio::buffer(bytes), group, 0, ec);
      ec ? ++stats.send_errors : ++stats.frames_sent;
    } else {
      for (const auto& c : clients) {
        command.send_to(asio::buffer(bytes), c, 0, ec);
        ec ? ++stats.send_errors : ++stats.frames_sent;
      }
    }
  }
};

NatNetServer::NatNetServer(NatNetServerConfig config, NatNetMotion motion)
    : impl_(std::make_unique<Impl>(std::move(config), std::move(motion))) {
  if (!(impl_->cfg.rate_hz > 0.0 && impl_->cfg.rate_hz <= 10000.0))
    throw std::invalid_argument("NatNet server: rate must be in (0, 10000] Hz");
  if (!natnet::supported(impl_->cfg.version))
    throw std::invalid_argument("NatNet server: version must be 2.0 .. 4.x");
  impl_->open();
}

NatNetServer::~NatNetServer() = default;

int NatNetServer::command_port() const { return impl_->command.local_endpoint().port(); }

void NatNetServer::run_for(double duration_s) {
  impl_->start = std::chrono::steady_clock::now();
  impl_->receive();
  impl_->schedule(impl_->start);
  if (duration_s > 0) {
    impl_->deadline.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(duration_s)));
    impl_->deadline.async_wait([this](boost::system::error_code ec) {
      if (!ec) impl_->io.stop();
    });
  }
  impl_->io.run();
}

void NatNetServer::stop() { impl_->io.stop(); }

NatNetServerStats NatNetServer::stats() const {
  std::lock_guard lock(impl_->mu);
  return impl_->stats;
}

}  // namespace telex::sim
