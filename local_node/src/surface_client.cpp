// SPDX-License-Identifier: MIT
// Asio implementation of the operator-side client. One thread owns every socket and timer.
#include "telex/local/surface_client.h"

#include <algorithm>
#include <boost/asio.hpp>
#include <deque>
#include <thread>
#include <vector>

#include "telex/base/periodic.h"
#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"

namespace telex::local {

namespace asio = boost::asio;
using asio::ip::tcp;
using asio::ip::udp;

std::string_view to_string(ClientState s) {
  switch (s) {
    case ClientState::Connecting:
      return "connecting";
    case ClientState::Handshaking:
      return "handshaking";
    case ClientState::Streaming:
      return "streaming";
    case ClientState::Backoff:
      return "backoff";
    case ClientState::Stopped:
      return "stopped";
  }
  return "?";
}

struct SurfaceClient::Impl {
  Impl(ClientConfig c, ClientEvents e, ClientStats& s)
      : cfg(std::move(c)),
        ev(std::move(e)),
        stats(s),
        work(asio::make_work_guard(io)),
        tcp_sock(io),
        udp_sock(io),
        resolver(io),
        heartbeat_timer(io),
        retry_timer(io),
        parser(cfg.limits),
        dgram(cfg.limits),
        backoff_ns(cfg.backoff_min_ns) {}

  ClientConfig cfg;
  ClientEvents ev;
  ClientStats& stats;
  asio::io_context io;
  asio::executor_work_guard<asio::io_context::executor_type> work;
  tcp::socket tcp_sock;
  udp::socket udp_sock;
  tcp::resolver resolver;
  asio::steady_timer heartbeat_timer;
  asio::steady_timer retry_timer;
  ThreadFault fault{"network (telex-net)"};
  std::thread thread;

  proto::StreamParser parser;
  proto::DatagramParser dgram;
  proto::Reassembler reassembler;
  std::uint64_t udp_lost_counted = 0;  // of this reassembler's lost(), already in stats.udp_lost
  std::array<std::uint64_t, 8> by_fragments_counted{};  // the same for messages_by_fragments
  std::array<std::uint8_t, 64 * 1024> tcp_buf{};
  std::array<std::uint8_t, 2048> udp_buf{};
  udp::endpoint udp_from;
  static constexpr std::size_t kMaxQueued = 64;
  std::deque<std::vector<std::uint8_t>> out_queue;  // front: being written while `writing`
  bool writing = false;

  // Authentication: the pre-shared key until Accept, then the session key (null without --psk).
  const proto::AuthKey* psk() const { return cfg.psk ? &*cfg.psk : nullptr; }
  std::optional<proto::AuthKey> session_key;
  std::uint64_t hello_nonce = 0;
  std::uint64_t conn_auth_failed = 0, conn_unexpected_tag = 0;  // on this connection
  std::string conn_auth_detail;
  std::int64_t last_warning_ns = 0;

  std::uint64_t generation = 0;  // bumps on every (re)connect so stale handlers bail out
  std::uint32_t session_id = 0;
  std::uint32_t seq = 0;
  std::int64_t last_rx_ns = 0;
  std::int64_t backoff_ns;
  bool stopping = false;
  tcp::endpoint remote_tcp;

  void set_state(ClientState s, const std::string& why) {
    stats.state.store(static_cast<std::uint8_t>(s));
    if (ev.on_state) ev.on_state(s, why);
  }

  const proto::AuthKey* tx_key() const { return session_key ? &*session_key : psk(); }

  void send(const proto::Message& m) {
    proto::Header h;
    h.session_id = session_id;
    h.seq = seq++;
    h.capture_ns = static_cast<std::uint64_t>(monotonic_ns());
    // With a key, Hello's capture_ns is the client nonce of the session key (it has no capture).
    if (cfg.psk && std::holds_alternative<proto::Hello>(m)) h.capture_ns = hello_nonce;
    out_queue.push_back(proto::encode_stream_sealed(h, m, tx_key()));
    // A stuck link must not grow memory: past kMaxQueued drop the oldest message still waiting.
    // Never the front while a write is in flight: async_write reads that buffer until its handler
    // runs, and the handler pops it.
    if (out_queue.size() > kMaxQueued) {
      out_queue.erase(out_queue.begin() + (writing ? 1 : 0));
      stats.upstream_dropped.fetch_add(1);
    }
    if (!writing) write_next();
  }

