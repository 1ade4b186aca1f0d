// SPDX-License-Identifier: MIT
// A recording proxy for the link's security tests: in the spirit of telex-sim-impair, but in
// process and faithful. It forwards TCP connections to the remote and the remote's datagrams to the
// station, and records every byte it carries, chunk by chunk (each datagram; each read from a TCP
// connection). With nothing listening at the remote's port it accepts and then closes, as a
// forwarder (ssh -L) does when its far end is down.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace telex::test {

class RecordingProxy {
 public:
  struct Chunk {
    bool udp = false;
    bool to_station = false;
    std::vector<std::uint8_t> bytes;
    std::uint16_t from_port = 0;  // UDP: the sender's port (the remote's UDP socket)
  };

  RecordingProxy(std::uint16_t remote_tcp, std::uint16_t station_udp);
  ~RecordingProxy();
  RecordingProxy(const RecordingProxy&) = delete;
  RecordingProxy& operator=(const RecordingProxy&) = delete;

  std::vector<Chunk> chunks() const;
  // TCP connections it accepted, and those of them it closed at once because the remote's port
  // refused its connect.
  int accepted() const { return accepted_.load(); }
  int refused() const { return refused_.load(); }
  std::uint16_t tcp_port = 0, udp_port = 0;

 private:
  void record(Chunk c);
  void run();
  void accept_one();
  void forward_datagram(std::vector<std::uint8_t>& buf);

  std::uint16_t remote_tcp_, station_udp_;
  int listen_fd_ = -1, udp_fd_ = -1;
  std::vector<std::pair<int, int>> pairs_;  // station side, remote side
  mutable std::mutex mu_;
  std::vector<Chunk> chunks_;
  std::atomic<int> accepted_{0}, refused_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace telex::test
