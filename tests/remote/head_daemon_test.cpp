// SPDX-License-Identifier: MIT
// HeadCommands over the wire to a running RemoteDaemon with the sim head: a released dead-man and
// a sample the station repeats as if new both hold the head where it was last commanded (braking
// to rest), read from the daemon's --log-head rows; pressing again moves it on. And a daemon that
// stops leaves its head holding.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "process.h"
#include "telex/remote/daemon.h"
#include "telex/remote/sources.h"
#include "test_client.h"

namespace telex::remote {
namespace {

using namespace std::chrono_literals;

struct LogRow {
  std::int64_t t_ns = 0;
  double yaw_rad = 0;
  double cmd_yaw_rad = 0;
  std::string hold;
};

std::vector<LogRow> read_log(const std::filesystem::path& p) {
  std::vector<LogRow> rows;
  for (const auto& r : ::telex::test::read_csv_file(p).rows)
    if (r.size() == 13 && r[1] == "1" && !r[5].empty())
      rows.push_back({std::stoll(r[0]), std::stod(r[2]), std::stod(r[5]), r[12]});
  return rows;
}

// Each run of rows holding for `reason`: the head must have been moving in the 50 ms before it
// (so the hold stopped it); the command brakes to rest within the run and stays there (the log's
// 1e-6 rad rounding); the measured yaw only closes on it, never turning back or passing it (the
// sim servo lags its command). Returns how many runs there were.
int check_holds(const std::vector<LogRow>& rows, const std::string& reason) {
  int runs = 0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (rows[i].hold != reason || rows[i - 1].hold == reason) continue;
    ++runs;
    std::size_t before = i;
    while (before > 0 && rows[before].t_ns > rows[i].t_ns - 50'000'000) --before;
    std::size_t end = i;
    while (end < rows.size() && rows[end].hold == reason) ++end;
    const double rest = rows[end - 1].cmd_yaw_rad;
    std::size_t at_rest = end - 1;
    while (at_rest > i && std::abs(rows[at_rest - 1].cmd_yaw_rad - rest) < 2e-6) --at_rest;
    const double toward = rest >= rows[i].yaw_rad ? 1.0 : -1.0;
    double turned_back = 0, past = 0;
    for (std::size_t k = i + 1; k < end; ++k) {
      turned_back = std::max(turned_back, -toward * (rows[k].yaw_rad - rows[k - 1].yaw_rad));
      past = std::max(past, -toward * (rest - rows[k].yaw_rad));
    }
    std::printf(
        "hold '%s': yaw %.4f rad, moving %.4f rad in the 50 ms before; the command at rest at "
        "%.4f rad after %.0f ms, the head %.4f rad from it at the end, over %zu loops\n",
        reason.c_str(), rows[i].yaw_rad, std::abs(rows[i].yaw_rad - rows[before].yaw_rad), rest,
        static_cast<double>(rows[at_rest].t_ns - rows[i].t_ns) * 1e-6,
        std::abs(rows[end - 1].yaw_rad - rest), end - i);
    EXPECT_GT(std::abs(rows[i].yaw_rad - rows[before].yaw_rad), 0.01) << reason;
    EXPECT_GT(end - i, 10u) << reason;
    EXPECT_LT(at_rest + 2, end) << reason << ": the command never came to rest";
    EXPECT_LT(turned_back, 2e-6) << reason;
    EXPECT_LT(past, 2e-6) << reason;
  }
  return runs;
}

TEST(HeadDaemon, AReleasedDeadManAndARepeatedSampleHoldTheSimHead) {
  const auto dir = ::telex::test::scratch_dir("head_daemon_holds");
  DaemonConfig cfg;
  cfg.depth_source = "synthetic:plane";
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  cfg.server.port = 0;
  cfg.stats_line = false;
  cfg.realtime = false;
  cfg.head = "sim";
  cfg.head_log_csv = dir / "head.csv";
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient client(d.port(), /*udp=*/false);
  ASSERT_TRUE(client.run_until([&] { return client.accept_.has_value(); }, 10s));
  std::uint32_t id = 0;
  // One HeadCommand every 5 ms, as the station sends them, for `ms`.
  const auto send_for = [&](int ms, float yaw, proto::DeadmanState deadman, bool repeat) {
    if (!repeat) ++id;
    for (int t = 0; t < ms; t += 5) {
      proto::HeadCommand c;
      c.joint_rad = {yaw, 0.0f, 0.0f};
      c.sample_id = repeat ? id : ++id;
      c.sample_age_us = repeat ? 0 : 2000;  // a repeat claims to be new: the old station's bug
      c.operator_ns = static_cast<std::uint64_t>(steady_now_ns() - c.sample_age_us * 1000);
      c.deadman = deadman;
      client.send(c);
      std::this_thread::sleep_for(5ms);
    }
  };
  using DS = proto::DeadmanState;
  // On its way to +1 rad (0.4 s of travel): released midway, the command brakes short of it.
  send_for(150, 1.0f, DS::Pressed, false);
  send_for(400, 1.0f, DS::Released, false);
  send_for(250, -1.0f, DS::Pressed, false);  // back toward -1 rad
  send_for(400, -1.0f, DS::Pressed, true);   // one sample resent as new
  const DaemonStats s = d.stats();
  client.close();
  d.stop();

  const std::vector<LogRow> rows = read_log(dir / "head.csv");
  ASSERT_GT(rows.size(), 100u);
  EXPECT_EQ(check_holds(rows, "deadman"), 1);
  EXPECT_EQ(check_holds(rows, "repeat"), 1);
  EXPECT_EQ(s.head_control.deadman_holds, 1u);
  EXPECT_EQ(s.head_control.repeat_holds, 1u);
  // Pressed again, it moved on: the head went back below zero after the dead-man hold.
  double lowest = 1.0;
  for (const LogRow& r : rows) lowest = std::min(lowest, r.yaw_rad);
  EXPECT_LT(lowest, 0.0);
}

// Issue 49 (8): a station whose send queue backed up delivers HeadCommands late, each judged
// fresh (2 ms) when it was built but 400 ms old when it arrives. The remote judges a command's
// age at its arrival, on the operator's clock (the offset its own heartbeat probes measure, which
// the station answers): such commands hold the head. Fresh ones after them move it. The station
// here is the test client on this host, whose steady clock is the station's clock.
TEST(HeadDaemon, CommandsThatArriveOldHoldTheHeadWhateverAgeTheyWereSentWith) {
  const auto dir = ::telex::test::scratch_dir("head_daemon_backlog");
  DaemonConfig cfg;
  cfg.depth_source = "synthetic:plane";
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  cfg.server.port = 0;
  cfg.stats_line = false;
  cfg.realtime = false;
  cfg.head = "sim";
  cfg.head_log_csv = dir / "head.csv";
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient client(d.port(), /*udp=*/false);
  ASSERT_TRUE(client.run_until([&] { return client.accept_.has_value(); }, 10s));
  std::uint32_t id = 0;
  // One HeadCommand every 5 ms toward +1 rad for `ms`, its sample taken `late_ns` before it goes
  // out yet claiming to be 2 ms old; between sends the client answers the remote's probes.
  const auto send_for = [&](int ms, std::int64_t late_ns) {
    for (int t = 0; t < ms; t += 5) {
      proto::HeadCommand c;
      c.joint_rad = {1.0f, 0.0f, 0.0f};
      c.sample_id = ++id;
      c.sample_age_us = 2000;
      c.operator_ns = static_cast<std::uint64_t>(steady_now_ns() - late_ns);
      client.send(c);
      client.run_until([] { return false; }, 5ms);
    }
  };
  send_for(600, 400'000'000);
  const std::int64_t fresh_from_ns = steady_now_ns();
  const DaemonStats held = d.stats();
  send_for(300, 2'000'000);
  client.close();
  d.stop();

  const std::vector<LogRow> rows = read_log(dir / "head.csv");
  ASSERT_GT(rows.size(), 50u);
  double moved_while_late = 0, moved_after = 0;
  std::size_t late_rows = 0;
  for (const LogRow& r : rows) {
    if (r.t_ns < fresh_from_ns) {
      ++late_rows;
      moved_while_late = std::max(moved_while_late, std::abs(r.yaw_rad));
      EXPECT_NE(r.hold, "none") << "moved by a command 400 ms old at " << r.t_ns;
    } else {
      moved_after = std::max(moved_after, std::abs(r.yaw_rad));
    }
  }
  std::printf(
      "backlog: %zu loops with commands 400 ms late, yaw at most %.6f rad (%llu stale holds); "
      "then fresh ones: yaw %.4f rad\n",
      late_rows, moved_while_late, static_cast<unsigned long long>(held.head_control.stale_holds),
      moved_after);
  EXPECT_GT(late_rows, 30u);
  EXPECT_GT(held.head_control.targets, 50u);
  EXPECT_LT(moved_while_late, 1e-6);
  EXPECT_GT(moved_after, 0.05);
}

// A lab's head controller (--head udp) that never moves: it answers every target with the same
// measured pose. The remote's commands run ahead of it (rate-limited from the last command);
// when the daemon stops, its last datagram must be the measured pose, so the head stays put.
class StillController {
 public:
  explicit StillController(HeadAngles pose) : pose_(pose) {
    fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    socklen_t n = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n);
    port_ = ntohs(a.sin_port);
    timeval tv{0, 20'000};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    thread_ = std::thread([this] { serve(); });
  }
  ~StillController() {
    stop_ = true;
    thread_.join();
    ::close(fd_);
  }
  std::uint16_t port() const { return port_; }
  std::vector<HeadAngles> targets() {
    std::lock_guard lock(mu_);
    return targets_;
  }

