// SPDX-License-Identifier: MIT
// A hostile station against telex-remote as a process: a heartbeat flood, a NACK storm and a storm
// of VideoNacks from a station that stops reading leave the remote's memory bounded, and what
// bounded it is counted.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>

#include "daemons.h"
#include "process.h"
#include "telex/video/frame_header.h"
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
  if (kResidentMemoryMeaningful) {
    EXPECT_LT(rss_after - rss_before, 32 * 1024);
  }
  EXPECT_GT(dropped, 0u) << "the probes never met the control queue's bound";
  EXPECT_GT(dup + budget + queue, 0u) << "the NACKs never met the repair bounds";
  EXPECT_LT(repaired, static_cast<std::uint64_t>(kNacks) * every_tile.tiles.size() / 100);
  client.close();
}

// Resent pairs count against the send queue's bound of queued resends (512 KiB, PROTOCOL.md
// 2.7), as tiles do. The eyes are 16 pairs of noise that play once through MJPEG, each pair
// about 100 kB: the remote's cache keeps all 16 after they end, every VideoNack of them is
// answerable, and five resent pairs fill the bound.
TEST(HostilePeer, VideoNacksFromAPeerThatStopsReadingAreRefusedOverTheResendBound) {
  const auto dir = scratch_dir("hostile_video_nack");
  constexpr int kPairs = 16;
  cv::RNG rng(28);
  for (int i = 0; i < kPairs; ++i)
    for (const char* eye : {"left", "right"}) {
      cv::Mat3b img(240, 320);
      rng.fill(img, cv::RNG::UNIFORM, 0, 256);
      char name[32];
      std::snprintf(name, sizeof name, "%s%02d.png", eye, i);
      ASSERT_TRUE(cv::imwrite((dir / name).string(), img));
    }
  RemoteProcess remote(
      dir,
      {"--source", "synthetic:moving", "--no-realtime", "--video-codec", "mjpeg", "--stereo",
       "files:" + (dir / "left*.png").string() + "," + (dir / "right*.png").string() + ",fps=30"});
  ASSERT_TRUE(eventually(10s, [&] {
    return remote.proc.stderr_text().find("listening") != std::string::npos ||
           !remote.proc.running();
  }));
  ASSERT_TRUE(remote.proc.running()) << remote.proc.stderr_text();

  // Depth and eyes over TCP with repair, so what the remote sends waits in its own queue once
  // this station stops reading; a small receive buffer makes that happen soon.
  remote::test::TestClient client(remote.port, /*udp=*/false, proto::kCapRepair | proto::kCapVideo);
  client.cap_receive_buffer(64 * 1024);
  // Until the eyes have played (pairs the full video lane dropped are cached all the same), with
  // a heartbeat now and then: a station silent for 3 s is gone.
  const auto eyes_ended = [&] {
    return remote.proc.stderr_text().find("| eyes ended") != std::string::npos;
  };
  for (int i = 0;
       i < 150 && !(eyes_ended() && !client.video_.empty() && client.frames_.size() >= 3); ++i) {
    client.send(proto::Heartbeat{static_cast<std::uint64_t>(i + 1), 0, 0, 0});
    client.run_until([] { return false; }, 200ms);
  }
  ASSERT_TRUE(eyes_ended() && !client.video_.empty() && client.frames_.size() >= 3)
      << client.video_.size() << " pairs, " << client.frames_.size() << " depth frames; "
      << remote.proc.stderr_text();
  std::uint32_t last_seq = 0;
  std::size_t smallest_pair = SIZE_MAX;
  for (const auto& v : client.video_) {
    const auto parsed = video::parse_frame(v.frame);
    ASSERT_EQ(parsed.status, video::HeaderStatus::Ok);
    last_seq = parsed.header.encode_seq;
    smallest_pair = std::min(smallest_pair, v.frame.size());
  }
  ASSERT_GE(last_seq, static_cast<std::uint32_t>(kPairs - 1));  // the last pair came
  // Large enough that a few fill the bound, small enough for the byte budget's burst.
  ASSERT_GT(smallest_pair, 64u * 1024u);
  ASSERT_LT(smallest_pair, 200u * 1024u);
  const std::uint32_t last_depth_frame = client.frames_.rbegin()->first;
  const long rss_before = vm_rss_kib(remote.proc.pid());
  ASSERT_GT(rss_before, 0);

  // From here on the station does not read, and asks for the remote's 16 cached pairs again
  // every 12 ms (just over the remote's dedup interval) for 18 s or more: without the bound the
  // byte budget alone would let 1.25 MB/s of resends pile up in the remote's queue.
  const proto::VideoNack all{last_seq - (kPairs - 1), static_cast<std::uint16_t>(kPairs)};
  constexpr int kNacks = 1500;
  for (int i = 0; i < kNacks; ++i) {
    client.send(all);
    std::this_thread::sleep_for(12ms);
  }
  ASSERT_TRUE(eventually(
      10s, [&] { return last_counter(remote.proc.stderr_text(), "pair-nacks") >= kNacks; }))
      << "the remote's stats line never counted the VideoNacks: " << remote.proc.stderr_text();
  const long rss_after = vm_rss_kib(remote.proc.pid());
  ASSERT_TRUE(remote.proc.running()) << remote.proc.stderr_text();
  const auto counter = [&](const char* key) {
    return static_cast<std::uint64_t>(std::max(0L, last_counter(remote.proc.stderr_text(), key)));
  };
  const auto resent = counter("resent");
  const auto over_queue = counter("pair-over-queue");
  const auto budget = counter("over-budget");
  std::printf(
      "remote RSS %ld -> %ld KiB (%+ld KiB) after %d VideoNacks of %d pairs of >= %zu bytes; "
      "resent %llu, pair-over-queue %llu, over-budget %llu\n",
      rss_before, rss_after, rss_after - rss_before, kNacks, kPairs, smallest_pair,
      static_cast<unsigned long long>(resent), static_cast<unsigned long long>(over_queue),
      static_cast<unsigned long long>(budget));
  EXPECT_GT(over_queue, 0u) << "no resent pair met the bound of queued resends";
  // The bound: 12 MiB over the remote's working set (measured: +7 MiB with the bound, +19 MiB
  // without it over 1000 VideoNacks, 1.25 MB/s of resends piling up).
  if (kResidentMemoryMeaningful) {
    EXPECT_LT(rss_after - rss_before, 12 * 1024);
  }

  // Reading again: depth comes through, decoded whole (a key frame after the frames the full
  // queue dropped), not stuck behind the resends.
  ASSERT_TRUE(client.run_until(
      [&] {
        return client.frames_.size() > 0 &&
               static_cast<std::int32_t>(client.frames_.rbegin()->first - last_depth_frame) > 3;
      },
      30s))
      << remote.proc.stderr_text();
  EXPECT_EQ(client.decode_errors_, 0u) << client.last_error_;
  client.close();
}

}  // namespace
}  // namespace telex::test
