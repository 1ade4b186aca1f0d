// SPDX-License-Identifier: MIT
// telex-sim-display, the UDP display that tools/fault_soak.sh reads its forces from: every
// command it is sent is one CSV line read with the station's own parser, a malformed datagram is
// counted and never written, and it ends cleanly on SIGINT.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iterator>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "process.h"
#include "telex/local/displays/udp_sink.h"
#include "test_support.h"

namespace telex {
namespace {

using namespace std::chrono_literals;

void send_to(std::uint16_t port, const std::string& text) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  ::inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
  ::sendto(fd, text.data(), text.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to);
  ::close(fd);
}

std::string command(double index_N, bool contact) {
  std::array<local::FingerForce, 5> f{};
  for (int i = 0; i < 5; ++i) f[static_cast<std::size_t>(i)].finger = i;
  f[1].pressure_N = index_N;
  f[1].contact = contact;
  std::array<char, local::kUdpSinkMaxBytes> buf{};
  const auto n = local::format_udp_sink(local::udp_sink_channels(f), buf);
  return std::string(buf.data(), n);
}

TEST(SimDisplay, WritesEachCommandAndCountsTheMalformed) {
  TELEX_REQUIRE_BINARIES("telex-sim-display");
  const auto dir = test::scratch_dir("sim_display");
  const std::uint16_t port = test::free_port();
  const auto csv = dir / "display.csv";
  test::Process display({test::built_binary("telex-sim-display").string(), "--listen",
                         "127.0.0.1:" + std::to_string(port), "--csv", csv.string()},
                        dir / "out.txt", dir / "err.txt");
  ASSERT_TRUE(test::eventually(10s, [&] {
    return display.stderr_text().find("listening") != std::string::npos;
  })) << display.stderr_text();
  send_to(port, command(2.5, true));
  send_to(port, "not a display command");
  send_to(port, command(0.0, false));
  ASSERT_TRUE(test::eventually(10s, [&] {
    std::ifstream in(csv);
    return std::count(std::istreambuf_iterator<char>(in), {}, '\n') >= 3;
  }));
  display.signal(SIGINT);
  const auto rc = display.wait(10s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0);
  std::ifstream in(csv);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0], "rx_ns,from_port,pressure_N,finger,contacts");
  EXPECT_NE(lines[1].find(",2.500,1,1"), std::string::npos) << lines[1];
  EXPECT_NE(lines[2].find(",0.000,0,0"), std::string::npos) << lines[2];
  EXPECT_NE(display.stderr_text().find("3 datagrams, 1 malformed, 1 with force, peak 2.5 N"),
            std::string::npos)
      << display.stderr_text();
}

}  // namespace
}  // namespace telex
