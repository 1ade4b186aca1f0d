// SPDX-License-Identifier: MIT
// The remote's network server, acceptor part: the listening socket, the TLS handshake and its
// check, the client timeout, session ends (logged and counted by reason), and RemoteServer's
// public face. Connections before authentication are server_pending.cpp's.
#include <openssl/objects.h>
#include <openssl/ssl.h>

#include <stdexcept>

#include "server_impl.h"
#include "telex/base/periodic.h"

namespace telex::remote {

std::string_view client_state_name(ClientState state) {
  return state == ClientState::Connected ? "connected" : "waiting";
}

std::string_view session_end_name(SessionEnd reason) {
  switch (reason) {
    case SessionEnd::ClientBye:
      return "client-bye";
    case SessionEnd::ConnectionLost:
      return "connection-lost";
    case SessionEnd::WriteFailed:
      return "write-failed";
    case SessionEnd::ClientSilent:
      return "client-silent";
    case SessionEnd::Unparseable:
      return "unparseable";
    case SessionEnd::Refused:
      return "refused";
    case SessionEnd::ServerStopping:
      break;
  }
  return "server-stopping";
}

RemoteServer::Impl::Impl(ServerConfig config)
    : config_(std::move(config)),
      acceptor_(io_),
      udp_(io_),
      timer_(io_),
      accept_backoff_(io_),
      cache_(config_.repair_cache_frames) {
  // Bad certificate, key or CA files are configuration errors (std::invalid_argument: exit 2).
  if (config_.tls.enabled())
    tls_.emplace(proto::make_tls_context(config_.tls, proto::TlsRole::Server));
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(config_.host, ec);
  if (ec)
    throw std::invalid_argument(
        fmt::format("--listen host '{}' is not an IP address: {}", config_.host, ec.message()));
  const tcp::endpoint endpoint(address, config_.port);
  acceptor_.open(endpoint.protocol(), ec);
  if (!ec) acceptor_.set_option(tcp::acceptor::reuse_address(true), ec);
  if (!ec) acceptor_.bind(endpoint, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  // A bad --listen value (port in use, address not ours) is a configuration error: exit 2.
  if (ec == boost::system::errc::address_not_available)
    throw std::invalid_argument(fmt::format(
        "cannot listen on {}:{}: this machine has no address {} (`ip -brief address` lists its "
        "addresses; 0.0.0.0 listens on all of them)",
        config_.host, config_.port, config_.host));
  if (ec)
    throw std::invalid_argument(
        fmt::format("cannot listen on {}:{}: {} (is another telex-remote running? pick another "
                    "--listen port)",
                    config_.host, config_.port, ec.message()));
  udp_.open(address.is_v4() ? udp::v4() : udp::v6(), ec);
  if (!ec) udp_.bind(udp::endpoint(address, 0), ec);
  if (!ec) udp_.set_option(asio::socket_base::send_buffer_size(4 << 20), ec);
  if (ec)
    throw std::runtime_error(
        fmt::format("cannot open the UDP socket on {}: {}", config_.host, ec.message()));
}

void RemoteServer::Impl::start() {
  if (thread_.joinable()) return;
  do_accept();
  arm_timer();
  udp_receive();
  thread_ = std::thread([this] { fault_.run([this] { io_.run(); }); });
  name_thread(thread_.native_handle(), "telex-net");
  scheduling_ = try_realtime(thread_.native_handle(), config_.realtime_priority);
}

void RemoteServer::Impl::stop() {
  if (!thread_.joinable()) return;
  asio::post(io_, [this] {
    boost::system::error_code ec;
    acceptor_.close(ec);
    timer_.cancel();
    accept_backoff_.cancel();
    close_all_pending();
    end_session(SessionEnd::ServerStopping);
    udp_.close(ec);
    work_.reset();
  });
  thread_.join();
}

FrameRequest RemoteServer::Impl::take_request() {
  std::lock_guard lock(mu_);
  FrameRequest r = request_;
  request_.force_key_frame = false;
  return r;
}

void RemoteServer::Impl::do_accept() {
  acceptor_.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted || !acceptor_.is_open()) return;
    if (ec) return on_accept_error(ec);
    admit(std::move(socket));
    do_accept();
  });
}

std::shared_ptr<proto::LinkStream> RemoteServer::Impl::make_link(tcp::socket socket) {
  if (tls_) return std::make_shared<proto::LinkStream>(std::move(socket), *tls_);
  return std::make_shared<proto::LinkStream>(std::move(socket));
}

// A Reject, then the connection closes. Only an authenticated peer, or one that speaks no TLS
// (which then learns only that TLS is required), is ever told why.
void RemoteServer::Impl::reject(std::shared_ptr<proto::LinkStream> link, proto::RejectReason reason,
                                std::string text) {
  ++counters_.clients_rejected;
  proto::Reject r;
  r.reason = reason;
  r.text = std::move(text);
  auto buf = make_buffer(proto::encode_stream(header(0, 0, steady_now_ns(), false), r));
  link->async_write(asio::buffer(*buf),
                    [link, buf](boost::system::error_code, std::size_t) { link->close(); });
}

