// SPDX-License-Identifier: MIT
// Fault tests on built binaries: telex-sim-impair forwarding and counting, bad flags and bad
// configuration of the proxy and telex-local exiting 2 with a message naming the problem.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <nlohmann/json.hpp>
#include <thread>

#include "process.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

// A loopback UDP socket bound to `port` (0 = any), closed on scope exit.
struct UdpSocket {
  int fd = -1;
  explicit UdpSocket(std::uint16_t port = 0) {
    fd = socket(AF_INET, SOCK_DGRAM, 0);
    const int rcvbuf = 4 << 20;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    bound = bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~UdpSocket() { close(fd); }
  std::uint16_t port() const {
    sockaddr_in a{};
    socklen_t len = sizeof a;
    getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    return ntohs(a.sin_port);
  }
  void send_to(std::uint16_t port, const std::vector<std::uint8_t>& d) const {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    sendto(fd, d.data(), d.size(), 0, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  bool bound = false;
};

// The summary is the last line and nests objects, so take the line, not the last brace.
nlohmann::json last_json_line(std::string out) {
  while (!out.empty() && out.back() == '\n') out.pop_back();
  const auto nl = out.rfind('\n');
  return nlohmann::json::parse(nl == std::string::npos ? out : out.substr(nl + 1), nullptr, false);
}

TEST(ImpairProxy, ForwardsBothWaysAndItsCountersMatchWhatArrived) {
  const auto dir = scratch_dir("impair_forward");
  UdpSocket server, client;
  ASSERT_TRUE(server.bound && client.bound);
  const auto proxy_port = free_port();
  Process proxy({built_binary("telex-sim-impair").string(),
                 "--listen",
                 "127.0.0.1:" + std::to_string(proxy_port),
                 "--forward",
                 "127.0.0.1:" + std::to_string(server.port()),
                 "--loss",
                 "0.2",
                 "--delay-ms",
                 "20",
                 "--jitter-ms",
                 "5",
                 "--duplicate",
                 "0.05",
                 "--corrupt",
                 "0.1",
                 "--seed",
                 "3",
                 "--duration",
                 "4",
                 "--json-summary"},
                dir / "proxy.out", dir / "proxy.err");
  ASSERT_TRUE(eventually(5s, [&] {
    return proxy.stderr_text().find("listening on") != std::string::npos;
  })) << proxy.stderr_text();

  // The server echoes everything; the client counts echoes and how many came back altered.
  std::atomic<bool> stop{false};
  std::atomic<int> at_server{0}, at_client{0}, altered{0};
  std::thread echo([&] {
    std::vector<std::uint8_t> buf(2048);
    pollfd p{server.fd, POLLIN, 0};
    while (!stop) {
      if (poll(&p, 1, 20) <= 0) continue;
      sockaddr_in from{};
      socklen_t len = sizeof from;
      const auto n =
          recvfrom(server.fd, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &len);
      if (n <= 0) continue;
      ++at_server;
      sendto(server.fd, buf.data(), static_cast<std::size_t>(n), 0,
             reinterpret_cast<sockaddr*>(&from), len);
    }
  });
  std::thread sink([&] {
    std::vector<std::uint8_t> buf(2048);
    pollfd p{client.fd, POLLIN, 0};
    while (!stop) {
      if (poll(&p, 1, 20) <= 0) continue;
      const auto n = recv(client.fd, buf.data(), buf.size(), 0);
      if (n <= 0) continue;
      ++at_client;
      bool same = n == 200;
      for (int i = 4; same && i < 200; ++i) same = buf[i] == 0x3C;
      altered += !same;
    }
  });
  constexpr int kSent = 1000;
  for (int i = 0; i < kSent; ++i) {
    std::vector<std::uint8_t> d(200, 0x3C);
    std::memcpy(d.data(), &i, 4);
    client.send_to(proxy_port, d);
    if (i % 50 == 49) std::this_thread::sleep_for(5ms);  // stay well under socket buffers
  }
  const auto rc = proxy.wait(15s);
  stop = true;
  echo.join();
  sink.join();
  ASSERT_TRUE(rc.has_value()) << "proxy did not stop after --duration";
  ASSERT_EQ(*rc, 0) << proxy.stderr_text();
  const auto j = last_json_line(proxy.stdout_text());
  ASSERT_TRUE(j.is_object()) << proxy.stdout_text();
  const auto& up = j["client_to_server"];
  const auto& down = j["server_to_client"];
  EXPECT_EQ(up["received"].get<int>(), kSent);
  // Seeded 20 % loss on 1000: binomial sd 12.6, so +-60 is a wide margin.
  EXPECT_NEAR(up["dropped"].get<int>(), 200, 60);
  EXPECT_EQ(up["delivered"].get<int>(),
            up["received"].get<int>() - up["dropped"].get<int>() + up["duplicated"].get<int>());
  // What the proxy says it delivered is what arrived, each way (loopback loses nothing itself).
  EXPECT_EQ(at_server.load(), up["delivered"].get<int>());
  EXPECT_EQ(down["received"].get<int>(), at_server.load());
  EXPECT_EQ(at_client.load(), down["delivered"].get<int>());
  EXPECT_EQ(j["send_errors"].get<int>(), 0);
  EXPECT_EQ(j["pending"].get<int>(), 0);
  // A datagram is altered when corrupted on either leg; a flip in the 4-byte id goes unseen.
  const int corrupted = up["corrupted"].get<int>() + down["corrupted"].get<int>();
  EXPECT_GT(corrupted, 0);
  EXPECT_LE(altered.load(),
            corrupted + up["duplicated"].get<int>() + down["duplicated"].get<int>());
  EXPECT_GT(altered.load(), corrupted / 2);
}

// The remote's direction as the tests wire it (the remote sends to --listen, the station is
// --forward) through --rate-limit-mbit 2: a fast stream in; what reaches the far end is bounded by
// the bucket, the queue and the rate over the time the stream took to send (with a generous
// slack for a slow proxy), and the proxy's summary counts the drops and reports the limit.
TEST(ImpairProxy, RateLimitThrottlesTheStreamToTheRate) {
  const auto dir = scratch_dir("impair_rate_limit");
  UdpSocket station, remote;
  ASSERT_TRUE(station.bound && remote.bound);
  const auto proxy_port = free_port();
  constexpr double kRateMbit = 2.0, kBurstBytes = 15'000, kQueueMs = 100;
  Process proxy({built_binary("telex-sim-impair").string(), "--listen",
                 "127.0.0.1:" + std::to_string(proxy_port), "--forward",
                 "127.0.0.1:" + std::to_string(station.port()), "--rate-limit-mbit", "2",
                 "--rate-burst-bytes", "15000", "--rate-queue-ms", "100", "--duration", "4",
                 "--json-summary"},
                dir / "proxy.out", dir / "proxy.err");
  ASSERT_TRUE(eventually(5s, [&] {
    return proxy.stderr_text().find("listening on") != std::string::npos;
  })) << proxy.stderr_text();

  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> station_bytes{0};
  std::thread sink([&] {
    std::vector<std::uint8_t> buf(2048);
    pollfd p{station.fd, POLLIN, 0};
    while (!stop) {
      if (poll(&p, 1, 20) <= 0) continue;
      const auto n = recv(station.fd, buf.data(), buf.size(), 0);
      if (n > 0) station_bytes += static_cast<std::uint64_t>(n);
    }
  });
  constexpr int kSent = 3'000;
  constexpr std::size_t kSize = 1'000;
  const std::vector<std::uint8_t> d(kSize, 0x5A);
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < kSent; ++i) {
    remote.send_to(proxy_port, d);
    if (i % 50 == 49) std::this_thread::sleep_for(5ms);  // stay well under socket buffers
  }
  const double send_span_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto rc = proxy.wait(20s);
  stop = true;
  sink.join();
  ASSERT_TRUE(rc.has_value()) << "proxy did not stop after --duration";
  ASSERT_EQ(*rc, 0) << proxy.stderr_text();
  const auto j = last_json_line(proxy.stdout_text());
  ASSERT_TRUE(j.is_object()) << proxy.stdout_text();
  const auto& up = j["client_to_server"];
  EXPECT_EQ(j["rate_limit_mbit"].get<double>(), kRateMbit);

  // What passed: at most the bucket, the queue and the rate over the proxy's receiving span
  // (the sending span plus 1 s); at least a full bucket and queue (the stream overflowed them).
  const double rate_bytes_per_s = kRateMbit * 1e6 / 8.0;
  const double queue_bytes = rate_bytes_per_s * kQueueMs / 1e3;
  const double upper = kBurstBytes + queue_bytes + rate_bytes_per_s * (send_span_s + 1.0);
  const double got = static_cast<double>(station_bytes.load());
  EXPECT_LE(got, upper) << "sent " << kSent * kSize << " bytes in " << send_span_s << " s";
  EXPECT_GE(got, kBurstBytes + queue_bytes - kSize);
  EXPECT_LT(got, 0.5 * kSent * kSize) << "the stream was not throttled";
  // The proxy's own counts agree with what arrived, and every datagram it took is accounted for.
  EXPECT_EQ(up["bytes_out"].get<double>(), got);
  EXPECT_GT(up["rate_dropped"].get<int>(), 0);
  EXPECT_EQ(up["delivered"].get<int>(), up["received"].get<int>() - up["rate_dropped"].get<int>());
  EXPECT_EQ(j["pending"].get<int>(), 0);
}

struct BadRun {
  std::vector<std::string> args;
  std::string expect_in_stderr;
};

void expect_exit_2(const std::string& binary, const std::vector<BadRun>& runs,
                   const std::string& name) {
  const auto dir = scratch_dir(name);
  for (std::size_t i = 0; i < runs.size(); ++i) {
    std::vector<std::string> argv{built_binary(binary).string()};
    argv.insert(argv.end(), runs[i].args.begin(), runs[i].args.end());
    Process p(argv, dir / ("out" + std::to_string(i)), dir / ("err" + std::to_string(i)));
    const auto rc = p.wait(10s);
    ASSERT_TRUE(rc.has_value()) << binary << " run " << i << " did not exit";
    EXPECT_EQ(*rc, 2) << binary << " run " << i << ": " << p.stderr_text();
    const std::string text = p.stderr_text() + p.stdout_text();
    EXPECT_NE(text.find(runs[i].expect_in_stderr), std::string::npos)
        << binary << " run " << i << " says: " << text;
  }
}

TEST(ImpairProxy, BadFlagsAndBusyPortExitTwoNamingTheProblem) {
  UdpSocket busy;
  ASSERT_TRUE(busy.bound);
  const std::string fwd = "127.0.0.1:9";
  expect_exit_2(
      "telex-sim-impair",
      {
          {{"--listen", "127.0.0.1:0"}, "--forward"},
          {{"--listen", "127.0.0.1:0", "--forward", fwd, "--bogus"}, "--bogus"},
          {{"--listen", "127.0.0.1:0", "--forward", fwd, "--loss", "1.5"}, "--loss"},
          {{"--listen", "127.0.0.1:0", "--forward", fwd, "--corrupt", "-0.1"}, "--corrupt"},
          {{"--listen", "127.0.0.1:0", "--forward", fwd, "--delay-ms", "abc"}, "--delay-ms"},
          {{"--listen", "127.0.0.1:0", "--forward", fwd, "--rate-limit-mbit", "-1"},
           "--rate-limit-mbit"},
          {{"--listen", "127.0.0.1:0", "--forward", fwd, "--rate-limit-mbit", "fast"},
           "--rate-limit-mbit"},
          {{"--listen", "127.0.0.1:0", "--forward", fwd, "--rate-queue-ms", "-5"},
           "--rate-queue-ms"},
          {{"--listen", "localhost:0", "--forward", fwd}, "not a numeric IP"},
          {{"--listen", "127.0.0.1:70000", "--forward", fwd}, "--listen"},
          {{"--listen", "127.0.0.1:0", "--forward", "127.0.0.1"}, "--forward"},
          {{"--listen", "127.0.0.1:0", "--forward", "127.0.0.1:0"}, "--forward"},
          {{"--listen", "127.0.0.1:" + std::to_string(busy.port()), "--forward", fwd},
           "cannot bind --listen"},
      },
      "impair_bad_flags");
}

TEST(TelexLocal, BadConfigurationExitsTwoNamingTheProblem) {
  const auto dir = scratch_dir("local_bad_config_files");
  expect_exit_2("telex-local",
                {
                    {{"--no-such-flag"}, "--no-such-flag"},
                    {{"--stiffness", "0"}, "--stiffness"},
                    {{"--max-force", "1e9"}, "--max-force"},
                    {{"--rate", "-5"}, "--rate"},
                    {{"--transport", "carrier-pigeon"}, "--transport"},
                    {{"--connect", "127.0.0.1"}, "--connect"},
                    {{"--connect", "127.0.0.1:0"}, "--connect"},
                    {{"--udp-port", "65536"}, "--udp-port"},
                    {{"--config", (dir / "missing.ini").string()}, "missing.ini"},
                },
                "local_bad_config");
}

// --duration bounds the run even when no remote ever answers: the station gives up at the end of
// its duration (its message says so), not after the longer first-surface timeout.
TEST(TelexLocal, DurationBoundsARunWithNoRemote) {
  const auto dir = scratch_dir("local_duration_unconnected");
  Process local({built_binary("telex-local").string(), "--connect",
                 "127.0.0.1:" + std::to_string(free_port()), "--duration", "1.5",
                 "--first-surface-timeout", "600", "--no-realtime"},
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(std::chrono::seconds(120));
  ASSERT_TRUE(rc.has_value()) << "still running long after --duration 1.5 and no remote";
  EXPECT_EQ(*rc, 1) << local.stderr_text();
  EXPECT_NE(local.stderr_text().find("within 1.5 s (--duration)"), std::string::npos)
      << local.stderr_text();
}

}  // namespace
}  // namespace telex::test
