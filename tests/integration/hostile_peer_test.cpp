// SPDX-License-Identifier: MIT
// A hostile station against telex-remote as a process: a heartbeat flood and a NACK storm from a
// station that never reads leave the remote's memory bounded, and what bounded it is counted.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <fstream>
#include <string>

#include "daemons.h"
#include "process.h"
#include "test_client.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

// Resident set of process `pid` in KiB (/proc/PID/status VmRSS).
long vm_rss_kib(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

TEST(HostilePeer, HeartbeatFloodAndNackStormFromAPeerThatNeverReadsKeepTheRemoteBounded) {
  const auto dir = scratch_dir("hostile_flood");
  RemoteProcess remote(dir, {"--source", "synthetic:moving", "--no-realtime"});
  ASSERT_TRUE(eventually(10s, [&] {
    return remote.proc.stderr_text().find("listening") != std::string::npos ||
           !remote.proc.running();
  }));
  ASSERT_TRUE(remote.proc.running()) << remote.proc.stderr_text();

  // Depth over TCP with repair: everything the remote answers waits in its own queues once this
  // station stops reading.
  remote::test::TestClient client(remote.port, /*udp=*/false, proto::kCapRepair);
  ASSERT_TRUE(client.run_until([&] { return client.frames_.size() >= 3; }, 20s))
      << remote.proc.stderr_text();
  ASSERT_TRUE(client.config_.has_value());
  const proto::TileGrid grid{client.config_->width, client.config_->height,
                             client.config_->tile_width, client.config_->tile_height};
  proto::TileNack every_tile{client.frames_.rbegin()->first, {}};
  for (std::size_t t = 0; t < static_cast<std::size_t>(grid.count()); ++t)
    every_tile.tiles.push_back(static_cast<std::uint16_t>(t));
  const long rss_before = vm_rss_kib(remote.proc.pid());
  ASSERT_GT(rss_before, 0);

  // From here on the station never reads: the remote's writes stall. 200,000 probes would queue
  // 200,000 answers (about 34 MB) and 20,000 NACKs of every tile up to 20,000 key frames of
  // resends (gigabytes) without the bounds.
  constexpr int kProbes = 200'000, kNacks = 20'000;
  for (int i = 0; i < kProbes; ++i)
    client.send(proto::Heartbeat{static_cast<std::uint64_t>(i + 1), 0, 0, 0});
  for (int i = 0; i < kNacks; ++i) client.send(every_tile);
  ASSERT_TRUE(
      eventually(30s, [&] { return last_counter(remote.proc.stderr_text(), "nacks") >= kNacks; }))
      << "the remote's stats line never counted the NACKs: " << remote.proc.stderr_text();
  const long rss_after = vm_rss_kib(remote.proc.pid());
  ASSERT_TRUE(remote.proc.running()) << remote.proc.stderr_text();

  const auto counter = [&](const char* key) {
    return static_cast<std::uint64_t>(std::max(0L, last_counter(remote.proc.stderr_text(), key)));
  };
  const auto dropped = counter("control-dropped");
  const auto dup = counter("repair-dup");
  const auto budget = counter("over-budget");
  const auto queue = counter("over-queue");
  const auto repaired = counter("repaired");
  std::printf(
      "remote RSS %ld -> %ld KiB (+%ld KiB) after %d probes and %d NACKs of %zu tiles; "
      "control-dropped %llu, repaired %llu, repair-dup %llu, over-budget %llu, over-queue %llu\n",
      rss_before, rss_after, rss_after - rss_before, kProbes, kNacks, every_tile.tiles.size(),
      static_cast<unsigned long long>(dropped), static_cast<unsigned long long>(repaired),
      static_cast<unsigned long long>(dup), static_cast<unsigned long long>(budget),
      static_cast<unsigned long long>(queue));
  // The bound: 32 MiB over the remote's own working set, for queues capped at 64 control
  // messages, 3 frames and 512 KiB of resends.
  EXPECT_LT(rss_after - rss_before, 32 * 1024);
  EXPECT_GT(dropped, 0u) << "the probes never met the control queue's bound";
  EXPECT_GT(dup + budget + queue, 0u) << "the NACKs never met the repair bounds";
  EXPECT_LT(repaired, static_cast<std::uint64_t>(kNacks) * every_tile.tiles.size() / 100);
  client.close();
}

}  // namespace
}  // namespace telex::test