 private:
  void serve() {
    std::uint32_t seq = 0;
    while (!stop_) {
      std::array<std::uint8_t, 64> buf{};
      sockaddr_in from{};
      socklen_t n = sizeof from;
      const ssize_t got =
          ::recvfrom(fd_, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &n);
      if (got <= 0) continue;
      const auto d = decode_head_datagram(std::span(buf.data(), static_cast<std::size_t>(got)));
      if (!d) continue;
      {
        std::lock_guard lock(mu_);
        targets_.push_back(d->joint_rad);
      }
      const auto reply = encode_head_datagram({seq++, 0, pose_});
      ::sendto(fd_, reply.data(), reply.size(), 0, reinterpret_cast<sockaddr*>(&from), n);
    }
  }

  HeadAngles pose_;
  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::mutex mu_;
  std::vector<HeadAngles> targets_;
  std::thread thread_;
};

TEST(HeadDaemon, StoppingLeavesTheHeadHoldingWhereItIs) {
  const HeadAngles where{0.05, 0.0, 0.0};
  StillController controller(where);
  DaemonConfig cfg;
  cfg.depth_source = "synthetic:plane";
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  cfg.server.port = 0;
  cfg.stats_line = false;
  cfg.realtime = false;
  cfg.head = "udp:127.0.0.1:" + std::to_string(controller.port());
  RemoteDaemon d(cfg);
  d.start();
  test::TestClient client(d.port(), /*udp=*/false);
  ASSERT_TRUE(client.run_until([&] { return client.accept_.has_value(); }, 10s));
  std::uint32_t id = 0;
  for (int t = 0; t < 300; t += 5) {  // toward +1 rad while the controller stays at 0.05
    proto::HeadCommand c;
    c.joint_rad = {1.0f, 0.0f, 0.0f};
    c.sample_id = ++id;
    c.sample_age_us = 2000;
    c.operator_ns = static_cast<std::uint64_t>(steady_now_ns() - 2'000'000);
    client.send(c);
    client.run_until([] { return false; }, 5ms);  // and answers the remote's probes
  }
  d.stop();  // mid-move: the link is alive and the commands run ahead
  client.close();
  std::this_thread::sleep_for(100ms);  // the last datagram's way over loopback
  const std::vector<HeadAngles> targets = controller.targets();
  ASSERT_GT(targets.size(), 10u);
  double ahead = 0;
  for (const HeadAngles& t : targets) ahead = std::max(ahead, t[0]);
  std::printf("udp head: %zu targets, up to %.4f rad while the head stayed at %.2f; last %.4f\n",
              targets.size(), ahead, where[0], targets.back()[0]);
  EXPECT_GT(ahead, 0.2);
  EXPECT_EQ(targets.back(), where);
}

TEST(HeadDaemon, AHeadLogWithoutAHeadOrAFolderIsAUsageError) {
  DaemonConfig cfg;
  cfg.depth_source = "synthetic:plane";
  cfg.head_log_csv = "head.csv";
  const auto message = [&] {
    try {
      validate(cfg);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_NE(message().find("--log-head logs the head loop, which runs only with a head"),
            std::string::npos)
      << message();
  cfg.head = "sim";
  EXPECT_EQ(message(), "(accepted)");
  cfg.source_options.width = 160;
  cfg.source_options.height = 120;
  cfg.server.port = 0;
  cfg.realtime = false;
  cfg.head_log_csv = "/nonexistent/telex/head.csv";
  RemoteDaemon d(cfg);
  try {
    d.start();
    ADD_FAILURE() << "started with an unwritable --log-head";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(
        std::string(e.what()).find("--log-head /nonexistent/telex/head.csv: cannot be written"),
        std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace telex::remote
