// SPDX-License-Identifier: MIT
// Asio implementation of the operator-side client. One thread owns every socket and timer.
#include "telex/local/link/surface_client.h"

#include <algorithm>
#include <boost/asio.hpp>
#include <thread>
#include <vector>

#include "link_drops.h"
#include "telex/base/periodic.h"
#include "telex/local/link/receiver_report.h"
#include "telex/proto/fragment.h"
#include "telex/proto/link_stream.h"
#include "telex/proto/parser.h"
#include "telex/proto/seal.h"
#include "upstream_queue.h"

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
        tls_ctx(make_tls(cfg.tls)),
        tcp_sock(io),
        udp_sock(io),
        heartbeat_timer(io),
        alive_timer(io),
        retry_timer(io),
        parser(cfg.limits),
        dgram(cfg.limits),
        backoff_ns(cfg.backoff_min_ns) {}

  ClientConfig cfg;
  ClientEvents ev;
  ClientStats& stats;
  asio::io_context io;
  asio::executor_work_guard<asio::io_context::executor_type> work;
  // With a key or certificates; main() has loaded them once already, so bad files exit 2 there.
  std::optional<asio::ssl::context> tls_ctx;
  tcp::socket tcp_sock;                     // while connecting; then moved into `link`
  std::shared_ptr<proto::LinkStream> link;  // the connection: TLS or plain
  udp::socket udp_sock;
  asio::steady_timer heartbeat_timer;
  asio::steady_timer alive_timer;
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
  // The kernel's send buffer for the link (SO_SNDBUF; Linux doubles it): the upstream is small
  // (head commands at 200 Hz, NACKs, reports), and what the kernel holds during a stall arrives
  // as a burst of old head targets afterwards. 16 KiB still leaves a window of 160 KB/s at a
  // 200 ms round trip.
  static constexpr int kUpstreamSendBuffer = 16 * 1024;
  UpstreamQueue out_queue;
  bool writing = false;

  // With TLS, after the handshake: opens the remote's datagrams (remote->station key).
  std::unique_ptr<proto::DatagramOpener> opener;
  std::vector<std::uint8_t> udp_plain;
  bool handshake_failed = false;  // on this connection, or the remote said why (Reject)
  std::int64_t last_warning_ns = 0;
  ReceiverReportBuilder report;  // the remote's datagrams since the last ReceiverReport

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

  static std::optional<asio::ssl::context> make_tls(const proto::TlsConfig& t) {
    if (!t.enabled()) return std::nullopt;
    return std::optional<asio::ssl::context>(std::in_place,
                                             proto::make_tls_context(t, proto::TlsRole::Client));
  }
  bool link_open() const { return link && link->is_open(); }

  void send(const proto::Message& m) {
    proto::Header h;
    h.session_id = session_id;
    h.seq = seq++;
    h.capture_ns = static_cast<std::uint64_t>(monotonic_ns());
    using Kind = UpstreamQueue::Kind;
    const auto* probe = std::get_if<proto::Heartbeat>(&m);
    const Kind kind = std::holds_alternative<proto::HeadCommand>(m) ? Kind::Head
                      : probe != nullptr && probe->t2_ns == 0       ? Kind::Probe
                                                                    : Kind::Kept;
    stats.upstream_dropped.fetch_add(out_queue.push(proto::encode_stream(h, m), kind, writing));
    if (!writing) write_next();
  }

  void write_next() {
    if (out_queue.empty() || !link_open()) {
      writing = false;
      return;
    }
    writing = true;
    const auto gen = generation;
    // The handler keeps the stream alive: a TLS stream must outlive its operations.
    link->async_write(asio::buffer(out_queue.front()),
                      [this, gen, keep = link](boost::system::error_code ec, std::size_t) {
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
    // The addresses resolved (and checked) at start; a config made in code resolves here.
    std::vector<tcp::endpoint> endpoints;
    try {
      for (const auto& a : cfg.addresses.empty() ? proto::resolve_host(cfg.host) : cfg.addresses)
        endpoints.emplace_back(asio::ip::make_address(a), cfg.port);
    } catch (const std::exception& e) {
      return retry(e.what());
    }
    asio::async_connect(tcp_sock, endpoints,
                        [this, gen](boost::system::error_code ec, const tcp::endpoint& ep) {
                          if (gen != generation || stopping) return;
                          if (ec) return retry("cannot connect: " + ec.message());
                          start_link(ep);
                        });
  }

  // TCP is up: the TLS handshake (when configured), then the session.
  void start_link(const tcp::endpoint& ep) {
    remote_tcp = ep;
    stats.connects.fetch_add(1);
    boost::system::error_code ec;
    tcp_sock.set_option(tcp::no_delay(true), ec);
    tcp_sock.set_option(asio::socket_base::send_buffer_size(kUpstreamSendBuffer), ec);
    link = tls_ctx ? std::make_shared<proto::LinkStream>(std::move(tcp_sock), *tls_ctx)
                   : std::make_shared<proto::LinkStream>(std::move(tcp_sock));
    tcp_sock = tcp::socket(io);
    opener.reset();
    handshake_failed = false;
    session_id = 0;
    set_state(ClientState::Handshaking,
              "connected to " + ep.address().to_string() + (link->tls() ? ", TLS handshake" : ""));
    last_rx_ns = monotonic_ns();
    arm_heartbeat();  // its silence check also bounds the handshake
    const auto gen = generation;
    link->async_handshake(
        asio::ssl::stream_base::client, [this, gen, ep, keep = link](boost::system::error_code e) {
          if (gen != generation) return;
          if (e) return on_handshake_failed(e);
          if (link->tls()) {
            // Before any byte of the session (the Hello) goes out: a peer that completed TLS
            // without the key (a certificate-only server on the path) is no remote of ours.
            if (auto why =
                    proto::unauthenticated_session(link->ssl(), proto::TlsRole::Client, cfg.tls)) {
              handshake_failed = true;
              return auth_failed(*why);
            }
            try {
              opener = std::make_unique<proto::DatagramOpener>(
                  proto::export_link_keys(link->ssl(), proto::TlsRole::Client).rx);
            } catch (const std::exception& x) {
              return disconnect(x.what());
            }
          }
          on_connected(ep);
        });
  }

  // Counted as an authentication failure only when the TLS layer says so (an alert, or bytes that
  // are not TLS): a connection closed or reset with no TLS reply is a remote not (yet) there, as
  // behind a forwarder that accepts before its far end listens, and is retried like a refused
  // connect, without "authentication failed" in the final message.
  void on_handshake_failed(const boost::system::error_code& e) {
    handshake_failed = true;
    if (e.category() == asio::error::get_ssl_category())
      return auth_failed(proto::explain_tls_failure(static_cast<unsigned long>(e.value()),
                                                    e.message(), proto::TlsRole::Client, cfg.tls));
    disconnect("the remote closed the connection during the TLS handshake (" + e.message() +
               "): it may run without --psk or certificates, or refuse this station's; see its "
               "log");
  }

  // Counted, said as an error (a key mismatch is not a passing state), then retried.
  void auth_failed(const std::string& why) {
    stats.auth_failed.fetch_add(1);
    if (ev.on_auth_failed) ev.on_auth_failed(why);
    disconnect(why);
  }

  void on_connected(const tcp::endpoint& ep) {
    boost::system::error_code ec;
    parser = proto::StreamParser(cfg.limits);
    dgram = proto::DatagramParser(cfg.limits);
    reassembler = proto::Reassembler();
    udp_lost_counted = 0;
    by_fragments_counted = {};
    report = ReceiverReportBuilder{};
    std::uint16_t udp_port = 0;
    if (cfg.use_udp) {
      // Receive UDP on the interface the TCP session uses, so loopback stays loopback.
      udp_sock.open(ep.protocol() == tcp::v4() ? udp::v4() : udp::v6(), ec);
      if (!ec) udp_sock.set_option(asio::socket_base::receive_buffer_size(4 << 20), ec);
      if (!ec)
        udp_sock.bind(udp::endpoint(link->socket().local_endpoint().address(), cfg.udp_bind_port),
                      ec);
      if (ec) return disconnect("cannot open UDP socket: " + ec.message());
      udp_port =
          cfg.udp_announce_port != 0 ? cfg.udp_announce_port : udp_sock.local_endpoint().port();
      udp_receive();
    }
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
  }

  void tcp_read() {
    const auto gen = generation;
    link->async_read_some(asio::buffer(tcp_buf), [this, gen, keep = link](
                                                     boost::system::error_code ec, std::size_t n) {
      if (gen != generation) return;
      // TLS 1.3: the client's handshake ends before the remote has checked its certificate, so
      // the remote's refusal (an alert) arrives at the first read.
      if (ec && link->tls() && session_id == 0 && ec.category() == asio::error::get_ssl_category())
        return on_handshake_failed(ec);
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
    if (opener) {
      // Sealed under the remote->station key exported from this TLS session: the reassembler sees
      // only authentic fragments, so forged ones cannot evict or supersede real frames.
      const auto why = opener->open(d, udp_plain);
      if (why != proto::OpenError::None) {
        count_drop(unopened(why), "UDP");
        return;
      }
      d = udp_plain;
    }
    const auto now = static_cast<std::uint64_t>(monotonic_ns());
    const auto before = reassembler.counters().malformed;
    auto whole = reassembler.push(d, now);
    report.add_datagram(d.size());
    report.add_lost(reassembler.counters().lost() - udp_lost_counted);
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
      const auto& h = r.envelope->header;
      report.add_message(static_cast<std::int64_t>(h.capture_ns),
                         static_cast<std::int64_t>(now) + stats.clock_offset_ns.load(),
                         h.type == proto::MsgType::EncodedVideo ? whole->size() : 0);
      handle(*r.envelope);
    } else if (reassembler.counters().malformed != before) {
      stats.dropped_malformed.fetch_add(1);
    }
  }

  // Counts a rejected message by reason; warns at most once a second.
  void count_drop(const proto::Result& r, const char* transport) {
    count_link_drop(stats, r);
    const auto now = monotonic_ns();
    if (ev.on_warning && now - last_warning_ns > 1'000'000'000) {
      last_warning_ns = now;
      ev.on_warning(link_drop_warning(stats, r, transport));
    }
  }

  // A plain station that loses the connection before Accept may be talking to a remote that
  // requires TLS (whose Reject it would have read, unless the remote is older or the bytes were
  // cut).
  std::string auth_hint() const {
    if (!tls_ctx && session_id == 0 && !handshake_failed)
      return "; if the remote requires TLS, start telex-local with its --psk FILE (or "
             "--cert/--key/--ca)";
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
    if (session_id != 0) stats.alive_ns.store(last_rx_ns, std::memory_order_relaxed);
    const std::uint64_t message_bytes = proto::kHeaderSize + h.payload_len;
    if (h.type == proto::MsgType::EncodedVideo)
      stats.video_bytes.fetch_add(message_bytes);
    else if (h.type == proto::MsgType::DepthTile || h.type == proto::MsgType::FrameManifest ||
             h.type == proto::MsgType::StreamConfig)
      stats.depth_bytes.fetch_add(message_bytes);
    std::visit(
        [&](const auto& m) {
          using T = std::decay_t<decltype(m)>;
          if constexpr (std::is_same_v<T, proto::Accept>) {
            if (session_id != 0) {  // one Accept per connection; a second is not the remote's
              stats.dropped_foreign.fetch_add(1);
              return;
            }
            session_id = m.session_id;
            stats.alive_ns.store(last_rx_ns, std::memory_order_relaxed);
            arm_alive_probe();
            backoff_ns = cfg.backoff_min_ns;
            set_state(ClientState::Streaming,
                      "session " + std::to_string(m.session_id) + ", " +
                          (m.transport == proto::Transport::Udp ? "udp" : "tcp") + ", " +
                          std::string(proto::codec_name(m.codec)));
          } else if constexpr (std::is_same_v<T, proto::Reject>) {
            stats.rejects.fetch_add(1);
            handshake_failed = true;  // the remote said why: no guessing in auth_hint
            if (m.reason == proto::RejectReason::AuthFailed)
              return auth_failed("remote refused: " + m.text);
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
          } else if constexpr (std::is_same_v<T, proto::EncodedVideo>) {
            if (ev.on_video) ev.on_video(h, m);
          } else if constexpr (std::is_same_v<T, proto::Stats>) {
            if (ev.on_stats) ev.on_stats(m);
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
      // With the 10 ms probes on, those are the probes and this timer only checks and reports.
      if (session_id != 0 && cfg.alive_probe_ns <= 0)
        send(proto::Heartbeat{static_cast<std::uint64_t>(monotonic_ns()), 0, 0, 0});
      // With each probe, what arrived over UDP since the last one (PROTOCOL.md 2.7).
      const auto r = report.take(monotonic_ns());
      if (session_id != 0 && cfg.use_udp && r) {
        send(*r);
        stats.receiver_reports.fetch_add(1);
      }
      arm_heartbeat();
    });
  }

  // Probes at alive_probe_ns while the session lasts: their answers are the link's pulse.
  void arm_alive_probe() {
    if (cfg.alive_probe_ns <= 0) return;
    const auto gen = generation;
    alive_timer.expires_after(std::chrono::nanoseconds(cfg.alive_probe_ns));
    alive_timer.async_wait([this, gen](boost::system::error_code ec) {
      if (ec || gen != generation || session_id == 0) return;
      send(proto::Heartbeat{static_cast<std::uint64_t>(monotonic_ns()), 0, 0, 0});
      arm_alive_probe();
    });
  }

  void close_sockets() {
    boost::system::error_code ec;
    stats.alive_ns.store(0, std::memory_order_relaxed);
    heartbeat_timer.cancel();
    alive_timer.cancel();
    if (tcp_sock.is_open()) tcp_sock.close(ec);
    if (link) link->close();
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
    ++impl_->generation;  // handlers still queued bail out
    impl_->retry_timer.cancel();
    const auto finish = [this] {
      impl_->close_sockets();
      impl_->work.reset();
      impl_->set_state(ClientState::Stopped, "stopped");
    };
    // Best effort goodbye; the socket closes right after. Never beside a write in flight, whose
    // bytes (or TLS record) it would cut, and only once the read in flight has been cancelled
    // (its aborted completion runs before the handler posted here).
    if (!impl_->link_open() || impl_->session_id == 0 || impl_->writing) return finish();
    boost::system::error_code ec;
    impl_->link->socket().cancel(ec);
    asio::post(impl_->io, [this, finish] {
      boost::system::error_code ignore;
      proto::Header h;
      h.session_id = impl_->session_id;
      h.seq = impl_->seq++;
      const auto bytes = proto::encode_stream(h, proto::Bye{0});
      if (impl_->link_open()) impl_->link->write_now(asio::buffer(bytes), ignore);
      finish();
    });
  });
  impl_->thread.join();
}

std::optional<ThreadFaultReport> SurfaceClient::thread_fault() const {
  return impl_->fault.report();
}

void SurfaceClient::request_roi(const proto::RoiRequest& roi) {
  asio::post(impl_->io, [this, roi] {
    if (impl_->session_id != 0 && impl_->link_open()) impl_->send(roi);
  });
}

void SurfaceClient::send_nack(const proto::TileNack& nack) {
  asio::post(impl_->io, [this, nack] {
    if (impl_->session_id != 0 && impl_->link_open()) impl_->send(nack);
  });
}

void SurfaceClient::send_head(const proto::HeadCommand& head) {
  asio::post(impl_->io, [this, head] {
    if (impl_->session_id != 0 && impl_->link_open()) impl_->send(head);
  });
}

void SurfaceClient::send_picture_loss(const proto::PictureLoss& pli) {
  asio::post(impl_->io, [this, pli] {
    if (impl_->session_id != 0 && impl_->link_open()) impl_->send(pli);
  });
}

void SurfaceClient::send_video_nack(const proto::VideoNack& nack) {
  asio::post(impl_->io, [this, nack] {
    if (impl_->session_id != 0 && impl_->link_open()) impl_->send(nack);
  });
}

void SurfaceClient::request_key_frame() {
  asio::post(impl_->io, [this] {
    if (impl_->session_id != 0 && impl_->link_open())
      impl_->send(proto::Stats{{{"key_frame_request", 1}}});
  });
}

}  // namespace telex::local