  void write_next() {
    if (out_queue.empty() || !tcp_sock.is_open()) {
      writing = false;
      return;
    }
    writing = true;
    const auto gen = generation;
    asio::async_write(tcp_sock, asio::buffer(out_queue.front()),
                      [this, gen](boost::system::error_code ec, std::size_t) {
                        if (gen != generation) return;
                        if (!out_queue.empty()) out_queue.pop_front();
                        if (ec) return disconnect("write failed: " + ec.message());
                        write_next();
                      });
  }

  void connect() {
    if (stopping) return;
    ++generation;
    set_state(ClientState::Connecting, cfg.host + ":" + std::to_string(cfg.port));
    const auto gen = generation;
    resolver.async_resolve(
        cfg.host, std::to_string(cfg.port),
        [this, gen](boost::system::error_code ec, tcp::resolver::results_type results) {
          if (gen != generation || stopping) return;
          if (ec) return retry("cannot resolve " + cfg.host + ": " + ec.message());
          asio::async_connect(tcp_sock, results,
                              [this, gen](boost::system::error_code ec2, const tcp::endpoint& ep) {
                                if (gen != generation || stopping) return;
                                if (ec2) return retry("cannot connect: " + ec2.message());
                                on_connected(ep);
                              });
        });
  }

  void on_connected(const tcp::endpoint& ep) {
    remote_tcp = ep;
    stats.connects.fetch_add(1);
    boost::system::error_code ec;
    tcp_sock.set_option(tcp::no_delay(true), ec);
    parser = proto::StreamParser(cfg.limits);
    dgram = proto::DatagramParser(cfg.limits);
    parser.set_key(cfg.psk);
    reassembler = proto::Reassembler();
    udp_lost_counted = 0;
    by_fragments_counted = {};
    session_id = 0;
    session_key.reset();
    conn_auth_failed = conn_unexpected_tag = 0;
    conn_auth_detail.clear();
    if (cfg.psk) hello_nonce = proto::random_u64();
    std::uint16_t udp_port = 0;
    if (cfg.use_udp) {
      // Receive UDP on the interface the TCP session uses, so loopback stays loopback.
      udp_sock.open(ep.protocol() == tcp::v4() ? udp::v4() : udp::v6(), ec);
      if (!ec) udp_sock.set_option(asio::socket_base::receive_buffer_size(4 << 20), ec);
      if (!ec)
        udp_sock.bind(udp::endpoint(tcp_sock.local_endpoint().address(), cfg.udp_bind_port), ec);
      if (ec) return disconnect("cannot open UDP socket: " + ec.message());
      udp_port =
          cfg.udp_announce_port != 0 ? cfg.udp_announce_port : udp_sock.local_endpoint().port();
      udp_receive();
    }
    set_state(ClientState::Handshaking, "connected to " + ep.address().to_string());
    last_rx_ns = monotonic_ns();
    proto::Hello hello;
    hello.capabilities =
        proto::kCapDepthTcp | proto::kCapRoi | proto::kCapStats |
        (cfg.frame_parts ? proto::kCapFrameParts : 0u) | (cfg.repair ? proto::kCapRepair : 0u) |
        (cfg.use_udp ? proto::kCapDepthUdp : 0u) | (cfg.want_video ? proto::kCapVideo : 0u);
    hello.codecs = {proto::Codec::Zip, proto::Codec::Fast, proto::Codec::Raw};
    hello.udp_port = udp_port;
    send(hello);
    tcp_read();
    arm_heartbeat();
  }

