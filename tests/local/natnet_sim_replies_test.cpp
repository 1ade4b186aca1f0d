// SPDX-License-Identifier: MIT
// telex-sim-natnet's command replies under every NatNet version it streams: the server info (268
// bytes for 2.x, 283 from 3.0 as Motive 2.1 sends it), the model definitions and the echo, each
// received over UDP, decoded with the project's parser and compared byte for byte with the
// reference layout written out here field by field (PacketClient.cpp's sSender / sSender_Server
// and Unpack of NAT_MODELDEF; NatNetClient.py 4.1 for the dataset byte counts).
#include <gtest/gtest.h>

#include <boost/asio.hpp>
#include <cstring>
#include <thread>
#include <vector>

#include "telex/natnet/natnet.h"
#include "telex/sim/natnet_server.h"

namespace telex::local {
namespace {

namespace asio = boost::asio;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;

// Little-endian field writers for the reference layouts.
void le(Bytes& b, std::uint64_t v, int n) {
  for (int i = 0; i < n; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void f32(Bytes& b, float f) {
  std::uint32_t u = 0;
  std::memcpy(&u, &f, 4);
  le(b, u, 4);
}
void cstr(Bytes& b, const std::string& s) {
  b.insert(b.end(), s.begin(), s.end());
  b.push_back(0);
}
Bytes packet(std::uint16_t id, const Bytes& payload) {
  Bytes b;
  le(b, id, 2);
  le(b, payload.size(), 2);
  b.insert(b.end(), payload.begin(), payload.end());
  return b;
}

Bytes reference_server_info(natnet::Version v, int data_port) {
  Bytes p(256, 0);
  const std::string name = "telex-sim-natnet";
  std::memcpy(p.data(), name.data(), name.size());
  for (std::uint8_t x : {1, 0, 0, 0}) p.push_back(x);  // app version
  for (int x : {v.major, v.minor, 0, 0}) p.push_back(static_cast<std::uint8_t>(x));
  if (v.major >= 3) {
    le(p, sim::kSimClockHz, 8);  // HighResClockFrequency
    le(p, static_cast<std::uint64_t>(data_port), 2);
    p.push_back(0);  // IsMulticast: the simulator streams unicast here
    for (std::uint8_t x : {239, 255, 42, 99}) p.push_back(x);
  }
  return packet(1, p);
}

Bytes reference_model_defs(natnet::Version v) {
  Bytes p;
  le(p, 3, 4);  // datasets
  for (std::int32_t id : {sim::kSimHeadId, sim::kSimRightHandId, sim::kSimRightShoulderId}) {
    le(p, 1, 4);  // type: rigid body
    Bytes d;
    if (v.major >= 2) cstr(d, sim::body_name(id));
    le(d, static_cast<std::uint32_t>(id), 4);
    le(d, 0xFFFFFFFFu, 4);  // parent id -1
    for (int i = 0; i < 3; ++i) f32(d, 0.0f);
    if (v.major >= 3) le(d, 0, 4);  // no markers
    if (v.at_least(4, 1)) le(p, d.size(), 4);
    p.insert(p.end(), d.begin(), d.end());
  }
  return packet(5, p);
}

class Exchange {
 public:
  explicit Exchange(int port) : socket_(io_, udp::endpoint(udp::v4(), 0)) {
    server_ = udp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port));
    socket_.non_blocking(true);
  }
  // The first reply to `request` that is not a frame of data.
  Bytes ask(const Bytes& request) {
    socket_.send_to(asio::buffer(request), server_);
    std::array<std::uint8_t, 65536> buf{};
    for (int i = 0; i < 4000; ++i) {
      boost::system::error_code ec;
      udp::endpoint from;
      const std::size_t n = socket_.receive_from(asio::buffer(buf), from, 0, ec);
      if (ec == asio::error::would_block) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        continue;
      }
      if (!ec && n >= 2 && buf[0] != natnet::kFrameOfData)
        return Bytes(buf.begin(), buf.begin() + static_cast<long>(n));
    }
    return {};
  }

