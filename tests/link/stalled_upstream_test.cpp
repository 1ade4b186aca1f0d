// SPDX-License-Identifier: MIT
// A remote that stops reading: the station's upstream queue stays bounded, drops only messages
// still waiting (never the one async_write is writing), and what does arrive is whole and in order.
// Head commands do not pile up (issue 49): a waiting one is replaced by the newest, and the link's
// small send buffer keeps the kernel's backlog to a few hundred commands, not megabytes.
#include <gtest/gtest.h>

#include <boost/asio.hpp>
#include <chrono>
#include <thread>
#include <vector>

#include "telex/local/link/surface_client.h"
#include "telex/proto/parser.h"

namespace telex::local {
namespace {

namespace asio = boost::asio;
using asio::ip::tcp;

// Reads from `sock` until `want` returns true for a parsed message or the stream ends; every
// message must parse.
template <typename Want>
void read_messages(tcp::socket& sock, proto::StreamParser& parser, Want want) {
  std::array<std::uint8_t, 16 * 1024> buf{};
  while (true) {
    boost::system::error_code ec;
    const std::size_t n = sock.read_some(asio::buffer(buf), ec);
    ASSERT_FALSE(ec) << "the station closed the stream: " << ec.message();
    std::span<const std::uint8_t> rest(buf.data(), n);
    while (!rest.empty()) {
      const std::size_t took = parser.feed(rest);
      rest = rest.subspan(took);
      while (auto r = parser.next()) {
        ASSERT_TRUE(r->ok()) << "corrupt message from the station: "
                             << proto::error_reason_name(r->error) << " (" << r->detail << ")";
        if (want(*r->envelope)) return;
      }
      ASSERT_FALSE(parser.failed());
      if (took == 0) break;
    }
  }
}

TEST(StalledUpstream, QueueDropsWaitingMessagesNeverTheOneBeingWritten) {
  asio::io_context io;
  tcp::acceptor acceptor(io);
  acceptor.open(tcp::v4());
  // A small receive window (inherited by the accepted socket) so the station's writes stall soon.
  acceptor.set_option(asio::socket_base::receive_buffer_size(4096));
  acceptor.bind({asio::ip::make_address("127.0.0.1"), 0});
  acceptor.listen();

  ClientConfig cfg;
  cfg.port = acceptor.local_endpoint().port();
  cfg.use_udp = false;
  cfg.timeout_ns = 120'000'000'000;      // this remote is silent on purpose
  cfg.heartbeat_ns = 3'600'000'000'000;  // no probes: every message sent is a head command
  SurfaceClient client(cfg, {});
  client.start();

  tcp::socket sock(io);
  acceptor.accept(sock);
  proto::StreamParser parser;
  bool hello = false;
  read_messages(sock, parser, [&](const proto::Envelope& e) {
    hello = std::holds_alternative<proto::Hello>(e.message);
    return true;
  });
  ASSERT_TRUE(hello);
  proto::Header h;
  h.session_id = 77;
  proto::Accept accept;
  accept.session_id = 77;
  asio::write(sock, asio::buffer(proto::encode_stream(h, accept)));
  for (int i = 0; i < 2000 && client.state() != ClientState::Streaming; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_EQ(client.state(), ClientState::Streaming);

  // Far more than the socket buffers hold (about 9 MB), in batches with pauses between them so
  // the network thread writes each batch out until the kernel's buffers are full: from then on
  // the write in flight is blocked (EAGAIN) with its buffer still in use while the queue keeps
  // taking head commands, the case that freed that buffer. Each command's operator_ns is its
  // index + 1.
  constexpr std::uint64_t kCommands = 150'000, kBatch = 1500;
  for (std::uint64_t i = 0; i < kCommands; ++i) {
    proto::HeadCommand c;
    c.operator_ns = i + 1;
    c.joint_rad = {0.001f * static_cast<float>(i % 1000), 0.0f, 0.0f};
    client.send_head(c);
    if ((i + 1) % kBatch == 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }

  // Now read everything: whole messages, head commands in order, the newest one last.
  std::uint64_t received = 0, last = 0;
  bool in_order = true;
  read_messages(sock, parser, [&](const proto::Envelope& e) {
    const auto* c = std::get_if<proto::HeadCommand>(&e.message);
    if (c == nullptr) return false;
    ++received;
    in_order = in_order && c->operator_ns > last;
    last = c->operator_ns;
    return last == kCommands;
  });
  const std::uint64_t dropped = client.stats().upstream_dropped.load();
  client.stop();

  EXPECT_TRUE(in_order);
  EXPECT_EQ(last, kCommands);
  EXPECT_GT(dropped, 0u) << "the upstream never stalled: the test did not reach the drop path";
  EXPECT_LT(received, kCommands);
  // What arrives is what the kernel held when the reader stalled (the station's 16 KiB send
  // buffer, doubled by Linux, and this reader's small receive window) plus the newest: before the
  // small send buffer and the replacing queue, 6,570 of the 150,000 arrived here (207 after).
  EXPECT_LT(received, 2000u);
  // Every command either arrived once or was counted as dropped.
  EXPECT_EQ(received + dropped, kCommands);
  std::printf("stalled upstream: %llu head commands sent, %llu arrived, %llu dropped\n",
              static_cast<unsigned long long>(kCommands), static_cast<unsigned long long>(received),
              static_cast<unsigned long long>(dropped));
}

}  // namespace
}  // namespace telex::local