  void tcp_read() {
    const auto gen = generation;
    tcp_sock.async_read_some(
        asio::buffer(tcp_buf), [this, gen](boost::system::error_code ec, std::size_t n) {
          if (gen != generation) return;
          if (ec)
            return disconnect(ec == asio::error::eof ? "remote closed the connection"
                                                     : "read failed: " + ec.message());
          stats.bytes_in.fetch_add(n);
          std::span<const std::uint8_t> rest(tcp_buf.data(), n);
          while (true) {
            const std::size_t took = parser.feed(rest);
            rest = rest.subspan(took);
            while (auto r = parser.next()) {
              if (!r->ok()) {
                count_drop(*r, "TCP");
                continue;
              }
              handle(*r->envelope);
              if (gen != generation) return;  // handling disconnected us
            }
            if (parser.failed()) return disconnect("malformed stream from remote");
            if (rest.empty() || took == 0) break;
          }
          tcp_read();
        });
  }

  void udp_receive() {
    const auto gen = generation;
    udp_sock.async_receive_from(asio::buffer(udp_buf), udp_from,
                                [this, gen](boost::system::error_code ec, std::size_t n) {
                                  if (gen != generation || !udp_sock.is_open()) return;
                                  if (!ec)
                                    on_datagram(std::span<const std::uint8_t>(udp_buf.data(), n));
                                  if (ec == asio::error::operation_aborted) return;
                                  udp_receive();
                                });
  }

  void on_datagram(std::span<const std::uint8_t> d) {
    stats.datagrams.fetch_add(1);
    stats.bytes_in.fetch_add(d.size());
    if (udp_from.address() != remote_tcp.address()) {
      stats.dropped_foreign.fetch_add(1);
      return;
    }
    if (cfg.psk) {
      // Datagrams exist only inside a session and carry tags under its key; the reassembler sees
      // only authentic fragments, so forged ones cannot evict or supersede real frames.
      if (!session_key) {
        stats.dropped_foreign.fetch_add(1);
        return;
      }
      const auto body = proto::verify_and_strip(d, *session_key);
      if (!body) {
        proto::Result bad;
        bad.error = proto::ErrorReason::AuthFailed;
        bad.detail = "datagram tag does not verify";
        count_drop(bad, "UDP");
        return;
      }
      d = *body;
    }
    const auto now = static_cast<std::uint64_t>(monotonic_ns());
    const auto before = reassembler.counters().malformed;
    auto whole = reassembler.push(d, now);
    stats.udp_lost.fetch_add(reassembler.counters().lost() - udp_lost_counted);
    udp_lost_counted = reassembler.counters().lost();
    for (std::size_t n = 0; n < by_fragments_counted.size(); ++n) {
      const auto seen = reassembler.counters().messages_by_fragments[n];
      stats.udp_messages_by_fragments[n].fetch_add(seen - by_fragments_counted[n]);
      by_fragments_counted[n] = seen;
    }
    if (whole) {
      auto r = dgram.parse(*whole);
      if (!r.ok()) {
        count_drop(r, "UDP");
        return;
      }
      handle(*r.envelope);
    } else if (reassembler.counters().malformed != before) {
      stats.dropped_malformed.fetch_add(1);
    }
  }

  // Counts a rejected message by reason; warns at most once a second.
  void count_drop(const proto::Result& r, const char* transport) {
    switch (r.error) {
      case proto::ErrorReason::AuthFailed:
        stats.auth_failed.fetch_add(1);
        ++conn_auth_failed;
        conn_auth_detail = r.detail;
        break;
      case proto::ErrorReason::UnexpectedTag:
        stats.unexpected_tag.fetch_add(1);
        ++conn_unexpected_tag;
        break;
      case proto::ErrorReason::Replayed:
        stats.replayed.fetch_add(1);
        break;
      default:
        stats.dropped_malformed.fetch_add(1);
        break;
    }
    const auto now = monotonic_ns();
    if (ev.on_warning && now - last_warning_ns > 1'000'000'000) {
      last_warning_ns = now;
      ev.on_warning("dropped a " + std::string(transport) + " message from the remote: " +
                    std::string(proto::error_reason_name(r.error)) + " (" + r.detail +
                    "); totals: auth_failed " + std::to_string(stats.auth_failed.load()) +
                    " unexpected_tag " + std::to_string(stats.unexpected_tag.load()) +
                    " replayed " + std::to_string(stats.replayed.load()) + " malformed " +
                    std::to_string(stats.dropped_malformed.load()));
    }
  }

