// SPDX-License-Identifier: MIT
// A file sequence without loop waits for its operator: telex-remote holds it until the first
// station connects, plays it to that station, and stops after the station leaves.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>

#include "daemons.h"
#include "process.h"
#include "telex/common/synthetic.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

TEST(PlaysOnce, AFolderWithoutLoopPlaysToTheFirstStationNotBeforeIt) {
  TELEX_REQUIRE_BINARIES("telex-local", "telex-remote");
  const auto dir = scratch_dir("plays_once_files");
  // Three frames of the synthetic plane at 0.8 m, as 16-bit millimetre PNGs.
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  const auto scene = synth::Scene::named("plane");
  for (int i = 0; i < 3; ++i)
    ASSERT_TRUE(cv::imwrite((dir / ("desk_" + std::to_string(i) + "_depth_mm.png")).string(),
                            synth::render(scene, k, synth::SensorModel{}, i).depth.depth_mm));
  // 5 fps: a frame every 200 ms, so none is replaced before the remote has sent it.
  RemoteProcess remote(dir,
                       {"--source", "files:" + (dir / "desk_*_depth_mm.png").string() + ",fps=5"});
  // Before the fix the remote played the frames to nobody and exited 0 after 0.3 s.
  std::this_thread::sleep_for(2s);
  ASSERT_TRUE(remote.proc.running()) << remote.proc.stderr_text();
  Process local(local_args(remote.port, dir, {"--hand", "script:press", "--duration", "3"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(60s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  ASSERT_EQ(*rc, 0) << local.stderr_text() << remote.proc.stderr_text();
  const auto j = summary_of(local);
  ASSERT_TRUE(j.is_object()) << local.stdout_text();
  EXPECT_EQ(j["frames"].get<int>(), 3) << j.dump();
  EXPECT_GE(j["surfaces"].get<int>(), 1) << j.dump();
  // The station left after the last frame: the remote stops by itself, with 0.
  const auto remote_rc = remote.proc.wait(20s);
  ASSERT_TRUE(remote_rc.has_value()) << "telex-remote kept running after its frames and station";
  EXPECT_EQ(*remote_rc, 0) << remote.proc.stderr_text();
  const std::string log = remote.proc.stdout_text() + remote.proc.stderr_text();
  EXPECT_NE(log.find("will play 3 frames once, when the first station connects"), std::string::npos)
      << log;
}

}  // namespace
}  // namespace telex::test
