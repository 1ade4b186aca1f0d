// SPDX-License-Identifier: MIT
// A minimal operator for tests: TCP control, UDP or TCP depth, reassembles frames with proto only.
#pragma once

#include <boost/asio.hpp>
#include <chrono>
#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "telex/proto/depth_codec.h"
#include "telex/proto/fragment.h"
#include "telex/proto/messages.h"
#include "telex/proto/parser.h"

namespace telex::remote::test {

struct ReceivedFrame {
  cv::Mat1w depth_mm;  // the receiver's whole frame after this frame's manifest
  bool key_frame = false;
  std::size_t tiles = 0;
  std::size_t wire_bytes = 0;  // datagrams (UDP) or stream bytes (TCP) carrying this frame
};

class TestClient {
 public:
  // Connects and sends Hello. `udp` offers a UDP port; `capabilities` adds to the depth bits.
  TestClient(std::uint16_t port, bool udp, std::uint32_t extra_caps = 0)
      : tcp_(io_), udp_(io_), reassembler_() {
    namespace asio = boost::asio;
    tcp_.connect({asio::ip::make_address("127.0.0.1"), port});
    proto::Hello hello;
    hello.capabilities = proto::kCapDepthTcp | extra_caps;
    hello.codecs = {proto::Codec::Zip, proto::Codec::Fast};
    if (udp) {
      udp_.open(asio::ip::udp::v4());
      udp_.bind({asio::ip::make_address("127.0.0.1"), 0});
      udp_.set_option(asio::socket_base::receive_buffer_size(8 << 20));
      hello.capabilities |= proto::kCapDepthUdp;
      hello.udp_port = udp_.local_endpoint().port();
      read_udp();
    }
    send(hello);
    read_tcp();
  }

  template <typename M>
  void send(const M& m) {
    proto::Header h;
    h.session_id = accept_ ? accept_->session_id : 0;
    h.seq = seq_++;
    auto bytes = std::make_shared<std::vector<std::uint8_t>>(proto::encode_stream(h, m));
    boost::asio::write(tcp_, boost::asio::buffer(*bytes));
  }
  void send_raw(const std::vector<std::uint8_t>& bytes) {
    boost::asio::write(tcp_, boost::asio::buffer(bytes));
  }

  // Runs the client's io until `done()` or the deadline; true when done.
  template <typename Pred>
  bool run_until(Pred done, std::chrono::milliseconds deadline) {
    const auto end = std::chrono::steady_clock::now() + deadline;
    while (!done()) {
      if (std::chrono::steady_clock::now() >= end) return false;
      io_.run_for(std::chrono::milliseconds(20));
      if (io_.stopped()) io_.restart();
    }
    return true;
  }

  // Caps the TCP socket's receive buffer (SO_RCVBUF; Linux stops autotuning it): a client that
  // stops reading then stalls the remote's writes after that much, not after tcp_rmem's maximum.
  void cap_receive_buffer(int bytes) {
    tcp_.set_option(boost::asio::socket_base::receive_buffer_size(bytes));
  }

  void close() {
    boost::system::error_code ec;
    tcp_.close(ec);
    udp_.close(ec);
  }

  std::optional<proto::Accept> accept_;
  std::optional<proto::Reject> reject_;
  std::optional<proto::StreamConfig> config_;
  std::vector<proto::Heartbeat> heartbeats_;  // answers to this client's probes
  std::vector<proto::EncodedVideo> video_;
  std::map<std::uint32_t, ReceivedFrame> frames_;
  std::uint64_t decode_errors_ = 0;
  std::string last_error_;
  bool tcp_closed_ = false;
  const proto::ReassemblerCounters& reassembly() const { return reassembler_.counters(); }

 private:
  void read_tcp() {
    tcp_.async_read_some(
        boost::asio::buffer(rx_), [this](boost::system::error_code ec, std::size_t n) {
          if (ec) {
            tcp_closed_ = true;
            return;
          }
          std::size_t off = 0;
          while (off < n) {
            const std::size_t took =
                parser_.feed(std::span<const std::uint8_t>(rx_.data() + off, n - off));
            off += took;
            while (auto r = parser_.next()) {
              if (!r->ok()) {
                ++decode_errors_;
                last_error_ = std::string("tcp: ") + r->detail;
                continue;
              }
              const auto& env = *r->envelope;
              std::size_t bytes = proto::kHeaderSize + 4 + env.header.payload_len;
              handle(env, bytes);
            }
            if (took == 0) break;
          }
          read_tcp();
        });
  }