  // What authentication failures on this connection say about the keys, for the state reason.
  std::string auth_hint() const {
    if (conn_unexpected_tag > 0)
      return "; the remote's messages carry authentication tags but this station has no --psk "
             "key: start telex-local with the remote's --psk FILE";
    if (conn_auth_failed > 0 && session_id == 0) {
      if (conn_auth_detail == "message has no tag")
        return "; the remote's messages carry no authentication tag: start telex-remote with the "
               "same --psk FILE as telex-local";
      return "; " + std::to_string(conn_auth_failed) +
             " message(s) from the remote failed authentication: the two daemons' --psk keys "
             "differ";
    }
    return "";
  }

  void handle(const proto::Envelope& env) {
    last_rx_ns = monotonic_ns();
    stats.messages.fetch_add(1);
    const auto& h = env.header;
    if (session_id != 0 && h.session_id != session_id &&
        !std::holds_alternative<proto::Accept>(env.message)) {
      stats.dropped_foreign.fetch_add(1);
      return;
    }
    std::visit(
        [&](const auto& m) {
          using T = std::decay_t<decltype(m)>;
          if constexpr (std::is_same_v<T, proto::Accept>) {
            if (session_id != 0) {  // one Accept per connection; a second is not the remote's
              stats.dropped_foreign.fetch_add(1);
              return;
            }
            session_id = m.session_id;
            if (cfg.psk) {
              session_key =
                  proto::derive_session_key(*cfg.psk, hello_nonce, h.capture_ns, m.session_id);
              parser.set_key(session_key);
              dgram.set_key(session_key);
            }
            backoff_ns = cfg.backoff_min_ns;
            set_state(ClientState::Streaming,
                      "session " + std::to_string(m.session_id) + ", " +
                          (m.transport == proto::Transport::Udp ? "udp" : "tcp") + ", " +
                          std::string(proto::codec_name(m.codec)));
          } else if constexpr (std::is_same_v<T, proto::Reject>) {
            stats.rejects.fetch_add(1);
            disconnect("remote refused: " + m.text);
          } else if constexpr (std::is_same_v<T, proto::Heartbeat>) {
            on_heartbeat(m);
          } else if constexpr (std::is_same_v<T, proto::Bye>) {
            disconnect("remote said bye");
          } else if constexpr (std::is_same_v<T, proto::StreamConfig>) {
            parser.set_frame_size(m.width, m.height);
            dgram.set_frame_size(m.width, m.height);
            if (ev.on_config) ev.on_config(m);
          } else if constexpr (std::is_same_v<T, proto::DepthTile>) {
            if (ev.on_tile) ev.on_tile(h, m);
          } else if constexpr (std::is_same_v<T, proto::FrameManifest>) {
            if (ev.on_manifest) ev.on_manifest(h, m);
          } else if constexpr (std::is_same_v<T, proto::VideoFrame>) {
            if (ev.on_video) ev.on_video(h, m);
          }
        },
        env.message);
  }

  void on_heartbeat(const proto::Heartbeat& hb) {
    const auto now = static_cast<std::uint64_t>(monotonic_ns());
    if (hb.t2_ns == 0) {
      // The remote's own probe: answer with our receive and send times.
      send(proto::Heartbeat{hb.t1_ns, now, static_cast<std::uint64_t>(monotonic_ns()), 0});
      return;
    }
    // Our probe answered: RFC 5905 offset and round-trip delay.
    stats.heartbeats.fetch_add(1);
    const auto t1 = static_cast<std::int64_t>(hb.t1_ns), t2 = static_cast<std::int64_t>(hb.t2_ns),
               t3 = static_cast<std::int64_t>(hb.t3_ns), t4 = static_cast<std::int64_t>(now);
    stats.clock_offset_ns.store(((t2 - t1) + (t3 - t4)) / 2);
    stats.rtt_ns.store((t4 - t1) - (t3 - t2));
  }

