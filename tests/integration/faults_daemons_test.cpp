// SPDX-License-Identifier: MIT
// Fault tests on both daemons: loss and delay through telex-sim-impair, remote and station killed
// and restarted, junk on every listening port, and bad remote configuration.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <thread>

#include "process.h"
#include "telex/proto/messages.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

#define TELEX_REQUIRE_REMOTE() TELEX_REQUIRE_BINARIES("telex-remote")

nlohmann::json last_json_line(std::string out) {
  while (!out.empty() && out.back() == '\n') out.pop_back();
  const auto nl = out.rfind('\n');
  return nlohmann::json::parse(nl == std::string::npos ? out : out.substr(nl + 1), nullptr, false);
}

Process start_remote(std::uint16_t port, const std::filesystem::path& dir, const std::string& tag) {
  return Process(
      {built_binary("telex-remote").string(), "--listen", "127.0.0.1:" + std::to_string(port),
       "--transport", "udp", "--source", "synthetic:plane"},
      dir / ("remote" + tag + ".out"), dir / ("remote" + tag + ".err"));
}

std::vector<std::string> local_argv(std::uint16_t port, std::vector<std::string> extra) {
  std::vector<std::string> a{built_binary("telex-local").string(),
                             "--connect",
                             "127.0.0.1:" + std::to_string(port),
                             "--haptics",
                             "sim",
                             "--no-realtime",
                             "--quiet",
                             "--json-summary",
                             "--first-surface-timeout",
                             "20"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

class LossThroughProxy : public ::testing::TestWithParam<double> {};

TEST_P(LossThroughProxy, StationStillGetsSurfacesAndTheProxyCountsTheLoss) {
  TELEX_REQUIRE_REMOTE();
  const double loss = GetParam();
  const auto dir = scratch_dir("loss_" + std::to_string(static_cast<int>(loss * 100)));
  const auto port = free_port(), udp_port = free_port(), proxy_port = free_port();
  Process remote = start_remote(port, dir, "");
  Process proxy({built_binary("telex-sim-impair").string(), "--listen",
                 "127.0.0.1:" + std::to_string(proxy_port), "--forward",
                 "127.0.0.1:" + std::to_string(udp_port), "--loss", std::to_string(loss),
                 "--delay-ms", "50", "--seed", "7", "--json-summary"},
                dir / "proxy.out", dir / "proxy.err");
  Process local(
      local_argv(port, {"--udp-port", std::to_string(udp_port), "--udp-announce-port",
                        std::to_string(proxy_port), "--hand", "script:press", "--duration", "5"}),
      dir / "local.out", dir / "local.err");
  const auto rc = local.wait(45s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  EXPECT_EQ(*rc, 0) << local.stderr_text();
  EXPECT_TRUE(remote.running()) << remote.stderr_text();
  proxy.signal(SIGINT);
  ASSERT_TRUE(proxy.wait(10s).has_value());
  const auto s = last_json_line(local.stdout_text());
  ASSERT_TRUE(s.is_object()) << local.stdout_text();
  EXPECT_GT(s["surfaces"].get<int>(), 0);
  const auto j = last_json_line(proxy.stdout_text());
  ASSERT_TRUE(j.is_object()) << proxy.stdout_text();
  const auto& up = j["client_to_server"];
  const int received = up["received"].get<int>();
  ASSERT_GT(received, 100) << "the depth stream did not go through the proxy";
  // Binomial bound: 5 sd plus one datagram.
  const double sd = std::sqrt(received * loss * (1 - loss));
  EXPECT_NEAR(up["dropped"].get<int>(), loss * received, 5 * sd + 1);
  remote.signal(SIGINT);
  remote.wait(5s);
}

INSTANTIATE_TEST_SUITE_P(Faults, LossThroughProxy, ::testing::Values(0.05, 0.20));

struct Row {
  double t = 0, pressure = 0;
  std::string status;
};

std::vector<Row> index_rows(const std::filesystem::path& csv) {
  std::vector<Row> rows;
  std::istringstream in(read_text(csv));
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    if (f.size() < 10 || f[1] != "index") continue;
    rows.push_back({std::stod(f[0]), std::stod(f[2]), f[9]});
  }
  return rows;
}

TEST(RemoteRestart, ForcesFadeWithinTheStaleLimitAndTheStationReconnects) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("remote_restart");
  const auto port = free_port();
  auto remote = std::make_unique<Process>(start_remote(port, dir, "1"));
  Process local(local_argv(port, {"--hand", "script:press", "--repeat", "--duration", "14",
                                  "--stiffness", "500", "--max-force", "10", "--stale-limit", "0.2",
                                  "--log-forces", (dir / "forces.csv").string()}),
                dir / "local.out", dir / "local.err");
  ASSERT_TRUE(eventually(20s, [&] {
    return local.stderr_text().find("remote streaming") != std::string::npos;
  })) << local.stderr_text();
  std::this_thread::sleep_for(4s);
  remote->signal(SIGKILL);
  remote->wait(5s);
  const auto killed = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(1s);
  remote = std::make_unique<Process>(start_remote(port, dir, "2"));
  const double outage_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  const auto rc = local.wait(40s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << local.stderr_text();
  EXPECT_TRUE(remote->running()) << remote->stderr_text();

  const auto rows = index_rows(dir / "forces.csv");
  ASSERT_GT(rows.size(), 1000u);
  // The outage: the longest run of stale-surface rows after fresh ones (a loaded machine's slow
  // frames make short ones before it with --stale-limit 0.2), and the last fresh row before it.
  std::size_t first_stale = rows.size();
  double longest = -1;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (rows[i].status != "stale-surface" || rows[i - 1].status == "stale-surface" ||
        rows[i - 1].status == "no-surface")
      continue;
    std::size_t end = i;
    while (end + 1 < rows.size() && rows[end + 1].status == "stale-surface") ++end;
    if (rows[end].t - rows[i].t > longest) {
      longest = rows[end].t - rows[i].t;
      first_stale = i;
    }
  }
  ASSERT_LT(first_stale, rows.size()) << "forces never went stale after the remote was killed";
  // The remote was down for at least the 1 s the test waited before restarting it.
  EXPECT_GT(longest, 0.5) << "no stale run as long as the outage";
  const double t_fresh = rows[first_stale - 1].t;
  double peak_before = 0;
  for (std::size_t i = 0; i < first_stale; ++i)
    peak_before = std::max(peak_before, rows[i].pressure);
  EXPECT_GT(peak_before, 0.5) << "the press never touched the plane before the kill";
  // Surface at most 0.2 s old at t_fresh, so stale by t_fresh + 0.2, faded (0.1 s) by + 0.3.
  std::size_t recovered = rows.size();
  for (std::size_t i = first_stale; i < rows.size(); ++i) {
    if (rows[i].status != "stale-surface") {
      recovered = i;
      break;
    }
    if (rows[i].t > t_fresh + 0.2 + 0.1 + 0.01) {
      ASSERT_EQ(rows[i].pressure, 0.0) << "force not zero " << rows[i].t - t_fresh << " s in";
    }
  }
  ASSERT_LT(recovered, rows.size()) << "no fresh surface after the remote came back";
  // Back within 2 s of the restart (back-off is at most 1 s; 0.5 s for the loaded machine).
  EXPECT_LT(rows[recovered].t - t_fresh, outage_s + 2.0 + 0.5) << "outage " << outage_s << " s";
  remote->signal(SIGINT);
  remote->wait(5s);
}

TEST(StationRestart, RemoteAcceptsTheStationAgainAfterSigkill) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("station_restart");
  const auto port = free_port();
  Process remote = start_remote(port, dir, "");
  {
    Process first(local_argv(port, {"--hand", "script:press", "--duration", "20"}),
                  dir / "local1.out", dir / "local1.err");
    ASSERT_TRUE(eventually(20s, [&] {
      return first.stderr_text().find("remote streaming") != std::string::npos;
    })) << first.stderr_text();
    std::this_thread::sleep_for(1s);
    first.signal(SIGKILL);
    first.wait(5s);
  }
  Process second(local_argv(port, {"--hand", "script:press", "--duration", "3"}),
                 dir / "local2.out", dir / "local2.err");
  const auto rc = second.wait(40s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << second.stderr_text() << remote.stderr_text();
  const auto s = last_json_line(second.stdout_text());
  ASSERT_TRUE(s.is_object()) << second.stdout_text();
  EXPECT_GT(s["surfaces"].get<int>(), 0);
  EXPECT_TRUE(remote.running());
  remote.signal(SIGINT);
  remote.wait(5s);
}

// A bounded menu of hostile inputs: random, truncated, oversize length, wrong magic, wrong
// version, a well-formed message of a foreign session.
std::vector<std::uint8_t> junk(int kind, std::mt19937& rng, bool stream) {
  std::vector<std::uint8_t> m;
  proto::Header h;
  h.session_id = 0xBADBAD;
  h.seq = static_cast<std::uint32_t>(rng());
  switch (kind % 6) {
    case 0:
      m.resize(1 + rng() % 1500);
      for (auto& b : m) b = static_cast<std::uint8_t>(rng());
      return m;
    case 1:
      m = proto::encode_stream(h, proto::Heartbeat{1, 2, 3, 4});
      m.resize(rng() % m.size());
      return m;
    case 2:
      m = {0xFF, 0xFF, 0xFF, 0x7F};  // a 2 GiB length prefix
      return m;
    case 3:
      h.magic = 0x58585858u;
      break;
    case 4:
      h.version = 99;
      break;
    default:
      break;  // valid bytes, wrong session
  }
  return stream ? proto::encode_stream(h, proto::Heartbeat{1, 2, 3, 4})
                : proto::encode(h, proto::Heartbeat{1, 2, 3, 4});
}

TEST(BadInput, DaemonsStayUpAndKeepServingTheRealSession) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("bad_input");
  const auto port = free_port(), udp_port = free_port();
  Process remote = start_remote(port, dir, "");
  ASSERT_TRUE(eventually(10s, [&] {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    const bool ok = connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    close(fd);
    return ok;
  }));
  std::atomic<bool> stop{false};
  std::atomic<int> sent{0};
  // Junk to the remote's TCP and UDP port and the station's UDP port, bounded in count and rate.
  std::thread attacker([&] {
    std::mt19937 rng(1234);
    for (int i = 0; i < 3000 && !stop; ++i) {
      tcp_blurt(port, junk(i, rng, true));
      udp_blurt(port, junk(i, rng, false));
      udp_blurt(udp_port, junk(i, rng, false));
      ++sent;
      if (i % 20 == 19) std::this_thread::sleep_for(10ms);
    }
  });
  Process local(local_argv(port, {"--udp-port", std::to_string(udp_port), "--hand", "script:press",
                                  "--duration", "5"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(45s);
  stop = true;
  attacker.join();
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << local.stderr_text();
  EXPECT_GT(sent.load(), 100);
  const auto s = last_json_line(local.stdout_text());
  ASSERT_TRUE(s.is_object()) << local.stdout_text();
  EXPECT_GT(s["surfaces"].get<int>(), 30);
  EXPECT_TRUE(remote.running()) << remote.stderr_text();
  remote.signal(SIGINT);
  const auto rrc = remote.wait(10s);
  ASSERT_TRUE(rrc.has_value());
  EXPECT_EQ(*rrc, 0) << remote.stderr_text();
}

TEST(RemoteConfig, BadConfigurationExitsTwo) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("remote_bad_config");
  // A TCP listener holding a port makes --listen on it fail.
  const int busy = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(busy, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(listen(busy, 1), 0);
  socklen_t len = sizeof a;
  getsockname(busy, reinterpret_cast<sockaddr*>(&a), &len);
  const std::string busy_port = std::to_string(ntohs(a.sin_port));
  const std::vector<std::vector<std::string>> runs{
      {"--no-such-flag"},
      {"--listen", "127.0.0.1:99999"},
      {"--listen", "127.0.0.1:" + busy_port, "--source", "synthetic:plane"},
      {"--transport", "carrier-pigeon"},
  };
  for (std::size_t i = 0; i < runs.size(); ++i) {
    std::vector<std::string> argv{built_binary("telex-remote").string()};
    argv.insert(argv.end(), runs[i].begin(), runs[i].end());
    Process p(argv, dir / ("out" + std::to_string(i)), dir / ("err" + std::to_string(i)));
    const auto rc = p.wait(10s);
    ASSERT_TRUE(rc.has_value()) << "run " << i << " did not exit";
    EXPECT_EQ(*rc, 2) << "run " << i << ": " << p.stderr_text();
    EXPECT_FALSE(p.stderr_text().empty()) << "run " << i << " gave no message";
  }
  close(busy);
}

}  // namespace
}  // namespace telex::test
