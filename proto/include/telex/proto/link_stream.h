// SPDX-License-Identifier: MIT
// The TCP connection of a session as both daemons drive it: TLS 1.3 (asio::ssl::stream) when a key
// or certificates are configured, a plain socket otherwise. Header-only and Asio-only: the nodes'
// connection classes use it; proto's parsers and codecs never touch a socket.
#pragma once

#include <boost/asio.hpp>
#include <boost/asio/ssl.hpp>
#include <optional>
#include <utility>

namespace telex::proto {

class LinkStream {
 public:
  using tcp = boost::asio::ip::tcp;
  using TlsStream = boost::asio::ssl::stream<tcp::socket>;

  // Plain.
  explicit LinkStream(tcp::socket socket) : plain_(std::move(socket)) {}
  // TLS over `socket`, under `context` (which must outlive the stream).
  LinkStream(tcp::socket socket, boost::asio::ssl::context& context)
      : tls_(std::in_place, std::move(socket), context) {}

  bool tls() const { return tls_.has_value(); }
  tcp::socket& socket() { return tls_ ? tls_->next_layer() : *plain_; }
  // The OpenSSL connection (only when tls()).
  SSL* ssl() { return tls_->native_handle(); }

  // Runs the handshake with TLS; completes at once (through the executor) without.
  template <class Handler>
  void async_handshake(boost::asio::ssl::stream_base::handshake_type type, Handler&& handler) {
    if (tls_) {
      tls_->async_handshake(type, std::forward<Handler>(handler));
    } else {
      boost::asio::post(plain_->get_executor(),
                        [h = std::forward<Handler>(handler)]() mutable { h({}); });
    }
  }

  template <class Buffers, class Handler>
  void async_read_some(const Buffers& buffers, Handler&& handler) {
    if (tls_)
      tls_->async_read_some(buffers, std::forward<Handler>(handler));
    else
      plain_->async_read_some(buffers, std::forward<Handler>(handler));
  }

  // The whole buffer, as boost::asio::async_write. One write in flight at a time (the callers
  // keep a queue), which is also what ssl::stream requires.
  template <class Buffers, class Handler>
  void async_write(const Buffers& buffers, Handler&& handler) {
    if (tls_)
      boost::asio::async_write(*tls_, buffers, std::forward<Handler>(handler));
    else
      boost::asio::async_write(*plain_, buffers, std::forward<Handler>(handler));
  }

  // A blocking write of the whole buffer (a goodbye at shutdown). With TLS, only while no read
  // is in flight: the caller cancels its read first.
  template <class Buffers>
  void write_now(const Buffers& buffers, boost::system::error_code& ec) {
    if (tls_)
      boost::asio::write(*tls_, buffers, ec);
    else
      boost::asio::write(*plain_, buffers, ec);
  }

  // Closes the connection at once (no TLS close_notify: the session's own Bye says goodbye).
  void close() {
    boost::system::error_code ec;
    socket().shutdown(tcp::socket::shutdown_both, ec);
    socket().close(ec);
  }
  bool is_open() { return socket().is_open(); }

 private:
  std::optional<tcp::socket> plain_;
  std::optional<TlsStream> tls_;
};

}  // namespace telex::proto