 private:
  asio::io_context io_;
  udp::socket socket_;
  udp::endpoint server_;
};

TEST(NatNetSimReplies, EveryVersionAnswersInItsOwnLayoutByteForByte) {
  const std::vector<natnet::Version> versions = {{2, 0}, {2, 5}, {2, 9}, {2, 11},
                                                 {3, 0}, {3, 1}, {4, 0}, {4, 1}};
  for (const natnet::Version v : versions) {
    SCOPED_TRACE(std::to_string(v.major) + "." + std::to_string(v.minor));
    sim::NatNetServerConfig cfg;
    cfg.command_port = 0;
    cfg.version = v;
    cfg.rate_hz = 10.0;
    sim::NatNetServer server(cfg, sim::natnet_press_motion);
    std::thread run([&] { server.run_for(20.0); });
    Exchange ex(server.command_port());

    const Bytes info = ex.ask(natnet::make_ping("test"));
    EXPECT_EQ(info, reference_server_info(v, cfg.data_port));
    EXPECT_EQ(info.size(), v.major >= 3 ? 283u : 268u);
    natnet::PacketView pkt;
    ASSERT_TRUE(natnet::parse_packet(info, pkt).ok());
    natnet::ServerInfo si;
    ASSERT_TRUE(natnet::parse_server_info(pkt.payload, v, si).ok());
    EXPECT_EQ(si.natnet_version, v);
    EXPECT_EQ(si.has_connection_info, v.major >= 3);
    if (v.major >= 3) {
      EXPECT_EQ(si.high_res_clock_hz, sim::kSimClockHz);
      EXPECT_EQ(si.data_port, cfg.data_port);
      EXPECT_FALSE(si.multicast);
      EXPECT_EQ(si.multicast_group, (std::array<std::uint8_t, 4>{239, 255, 42, 99}));
    }

    const Bytes defs = ex.ask(natnet::make_packet(natnet::kRequestModelDef, {}));
    EXPECT_EQ(defs, reference_model_defs(v));
    ASSERT_TRUE(natnet::parse_packet(defs, pkt).ok());
    natnet::ModelDefs md;
    const auto st = natnet::parse_model_defs(pkt.payload, v, md);
    ASSERT_TRUE(st.ok()) << st.reason;
    ASSERT_EQ(md.rigid_bodies.size(), 3u);
    EXPECT_EQ(md.rigid_bodies[1].id, sim::kSimRightHandId);
    EXPECT_EQ(md.rigid_bodies[1].name, v.major >= 2 ? "right_hand" : "");

    Bytes echo_request;
    le(echo_request, 0x0123456789abcdefULL, 8);
    const Bytes echo = ex.ask(natnet::make_packet(natnet::kEchoRequest, echo_request));
    ASSERT_GE(echo.size(), 4u);
    if (v.major >= 3) {
      ASSERT_EQ(echo.size(), 20u);  // header, the client's stamp, the server's
      EXPECT_EQ(Bytes(echo.begin(), echo.begin() + 12),
                (Bytes{13, 0, 16, 0, 0xef, 0xcd, 0xab, 0x89, 0x67, 0x45, 0x23, 0x01}));
    } else {
      EXPECT_EQ(echo, (Bytes{100, 0, 0, 0}));  // no echo before 3.0: unrecognised
    }
    server.stop();
    run.join();
    const auto stats = server.stats();
    EXPECT_EQ(stats.pings_answered, 1u);
    EXPECT_EQ(stats.model_defs_answered, 1u);
    EXPECT_EQ(stats.echoes_answered, 1u);
  }
}

TEST(NatNetSimReplies, ALayoutReadAsAnotherVersionIsRejected) {
  natnet::ServerInfo info;
  info.natnet_version = {3, 1};
  const auto b3 = natnet::make_server_info(info);
  natnet::PacketView pkt;
  ASSERT_TRUE(natnet::parse_packet(b3, pkt).ok());
  natnet::ServerInfo got;
  EXPECT_STREQ(natnet::parse_server_info(pkt.payload, {2, 9}, got).reason,
               "bytes after a 2.x server info");
  info.natnet_version = {2, 9};
  const auto b2 = natnet::make_server_info(info);
  ASSERT_TRUE(natnet::parse_packet(b2, pkt).ok());
  EXPECT_STREQ(natnet::parse_server_info(pkt.payload, {3, 0}, got).reason,
               "3.0+ server info without its clock frequency, data port and multicast flag");

  natnet::ModelDefs defs;
  defs.rigid_bodies.push_back({"hand", 2, -1, {0.1f, 0.2f, 0.3f}});
  const auto d41 = natnet::make_model_defs(defs, {4, 1});
  ASSERT_TRUE(natnet::parse_packet(d41, pkt).ok());
  natnet::ModelDefs back;
  ASSERT_TRUE(natnet::parse_model_defs(pkt.payload, {4, 1}, back).ok());
  EXPECT_EQ(back.rigid_bodies, defs.rigid_bodies);
  EXPECT_FALSE(natnet::parse_model_defs(pkt.payload, {3, 1}, back).ok());
  EXPECT_FALSE(natnet::parse_model_defs(pkt.payload, {2, 9}, back).ok());
}

}  // namespace
}  // namespace telex::local
