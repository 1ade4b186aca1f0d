// SPDX-License-Identifier: MIT
// telex-sim-natnet as a separate process on loopback: the client connects and poses arrive.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <boost/asio.hpp>
#include <chrono>
#include <thread>

#include "telex/local/inputs/natnet_client.h"
#include "telex/sim/natnet_server.h"
#include "test_support.h"

extern char** environ;

namespace telex::local {
namespace {

using namespace ::telex::sim;  // the simulators of the other end

int free_udp_port() {
  boost::asio::io_context io;
  boost::asio::ip::udp::socket s(
      io, boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  return s.local_endpoint().port();
}

TEST(NatNetSimProcess, ClientReceivesPosesFromTheSimulatorBinary) {
  const auto bin = telex::test::built_binary("telex-sim-natnet");
  ASSERT_TRUE(std::filesystem::exists(bin)) << bin << " not built";
  const std::string port = std::to_string(free_udp_port());
  std::vector<std::string> args{bin.string(), "--natnet-version", "4.1", "--rate",
                                "100",        "--duration",       "30",  "--command-port",
                                port};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, bin.c_str(), nullptr, nullptr, argv.data(), environ), 0);

  NatNetClientConfig c;
  c.multicast = false;
  c.command_port = std::stoi(port);
  c.body_ids = {kSimHeadId, kSimRightHandId, kSimRightShoulderId};
  bool got = false;
  NatNetSample s;
  {
    NatNetClient client(c);  // repeats its connect request until the process is up
    for (int i = 0; i < 2000 && !got; ++i) {
      got = client.latest(s);
      if (!got) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_TRUE(client.server_info().has_value());
    EXPECT_EQ(client.server_info()->natnet_version, (natnet::Version{4, 1}));
  }
  kill(pid, SIGTERM);  // the simulator stops cleanly on SIGTERM and reports its counts
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
  ASSERT_TRUE(got);
  natnet::Frame truth;
  natnet_press_motion(s.timestamp_s, truth);
  const auto* hand = s.find(kSimRightHandId);
  ASSERT_NE(hand, nullptr);
  EXPECT_NEAR(hand->pose.p_m.z, truth.find_body(kSimRightHandId)->p_m.z, 1e-6);
}

}  // namespace
}  // namespace telex::local