  void arm_heartbeat() {
    const auto gen = generation;
    heartbeat_timer.expires_after(std::chrono::nanoseconds(cfg.heartbeat_ns));
    heartbeat_timer.async_wait([this, gen](boost::system::error_code ec) {
      if (ec || gen != generation) return;
      if (monotonic_ns() - last_rx_ns > cfg.timeout_ns)
        return disconnect("remote silent for " + std::to_string(cfg.timeout_ns / 1'000'000) +
                          " ms");
      // Probes start with the session: before Accept there is no session key to tag them with.
      if (session_id != 0)
        send(proto::Heartbeat{static_cast<std::uint64_t>(monotonic_ns()), 0, 0, 0});
      arm_heartbeat();
    });
  }

  void close_sockets() {
    boost::system::error_code ec;
    heartbeat_timer.cancel();
    if (tcp_sock.is_open()) {
      tcp_sock.shutdown(tcp::socket::shutdown_both, ec);
      tcp_sock.close(ec);
    }
    if (udp_sock.is_open()) udp_sock.close(ec);
    out_queue.clear();
    writing = false;
  }

  void disconnect(const std::string& why_in) {
    const std::string why = why_in + auth_hint();
    ++generation;
    stats.disconnects.fetch_add(1);
    close_sockets();
    retry(why);
  }

  void retry(const std::string& why) {
    if (stopping) return;
    set_state(ClientState::Backoff,
              why + "; retrying in " + std::to_string(backoff_ns / 1'000'000) + " ms");
    retry_timer.expires_after(std::chrono::nanoseconds(backoff_ns));
    backoff_ns = std::min(backoff_ns * 2, cfg.backoff_max_ns);
    const auto gen = ++generation;
    retry_timer.async_wait([this, gen](boost::system::error_code ec) {
      if (ec || gen != generation) return;
      close_sockets();
      connect();
    });
  }
};

SurfaceClient::SurfaceClient(ClientConfig config, ClientEvents events)
    : impl_(std::make_unique<Impl>(std::move(config), std::move(events), stats_)) {}

SurfaceClient::~SurfaceClient() { stop(); }

void SurfaceClient::start() {
  if (impl_->thread.joinable()) return;
  asio::post(impl_->io, [this] { impl_->connect(); });
  impl_->thread = std::thread([this] { impl_->fault.run([this] { impl_->io.run(); }); });
  name_thread(impl_->thread.native_handle(), "telex-net");
  scheduling_ = try_realtime(impl_->thread.native_handle(), impl_->cfg.realtime_priority);
}

void SurfaceClient::stop() {
  if (!impl_->thread.joinable()) return;
  asio::post(impl_->io, [this] {
    impl_->stopping = true;
    if (impl_->tcp_sock.is_open() && impl_->session_id != 0) {
      // Best effort goodbye; the socket closes right after.
      boost::system::error_code ec;
      proto::Header h;
      h.session_id = impl_->session_id;
      h.seq = impl_->seq++;
      auto bytes = proto::encode_stream_sealed(h, proto::Bye{0}, impl_->tx_key());
      asio::write(impl_->tcp_sock, asio::buffer(bytes), ec);
    }
    ++impl_->generation;
    impl_->retry_timer.cancel();
    impl_->resolver.cancel();
    impl_->close_sockets();
    impl_->work.reset();
    impl_->set_state(ClientState::Stopped, "stopped");
  });
  impl_->thread.join();
}

std::optional<ThreadFaultReport> SurfaceClient::thread_fault() const {
  return impl_->fault.report();
}

void SurfaceClient::request_roi(const proto::RoiRequest& roi) {
  asio::post(impl_->io, [this, roi] {
    if (impl_->session_id != 0 && impl_->tcp_sock.is_open()) impl_->send(roi);
  });
}

void SurfaceClient::send_nack(const proto::TileNack& nack) {
  asio::post(impl_->io, [this, nack] {
    if (impl_->session_id != 0 && impl_->tcp_sock.is_open()) impl_->send(nack);
  });
}

void SurfaceClient::send_head(const proto::HeadCommand& head) {
  asio::post(impl_->io, [this, head] {
    if (impl_->session_id != 0 && impl_->tcp_sock.is_open()) impl_->send(head);
  });
}

void SurfaceClient::request_key_frame() {
  asio::post(impl_->io, [this] {
    if (impl_->session_id != 0 && impl_->tcp_sock.is_open())
      impl_->send(proto::Stats{{{"key_frame_request", 1}}});
  });
}

}  // namespace telex::local
