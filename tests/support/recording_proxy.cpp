// SPDX-License-Identifier: MIT
// A recording proxy for the link's security tests (recording_proxy.h).
#include "recording_proxy.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include "process.h"

namespace telex::test {

RecordingProxy::RecordingProxy(std::uint16_t remote_tcp, std::uint16_t station_udp)
    : remote_tcp_(remote_tcp), station_udp_(station_udp) {
  listen_fd_ = bound_socket(SOCK_STREAM, tcp_port);
  ::listen(listen_fd_, 8);
  udp_fd_ = bound_socket(SOCK_DGRAM, udp_port);
  thread_ = std::thread([this] { run(); });
}

RecordingProxy::~RecordingProxy() {
  stop_ = true;
  thread_.join();
  for (int fd : {listen_fd_, udp_fd_}) ::close(fd);
  for (const auto& [a, b] : pairs_) ::close(a), ::close(b);
}

std::vector<RecordingProxy::Chunk> RecordingProxy::chunks() const {
  std::lock_guard lock(mu_);
  return chunks_;
}

void RecordingProxy::record(Chunk c) {
  std::lock_guard lock(mu_);
  chunks_.push_back(std::move(c));
}

void RecordingProxy::accept_one() {
  const int station = ::accept(listen_fd_, nullptr, nullptr);
  if (station < 0) return;
  ++accepted_;
  const int remote = ::socket(AF_INET, SOCK_STREAM, 0);
  const sockaddr_in a = loopback_address(remote_tcp_);
  if (::connect(remote, reinterpret_cast<const sockaddr*>(&a), sizeof a) == 0) {
    pairs_.emplace_back(station, remote);
    return;
  }
  ++refused_;
  ::close(station);
  ::close(remote);
}

void RecordingProxy::forward_datagram(std::vector<std::uint8_t>& buf) {
  sockaddr_in from{};
  socklen_t len = sizeof from;
  const ssize_t n =
      ::recvfrom(udp_fd_, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &len);
  if (n <= 0) return;
  record(
      {true, true, std::vector<std::uint8_t>(buf.begin(), buf.begin() + n), ntohs(from.sin_port)});
  const sockaddr_in to = loopback_address(station_udp_);
  ::sendto(udp_fd_, buf.data(), static_cast<std::size_t>(n), 0,
           reinterpret_cast<const sockaddr*>(&to), sizeof to);
}

void RecordingProxy::run() {
  std::vector<std::uint8_t> buf(65536);
  while (!stop_) {
    std::vector<pollfd> fds{{listen_fd_, POLLIN, 0}, {udp_fd_, POLLIN, 0}};
    for (const auto& [station, remote] : pairs_) {
      fds.push_back({station, POLLIN, 0});
      fds.push_back({remote, POLLIN, 0});
    }
    if (::poll(fds.data(), fds.size(), 50) <= 0) continue;
    if (fds[0].revents & POLLIN) accept_one();
    if (fds[1].revents & POLLIN) forward_datagram(buf);
    for (std::size_t i = 2; i < fds.size(); ++i) {
      if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      const auto& [station, remote] = pairs_[(i - 2) / 2];
      const bool from_station = fds[i].fd == station;
      const ssize_t n = ::recv(fds[i].fd, buf.data(), buf.size(), 0);
      if (n <= 0) {
        ::shutdown(from_station ? remote : station, SHUT_WR);
        continue;
      }
      record({false, !from_station, std::vector<std::uint8_t>(buf.begin(), buf.begin() + n), 0});
      ::send(from_station ? remote : station, buf.data(), static_cast<std::size_t>(n),
             MSG_NOSIGNAL);
    }
  }
}

}  // namespace telex::test