void RemoteServer::Impl::on_handshake(const std::shared_ptr<Session>& a,
                                      boost::system::error_code ec) {
  if (!a->open) return;
  if (ec) {
    ++counters_.auth_failed;
    const bool ssl_error = ec.category() == asio::error::get_ssl_category();
    const auto code = static_cast<unsigned long>(ec.value());
    const std::string why =
        ssl_error
            ? proto::explain_tls_failure(code, ec.message(), proto::TlsRole::Server, config_.tls)
            : "the connection closed during the TLS handshake (" + ec.message() + ")";
    if (log_allowed(last_auth_log_, auth_logs_held_))
      spdlog::warn("TLS handshake with {} failed: {}", a->peer, why);
    // A station without TLS reads a clear-text Reject and can say what to fix.
    const bool plain_peer = ssl_error && proto::tls_failure_is_plain_peer(code);
    refuse_session(a, proto::RejectReason::AuthFailed,
                   plain_peer ? "this telex-remote requires TLS (" + config_.tls.describe() +
                                    "): start telex-local with the same --psk FILE (or "
                                    "--cert/--key/--ca)"
                              : why,
                   plain_peer, plain_peer);
    return;
  }
  if (a->link->tls()) {
    if (auto why =
            proto::unauthenticated_session(a->link->ssl(), proto::TlsRole::Server, config_.tls)) {
      ++counters_.auth_failed;
      if (log_allowed(last_auth_log_, auth_logs_held_))
        spdlog::warn("TLS handshake with {} refused: {}", a->peer, *why);
      refuse_session(a, proto::RejectReason::AuthFailed, *why, false);
      return;
    }
    try {
      auto keys = proto::export_link_keys(a->link->ssl(), proto::TlsRole::Server);
      a->sealer = std::make_shared<proto::DatagramSealer>(keys.tx);
      a->opener = std::make_unique<proto::DatagramOpener>(keys.rx);
    } catch (const std::exception& e) {
      spdlog::error("session with {}: {}", a->peer, e.what());
      refuse_session(a, proto::RejectReason::Unspecified, e.what(), false);
      return;
    }
    SSL* ssl = a->link->ssl();
    const int group = SSL_get_negotiated_group(ssl);
    spdlog::info("TLS with {}: {} {} ({}, key exchange {})", a->peer, SSL_get_version(ssl),
                 SSL_get_cipher_name(ssl), config_.tls.describe(),
                 group != 0 ? OBJ_nid2sn(group) : "none");
  }
  a->stage = Session::Stage::AwaitingHello;
  do_read(a);
}

void RemoteServer::Impl::close_session(const std::shared_ptr<Session>& a, SessionEnd why) {
  if (a == active_) return end_session(why);
  drop_pending(a);
}

// Every way a session ends comes through here (or refuse_session, which answers first): the
// reason is logged and counted.
void RemoteServer::Impl::end_session(SessionEnd why) {
  if (!active_) return;
  ++counters_.sessions_ended[static_cast<std::size_t>(why)];
  spdlog::info("session {} with {} ended: {}", session_id_, active_->peer, session_end_name(why));
  active_->open = false;
  active_->link->close();
  active_.reset();
  std::lock_guard lock(mu_);
  connected_ = false;
  video_wanted_ = false;
}

void RemoteServer::Impl::arm_timer() {
  timer_.expires_after(std::chrono::milliseconds(100));
  timer_.async_wait([this](boost::system::error_code ec) {
    // An expiry already queued when stop() ran cannot be cancelled: it arrives with no error
    // after stop()'s handler, which closed the acceptor. Re-arming then would keep io_.run()
    // (and stop()'s join) waiting forever; a latency run of the daemons hung there once.
    if (ec || !acceptor_.is_open()) return;
    const auto now = std::chrono::steady_clock::now();
    if (active_ && now - active_->last_rx > config_.client_timeout) {
      ++counters_.client_timeouts;
      end_session(SessionEnd::ClientSilent);
    }
    sweep_pending(now);
    if (active_) probe(active_);
    arm_timer();
  });
}

RemoteServer::RemoteServer(ServerConfig config)
    : impl_(std::make_unique<Impl>(std::move(config))) {}
RemoteServer::~RemoteServer() = default;
void RemoteServer::start() { impl_->start(); }
void RemoteServer::stop() { impl_->stop(); }
std::uint16_t RemoteServer::port() const { return impl_->port(); }
ClientState RemoteServer::state() const { return impl_->state(); }
bool RemoteServer::video_wanted() const { return impl_->video_wanted(); }
void RemoteServer::tell(const std::string& key) { impl_->tell(key); }
const ServerCounters& RemoteServer::counters() const { return impl_->counters_; }
const std::string& RemoteServer::scheduling() const { return impl_->scheduling_; }
const ThreadFault& RemoteServer::fault() const { return impl_->fault_; }
FrameRequest RemoteServer::take_request() { return impl_->take_request(); }
void RemoteServer::publish(const ProcessedFrame& frame) { impl_->publish(frame); }
void RemoteServer::publish_tiles(const ProcessedFrame& part, std::size_t from) {
  impl_->publish_tiles(part, from);
}
void RemoteServer::publish_video(std::uint32_t frame_id, std::int64_t capture_ns, bool is_intra,
                                 std::vector<std::uint8_t> encoded_pair) {
  impl_->publish_video(frame_id, capture_ns, is_intra, std::move(encoded_pair));
}

}  // namespace telex::remote
