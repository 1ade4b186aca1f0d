// SPDX-License-Identifier: MIT
// Hostile TLS peers and crowds for the link's attack tests: throw-away certificates from the
// openssl command line, a certificate-only TLS 1.3 server (an impostor on the path) and client,
// and a crowd of idle or half-open TCP connections that reconnect as the daemon closes them.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

namespace telex::test {

// Runs the openssl command line in `dir` (its output goes to dir/openssl.log); false on failure.
bool openssl(const std::string& args, const std::filesystem::path& dir);
// A self-signed CA `ca` (dir/ca.pem, dir/ca.key), EC P-256.
bool make_ca(const std::filesystem::path& dir, const std::string& ca);
// A certificate for `who` signed by `ca` (dir/who.pem, dir/who.key with mode 0600).
bool make_cert(const std::filesystem::path& dir, const std::string& ca, const std::string& who);

// A TLS 1.3 server on a loopback port with a self-signed certificate and no key of ours: what
// anyone on the path can run. Each connection gets a handshake; after one that completes it
// reads what the client sends (up to 1 s). Counts both, so a test can see that a keyed station
// neither completes the handshake nor sends a byte (its Hello) to it.
class CertOnlyTlsServer {
 public:
  // Throws std::runtime_error when the certificate or the socket cannot be made.
  explicit CertOnlyTlsServer(const std::filesystem::path& dir);
  ~CertOnlyTlsServer();
  std::uint16_t port() const { return port_; }
  int connections() const { return connections_.load(); }
  int handshakes() const { return handshakes_.load(); }   // completed on the server's side
  long bytes_read() const { return bytes_read_.load(); }  // application data after a handshake

 private:
  void serve();
  std::filesystem::path cert_, key_;
  int listen_fd_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> connections_{0}, handshakes_{0};
  std::atomic<long> bytes_read_{0};
  std::thread thread_;
};

// A TLS 1.3 client with a self-signed certificate (dir/who.pem) and no key of ours against
// 127.0.0.1:port. True when its handshake completed and the server then sent application data
// or accepted what it wrote (a Hello) without closing: a session the server should never give.
bool cert_only_client_gets_a_session(const std::filesystem::path& dir, std::uint16_t port);

// `count` TCP connections to 127.0.0.1:port from the loopback addresses `sources` (in turn),
// each idle (connects and says nothing) or half-open (the first 6 bytes of a TLS record, then
// silence), reconnected within about 10 ms whenever the daemon closes one, until destroyed.
class ConnectionCrowd {
 public:
  enum class Kind { Idle, HalfOpen };
  ConnectionCrowd(std::uint16_t port, int count, Kind kind, std::vector<std::string> sources);
  ~ConnectionCrowd();
  long connects() const { return connects_.load(); }  // including the first ones

 private:
  void run();
  std::uint16_t port_;
  int count_;
  Kind kind_;
  std::vector<std::string> sources_;
  std::atomic<bool> stop_{false};
  std::atomic<long> connects_{0};
  std::thread thread_;
};

}  // namespace telex::test
