// SPDX-License-Identifier: MIT
// A fault in any station thread stops the station cleanly with zero force on every finger.
// The remote runs in-process on the synthetic plane; the station presses it with the scripted hand
// (or a NatNet hand held 10 mm inside the wall) into the recording display, and a test hook throws
// from the main loop, the surface thread, the haptic thread, the network client's thread or the
// NatNet receive thread once the finger pushes. Before the jthread members and the zero-force
// guard, the main-loop case destroyed a joinable std::thread and the process terminated mid-press;
// before the network and NatNet threads caught what escaped them, those cases called
// std::terminate with the display still pressing.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <numbers>
#include <opencv2/core/utility.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "process.h"
#include "telex/base/periodic.h"
#include "telex/local/inputs/hand_model.h"
#include "telex/local/station/station.h"
#include "telex/remote/daemon.h"
#include "telex/sim/natnet_server.h"

namespace telex::local {
namespace {

// The sim display's CSV: time_ns, then pressure, shear and contact for each of five fingers.
struct DisplayRow {
  double max_pressure_N = 0.0;
  bool any_force_or_contact = false;
};

std::vector<DisplayRow> read_display_csv(const std::filesystem::path& path) {
  const test::CsvFile table = test::read_csv_file(path);
  std::vector<DisplayRow> rows;
  for (const auto& f : table.rows) {
    if (f.size() != 16) ADD_FAILURE() << "malformed display row: " << testing::PrintToString(f);
    if (f.size() != 16) continue;
    DisplayRow r;
    for (int finger = 0; finger < 5; ++finger) {
      const double p = std::stod(f[1 + 3 * finger]);
      const double s = std::stod(f[2 + 3 * finger]);
      r.max_pressure_N = std::max(r.max_pressure_N, p);
      r.any_force_or_contact =
          r.any_force_or_contact || p != 0.0 || s != 0.0 || f[3 + 3 * finger] != "0";
    }
    rows.push_back(r);
  }
  return rows;
}

class StationFault : public ::testing::TestWithParam<StationLoop> {};

std::string loop_name(StationLoop loop) {
  switch (loop) {
    case StationLoop::Main:
      return "Main";
    case StationLoop::Surface:
      return "Surface";
    case StationLoop::Haptic:
      return "Haptic";
    case StationLoop::Network:
      return "Network";
    case StationLoop::Tracking:
      return "Tracking";
  }
  return "?";
}

// The thread a loop's fault names (StationThreadError::thread()).
std::string thread_name(StationLoop loop) {
  switch (loop) {
    case StationLoop::Main:
      return "main";
    case StationLoop::Surface:
      return "surface (telex-surface)";
    case StationLoop::Haptic:
      return "haptic (telex-haptic)";
    case StationLoop::Network:
      return "network (telex-net)";
    case StationLoop::Tracking:
      return "tracking (telex-natnet)";
  }
  return "?";
}

// A NatNet server holding the index fingertip 10 mm inside the plane's wall (0.8 m ahead of the
// camera) from the start, the head still: the Tracking case's hand.
struct PressingMocap {
  explicit PressingMocap(TrackerConfig& tc) {
    tc.head_body_id = 1;
    tc.right_hand_body_id = 2;
    tc.right_shoulder_body_id = -1;
    tc.hand.p_HeadCamera = glm::dvec3(0.0);
    const glm::dvec3 tip_world =
        glm::dvec3(0.0, 1.6, 0.0) + glm::transpose(tc.hand.R_CameraHead) * glm::dvec3(0, 0, 0.81);
    const double s = std::sin(std::numbers::pi / 4), c = std::cos(std::numbers::pi / 4);
    Pose hand{{0, 0, 0}, glm::dquat(c, 0, s, 0)};  // fingers along world -z
    hand.p_m = tip_world - hand_forward(tc.hand, hand, tc.default_bend).joints[1][3];
    sim::NatNetServerConfig scfg;
    scfg.command_port = 0;
    scfg.rate_hz = 240.0;
    server = std::make_unique<sim::NatNetServer>(scfg, [hand](double, natnet::Frame& f) {
      natnet::RigidBody head;
      head.id = 1;
      head.p_m = {0.0f, 1.6f, 0.0f};
      natnet::RigidBody h;
      h.id = 2;
      h.p_m = {static_cast<float>(hand.p_m.x), static_cast<float>(hand.p_m.y),
               static_cast<float>(hand.p_m.z)};
      h.qy = static_cast<float>(hand.q.y);
      h.qw = static_cast<float>(hand.q.w);
      f.rigid_bodies = {head, h};
    });
    thread = std::thread([this] { server->run_for(120.0); });
  }
  ~PressingMocap() {
    server->stop();
    thread.join();
  }
  std::string spec() const {
    return "natnet:127.0.0.1,unicast,cmd=" + std::to_string(server->command_port());
  }
  std::unique_ptr<sim::NatNetServer> server;
  std::thread thread;
};

TEST_P(StationFault, ExceptionStopsTheStationWithZeroForceAsTheDisplaysLastCommand) {
  const StationLoop faulty = GetParam();
  // The renderer serial (identical output; OpenCV's thread pool is uninstrumented, so TSan builds
  // could not see its synchronisation) and at 320x240, so sanitizer builds keep 30 Hz.
  const int cv_threads = cv::getNumThreads();
  cv::setNumThreads(1);
  remote::DaemonConfig rc;
  rc.depth_source = "synthetic:plane";
  rc.source_options.width = 320;
  rc.source_options.height = 240;
  rc.server.port = 0;
  rc.stats_line = false;
  remote::RemoteDaemon remote(rc);
  remote.start();

  const auto dir = test::scratch_dir("station_fault_" + loop_name(faulty));
  const auto csv = dir / "display.csv";

  StationConfig cfg;
  cfg.client.host = "127.0.0.1";
  cfg.client.port = remote.port();
  cfg.hand_spec = "script:press";
  std::unique_ptr<PressingMocap> mocap;
  if (faulty == StationLoop::Tracking) {
    mocap = std::make_unique<PressingMocap>(cfg.tracker);
    cfg.hand_spec = mocap->spec();
  }
  cfg.haptics_spec = "sim:" + csv.string();
  cfg.haptic.stiffness_N_per_m = 500.0;
  // This test is about the exit path, not the stale-surface fade (RemoteRestart tests that): a
  // sanitizer build's slow frames must not fade the press out.
  cfg.haptic.stale_limit_s = 1.0;
  cfg.status_line = false;
  cfg.duration_s = 60.0;  // the fault comes long before
  cfg.first_surface_timeout_s = 60.0;
  // 3.7 s after the first haptic tick the scripted finger holds 10 mm inside the plane (it
  // arrives at 0.1 m/s from 0.3 m away, about 3.1 s into the script, and holds 1 s). Script time
  // is wall time, so the trigger is too (a sanitizer build misses ticks, and a tick count would
  // land after the release).
  std::atomic<std::int64_t> first_tick_ns{0};
  std::atomic<bool> thrown{false};
  cfg.fault_hook = [&](StationLoop loop) {
    const std::int64_t now = monotonic_ns();
    if (loop == StationLoop::Haptic && first_tick_ns.load() == 0) first_tick_ns.store(now);
    const std::int64_t t0 = first_tick_ns.load();
    if (loop == faulty && t0 != 0 && now - t0 > 3'700'000'000 && !thrown.exchange(true))
      throw std::runtime_error("injected fault in the " + loop_name(loop) + " loop");
  };
  {
    Station station(cfg);
    try {
      station.run();
      ADD_FAILURE() << "run() returned although its " << loop_name(faulty) << " loop threw";
    } catch (const StationThreadError& e) {
      // The exit message names the thread and what it threw.
      std::printf("StationFault %s: %s\n", loop_name(faulty).c_str(), e.what());
      EXPECT_EQ(e.thread(), thread_name(faulty));
      EXPECT_EQ(std::string(e.what()), "the " + thread_name(faulty) +
                                           " thread failed: injected fault in the " +
                                           loop_name(faulty) + " loop");
    }
  }  // the station and its display are gone: the CSV is complete
  mocap.reset();
  remote.stop();
  cv::setNumThreads(cv_threads);
  EXPECT_TRUE(thrown.load());

  const auto rows = read_display_csv(csv);
  ASSERT_GT(rows.size(), 100u);
  double peak_N = 0.0;
  for (const auto& r : rows) peak_N = std::max(peak_N, r.max_pressure_N);
  EXPECT_GT(peak_N, 0.5) << "the finger never pressed: the test would not see a missing release";
  EXPECT_FALSE(rows.back().any_force_or_contact)
      << "the display's last command is not zero force (" << rows.back().max_pressure_N << " N)";
  std::printf("StationFault %s: %zu display commands, peak %.2f N, last %.2f N\n",
              loop_name(faulty).c_str(), rows.size(), peak_N, rows.back().max_pressure_N);
  std::filesystem::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Loops, StationFault,
                         ::testing::Values(StationLoop::Main, StationLoop::Surface,
                                           StationLoop::Haptic, StationLoop::Network,
                                           StationLoop::Tracking),
                         [](const auto& info) { return loop_name(info.param); });

}  // namespace
}  // namespace telex::local