  void read_udp() {
    udp_.async_receive_from(
        boost::asio::buffer(udp_rx_), peer_, [this](boost::system::error_code ec, std::size_t n) {
          if (ec) return;
          const auto now = static_cast<std::uint64_t>(
              std::chrono::steady_clock::now().time_since_epoch().count());
          pending_wire_ += n;
          if (auto msg = reassembler_.push(std::span<const std::uint8_t>(udp_rx_.data(), n), now)) {
            auto r = dgram_.parse(*msg);
            if (r.ok()) {
              const std::size_t bytes = pending_wire_;
              pending_wire_ = 0;
              handle(*r.envelope, bytes);
            } else {
              ++decode_errors_;
              last_error_ = std::string("udp: ") + r.detail;
            }
          }
          read_udp();
        });
  }

  void handle(const proto::Envelope& env, std::size_t wire_bytes) {
    // StreamConfig comes over TCP, tiles over UDP: tiles may overtake it and wait for it here.
    const bool is_config = std::holds_alternative<proto::StreamConfig>(env.message);
    if (!config_ && !is_config &&
        (std::holds_alternative<proto::DepthTile>(env.message) ||
         std::holds_alternative<proto::FrameManifest>(env.message))) {
      early_.emplace_back(env, wire_bytes);
      return;
    }
    dispatch(env, wire_bytes);
    if (is_config) {
      auto early = std::move(early_);
      early_.clear();
      for (const auto& [e, b] : early) dispatch(e, b);
    }
  }

  void dispatch(const proto::Envelope& env, std::size_t wire_bytes) {
    std::visit(
        [&](const auto& m) {
          using T = std::decay_t<decltype(m)>;
          if constexpr (std::is_same_v<T, proto::Accept>) {
            accept_ = m;
          } else if constexpr (std::is_same_v<T, proto::Reject>) {
            reject_ = m;
          } else if constexpr (std::is_same_v<T, proto::StreamConfig>) {
            config_ = m;
            grid_ = proto::TileGrid{m.width, m.height, m.tile_width, m.tile_height};
            if (frame_.rows != m.height || frame_.cols != m.width)
              frame_ = cv::Mat1w(m.height, m.width, std::uint16_t(0));
          } else if constexpr (std::is_same_v<T, proto::Heartbeat>) {
            // The remote's own probes are answered as the station answers them (its clock is
            // this host's steady clock); answers to ours are kept.
            if (m.t2_ns == 0) {
              const auto now = static_cast<std::uint64_t>(
                  std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::chrono::steady_clock::now().time_since_epoch())
                      .count());
              send(proto::Heartbeat{m.t1_ns, now, now, 0});
            } else {
              heartbeats_.push_back(m);
            }
          } else if constexpr (std::is_same_v<T, proto::EncodedVideo>) {
            video_.push_back(m);
          } else if constexpr (std::is_same_v<T, proto::DepthTile>) {
            current_bytes_ += wire_bytes;
            if (!config_ || proto::decode_tile_into(m.payload, grid_, m.tile_index, m.codec,
                                                    frame_) != proto::DecodeStatus::Ok) {
              ++decode_errors_;
              last_error_ = "tile " + std::to_string(m.tile_index) + " did not decode";
            } else
              ++current_tiles_;
          } else if constexpr (std::is_same_v<T, proto::FrameManifest>) {
            ReceivedFrame f;
            f.depth_mm = frame_.clone();
            f.key_frame = m.key_frame;
            f.tiles = current_tiles_;
            f.wire_bytes = current_bytes_ + wire_bytes;
            frames_[m.frame_id] = std::move(f);
            current_tiles_ = 0;
            current_bytes_ = 0;
          }
        },
        env.message);
  }

  boost::asio::io_context io_;
  boost::asio::ip::tcp::socket tcp_;
  boost::asio::ip::udp::socket udp_;
  boost::asio::ip::udp::endpoint peer_;
  std::array<std::uint8_t, 65536> rx_{};
  std::array<std::uint8_t, 2048> udp_rx_{};
  proto::StreamParser parser_;
  proto::DatagramParser dgram_;
  proto::Reassembler reassembler_;
  proto::TileGrid grid_;
  cv::Mat1w frame_;
  std::size_t current_tiles_ = 0, current_bytes_ = 0, pending_wire_ = 0;
  std::vector<std::pair<proto::Envelope, std::size_t>> early_;
  std::uint32_t seq_ = 0;
};

}  // namespace telex::remote::test
