// SPDX-License-Identifier: MIT
// .oni playback end to end: a recording made here from OpenNI2's Dummy device, played by the
// telex-remote process, received over loopback by the test operator (frames compared pixel for
// pixel with the recording) and by telex-local (its surfaces counted).
#include <gtest/gtest.h>
#include <signal.h>

#include <nlohmann/json.hpp>
#include <set>

#include "daemons.h"
#include "process.h"
#include "telex/remote/openni_record.h"
#include "telex/remote/sources.h"
#include "test_client.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

// Every frame of the file, in order, as this process's oni source plays it (the sources tests
// check that against the frames read while recording).
std::vector<cv::Mat1w> frames_in(const std::filesystem::path& oni) {
  std::vector<cv::Mat1w> out;
  auto source = remote::make_depth_source("oni:" + oni.string() + ",fast");
  source->start();
  for (int i = 0; i < 200; ++i) {
    auto r = source->read(200ms);
    if (r.status == remote::ReadStatus::EndOfStream) break;
    if (r.status == remote::ReadStatus::Frame) out.push_back(r.frame.image.depth_mm.clone());
    EXPECT_NE(r.status, remote::ReadStatus::Error) << r.error;
  }
  source->stop();
  return out;
}

bool same(const cv::Mat1w& a, const cv::Mat1w& b) {
  return a.size() == b.size() && cv::countNonZero(a != b) == 0;
}

std::filesystem::path record_dummy(const std::filesystem::path& dir, int frames) {
  const auto path = dir / "dummy.oni";
  const auto capture = remote::record_oni_frames("Dummy", path, frames);
  EXPECT_EQ(capture.frames(), frames);
  return path;
}

TEST(OniEndToEnd, RemoteProcessSendsTheRecordedFramesExactly) {
  const auto dir = scratch_dir("oni_e2e_client");
  const auto oni = record_dummy(dir, 15);
  const auto recorded = frames_in(oni);
  ASSERT_GE(recorded.size(), 14u);
  // No fill (the Dummy frames are mostly holes) and a lossless codec: what arrives must be the
  // recording itself.
  RemoteProcess remote(dir, {"--no-stats", "--source", "oni:" + oni.string() + ",loop", "--no-fill",
                             "--codec", "zip"});
  ASSERT_TRUE(eventually(10s, [&] {
    return remote.proc.stderr_text().find("listening") != std::string::npos ||
           !remote.proc.running();
  }));
  ASSERT_TRUE(remote.proc.running()) << remote.proc.stderr_text();
  remote::test::TestClient client(remote.port, /*udp=*/true);
  ASSERT_TRUE(client.run_until([&] { return client.frames_.size() >= 40; }, 20s))
      << "frames received: " << client.frames_.size() << "\n"
      << remote.proc.stderr_text();
  client.close();
  EXPECT_EQ(client.decode_errors_, 0u) << client.last_error_;
  ASSERT_TRUE(client.config_.has_value());
  EXPECT_EQ(client.config_->width, 320);
  EXPECT_EQ(client.config_->height, 240);
  std::set<std::size_t> seen;
  for (const auto& [id, f] : client.frames_) {
    std::optional<std::size_t> match;
    for (std::size_t k = 0; k < recorded.size() && !match; ++k)
      if (same(f.depth_mm, recorded[k])) match = k;
    EXPECT_TRUE(match.has_value()) << "received frame " << id << " is not a recorded frame";
    if (match) seen.insert(*match);
  }
  // 40 frames at 30 Hz out of a 15-frame loop: the loop came round, most frames were seen (the
  // operator keeps the newest, so a slow moment can skip one).
  EXPECT_GE(seen.size(), recorded.size() / 2) << "distinct recorded frames received";
}

TEST(OniEndToEnd, OperatorStationConsumesAnOniPlayback) {
  const auto dir = scratch_dir("oni_e2e_local");
  const auto oni = record_dummy(dir, 10);
  RemoteProcess remote(dir, {"--no-stats", "--source", "oni:" + oni.string() + ",loop"});
  Process local(
      {built_binary("telex-local").string(), "--connect",
       "127.0.0.1:" + std::to_string(remote.port), "--haptics", "sim", "--hand", "script:press",
       "--json-summary", "--no-realtime", "--stale-limit", "1.0", "--duration", "3"},
      dir / "local.out", dir / "local.err");
  const auto rc = local.wait(30s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  ASSERT_EQ(*rc, 0) << local.stderr_text() << remote.proc.stderr_text();
  const std::string out = local.stdout_text();
  const auto j = summary_of(local);  // the summary holds nested objects (thread_scheduling)
  ASSERT_TRUE(j.is_object()) << out;
  // About 2.5 s of a 30 Hz playback after connecting: far more than 10 surfaces.
  EXPECT_GT(j["surfaces"].get<int>(), 10) << out;
  EXPECT_TRUE(remote.proc.running()) << "a looping playback must not end";
}

}  // namespace
}  // namespace telex::test
