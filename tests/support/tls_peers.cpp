// SPDX-License-Identifier: MIT
// Hostile TLS peers and connection crowds (tls_peers.h).
#include "tls_peers.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <stdexcept>

#include "process.h"

namespace telex::test {
namespace {

using SslCtx = std::unique_ptr<SSL_CTX, decltype(&SSL_CTX_free)>;

SslCtx tls13_context(bool server, const std::filesystem::path& cert,
                     const std::filesystem::path& key) {
  SslCtx ctx(SSL_CTX_new(server ? TLS_server_method() : TLS_client_method()), &SSL_CTX_free);
  if (!ctx || SSL_CTX_set_min_proto_version(ctx.get(), TLS1_3_VERSION) != 1 ||
      SSL_CTX_use_certificate_file(ctx.get(), cert.c_str(), SSL_FILETYPE_PEM) != 1 ||
      SSL_CTX_use_PrivateKey_file(ctx.get(), key.c_str(), SSL_FILETYPE_PEM) != 1)
    throw std::runtime_error("cannot make a TLS context from " + cert.string());
  SSL_CTX_set_verify(ctx.get(), SSL_VERIFY_NONE, nullptr);
  return ctx;
}

int connect_from(const std::string& source, std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  sockaddr_in from{};
  from.sin_family = AF_INET;
  inet_pton(AF_INET, source.c_str(), &from.sin_addr);
  const sockaddr_in to = loopback_address(port);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&from), sizeof from) != 0 ||
      ::connect(fd, reinterpret_cast<const sockaddr*>(&to), sizeof to) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

}  // namespace

bool openssl(const std::string& args, const std::filesystem::path& dir) {
  const std::string cmd = "cd '" + dir.string() + "' && openssl " + args + " >> openssl.log 2>&1";
  return std::system(cmd.c_str()) == 0;
}

bool make_ca(const std::filesystem::path& dir, const std::string& ca) {
  return openssl(
      "req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 -subj "
      "/CN=" +
          ca + " -keyout " + ca + ".key -out " + ca + ".pem",
      dir);
}

bool make_cert(const std::filesystem::path& dir, const std::string& ca, const std::string& who) {
  return openssl("req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj /CN=" + who +
                     " -keyout " + who + ".key -out " + who + ".csr",
                 dir) &&
         openssl("x509 -req -in " + who + ".csr -CA " + ca + ".pem -CAkey " + ca +
                     ".key -CAcreateserial -days 2 -out " + who + ".pem",
                 dir) &&
         ::chmod((dir / (who + ".key")).c_str(), 0600) == 0;
}

CertOnlyTlsServer::CertOnlyTlsServer(const std::filesystem::path& dir)
    : cert_(dir / "impostor.pem"), key_(dir / "impostor.key") {
  if (!make_ca(dir, "impostor"))
    throw std::runtime_error("openssl could not make a certificate: " +
                             read_text(dir / "openssl.log"));
  listen_fd_ = bound_socket(SOCK_STREAM, port_);
  if (::listen(listen_fd_, 16) != 0) throw std::runtime_error("listen failed");
  thread_ = std::thread([this] { serve(); });
}

CertOnlyTlsServer::~CertOnlyTlsServer() {
  stop_ = true;
  ::shutdown(listen_fd_, SHUT_RDWR);
  thread_.join();
  ::close(listen_fd_);
}

void CertOnlyTlsServer::serve() {
  const SslCtx ctx = tls13_context(true, cert_, key_);
  while (!stop_) {
    pollfd p{listen_fd_, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    const int fd = ::accept(listen_fd_, nullptr, nullptr);
    if (fd < 0) continue;
    ++connections_;
    timeval tv{1, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    SSL* ssl = SSL_new(ctx.get());
    SSL_set_fd(ssl, fd);
    if (SSL_accept(ssl) == 1) {
      ++handshakes_;
      char buf[4096];
      int n = 0;
      while ((n = SSL_read(ssl, buf, sizeof buf)) > 0) bytes_read_ += n;
    }
    ERR_clear_error();
    SSL_free(ssl);
    ::close(fd);
  }
}

bool cert_only_client_gets_a_session(const std::filesystem::path& dir, std::uint16_t port) {
  if (!std::filesystem::exists(dir / "impostor.pem") && !make_ca(dir, "impostor"))
    throw std::runtime_error("openssl could not make a certificate");
  const SslCtx ctx = tls13_context(false, dir / "impostor.pem", dir / "impostor.key");
  // The daemon may still be starting: its port is tried for up to 10 s.
  int fd = -1;
  for (int i = 0; i < 200 && fd < 0; ++i) {
    fd = connect_from("127.0.0.1", port);
    if (fd < 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (fd < 0) return false;
  timeval tv{2, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  SSL* ssl = SSL_new(ctx.get());
  SSL_set_fd(ssl, fd);
  bool session = false;
  if (SSL_connect(ssl) == 1) {
    // TLS 1.3: a server that refuses a certificate says so at the client's first read.
    const char hello[] = "TLX1";
    char buf[256];
    session = SSL_write(ssl, hello, sizeof hello) > 0 && SSL_read(ssl, buf, sizeof buf) > 0;
  }
  ERR_clear_error();
  SSL_free(ssl);
  ::close(fd);
  return session;
}

ConnectionCrowd::ConnectionCrowd(std::uint16_t port, int count, Kind kind,
                                 std::vector<std::string> sources)
    : port_(port), count_(count), kind_(kind), sources_(std::move(sources)) {
  thread_ = std::thread([this] { run(); });
}

ConnectionCrowd::~ConnectionCrowd() {
  stop_ = true;
  thread_.join();
}

void ConnectionCrowd::run() {
  static const std::uint8_t kPartialRecord[] = {0x16, 0x03, 0x01, 0x02, 0x00, 0x01};
  std::vector<int> fds(static_cast<std::size_t>(count_), -1);
  std::size_t next_source = 0;
  while (!stop_) {
    for (auto& fd : fds) {
      if (fd >= 0) {
        // Closed by the daemon: readable with nothing to read (or an error).
        pollfd p{fd, POLLIN, 0};
        char c;
        if (::poll(&p, 1, 0) == 1 && ::recv(fd, &c, 1, MSG_DONTWAIT) <= 0) {
          ::close(fd);
          fd = -1;
        }
      }
      if (fd < 0 && !stop_) {
        fd = connect_from(sources_[next_source++ % sources_.size()], port_);
        if (fd < 0) continue;
        ++connects_;
        if (kind_ == Kind::HalfOpen)
          (void)!::send(fd, kPartialRecord, sizeof kPartialRecord, MSG_NOSIGNAL);
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  for (const int fd : fds)
    if (fd >= 0) ::close(fd);
}

}  // namespace telex::test
