// SPDX-License-Identifier: MIT
// The operator's own inputs are checked, end to end with the daemons as processes: telex-remote on
// the synthetic plane, telex-sim-natnet multicasting a recording whose hand and head poses are
// at times NaN, of non-unit quaternion or jump 3 m in one frame, and telex-local tracking it.
// A spoofer on 127.0.0.2 sends server info and frames to the station's data port. The station
// keeps running on the real server's good frames, every force it logs is finite, and its summary
// counts each kind of drop.
#include <gtest/gtest.h>
#include <signal.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include "daemons.h"
#include "process.h"
#include "telex/natnet/natnet.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;
namespace natnet = local::natnet;

// Head (1), right hand (2) and shoulder (3) as telex-sim-natnet's press motion holds them, with a
// fault in one body for 0.1 s at a time; the recording loops every 2 s.
constexpr const char* kGlitchyRecording =
    "time_s,body_id,x,y,z,qx,qy,qz,qw\n"
    "0.0,1,0,1.6,0,0,0,0,1\n"
    "0.0,2,0.03,1.5,-0.4,0,0.707107,0,0.707107\n"
    "0.0,3,0.2,1.45,0.05,0,0,0,1\n"
    "0.5,2,nan,1.5,-0.4,0,0.707107,0,0.707107\n"  // non-finite position
    "0.6,2,0.03,1.5,-0.4,0,0.707107,0,0.707107\n"
    "0.8,2,0.03,1.5,-0.4,0,0.848528,0,0.848528\n"  // |q| = 1.2
    "0.9,2,0.03,1.5,-0.4,0,0.707107,0,0.707107\n"
    "1.1,2,3.03,1.5,-0.4,0,0.707107,0,0.707107\n"  // 3 m in one frame
    "1.2,2,0.03,1.5,-0.4,0,0.707107,0,0.707107\n"
    "1.4,1,0,1.6,0,0,nan,0,1\n"  // the head's quaternion
    "1.5,1,0,1.6,0,0,0,0,1\n"
    "2.0,1,0,1.6,0,0,0,0,1\n";

std::vector<std::vector<std::uint8_t>> spoofed_datagrams() {
  std::vector<std::vector<std::uint8_t>> out;
  natnet::ServerInfo info;
  info.app_name = "spoofer";
  info.natnet_version = {2, 0};  // the real server streams 3.1
  for (int i = 0; i < 5; ++i) out.push_back(natnet::make_server_info(info));
  for (int i = 0; i < 50; ++i) {
    natnet::Frame f;
    natnet::RigidBody hand;
    hand.id = 2;
    hand.p_m = {0.03f, 1.5f, -0.45f};
    hand.qy = hand.qw = 0.707107f;
    f.rigid_bodies = {hand};
    f.frame_number = 0x5900'0000u + static_cast<std::uint32_t>(i);
    out.push_back(natnet::encode_frame(f, {3, 1}));
  }
  return out;
}

TEST(NatNetInputs, SpoofedSenderAndBadPosesAreDroppedAndCountedWhileTheStationRuns) {
  TELEX_REQUIRE_BINARIES("telex-local", "telex-remote", "telex-sim-natnet");
  const auto dir = scratch_dir("natnet_inputs_spoof_and_bad_poses");
  std::ofstream(dir / "glitchy.csv") << kGlitchyRecording;
  RemoteProcess remote(dir, {"--source", "synthetic:plane"});
  const std::uint16_t cmd_port = free_port(), data_port = free_port();
  Process sim(
      {built_binary("telex-sim-natnet").string(), "--command-port", std::to_string(cmd_port),
       "--multicast", "--data-port", std::to_string(data_port), "--interface", "127.0.0.1",
       "--rate", "120", "--duration", "60", "--motion", (dir / "glitchy.csv").string()},
      dir / "sim.out", dir / "sim.err");
  Process local(local_args(remote.port, dir,
                           {"--hand",
                            "natnet:127.0.0.1,multicast,local=127.0.0.1,cmd=" +
                                std::to_string(cmd_port) + ",data=" + std::to_string(data_port),
                            "--log-tracking", (dir / "tracking.csv").string(), "--duration", "8"}),
                dir / "local.out", dir / "local.err");
  // The tracker exists once the haptic loop runs: then the spoofer sends to its data port.
  ASSERT_TRUE(eventually(30s, [&] {
    return local.stderr_text().find("haptic loop at") != std::string::npos || !local.running();
  }));
  const std::size_t sent = udp_send_from("127.0.0.2", data_port, spoofed_datagrams());
  ASSERT_EQ(sent, 55u);
  const auto rc = local.wait(60s);
  sim.signal(SIGINT);
  ASSERT_EQ(rc.value_or(-1), 0) << local.stderr_text();

  const nlohmann::json j = summary_of(local);
  ASSERT_TRUE(j.contains("tracker")) << local.stdout_text();
  const nlohmann::json& t = j["tracker"];
  std::printf("NatNetInputs: tracker %s; head commands %llu, invalid %llu\n", t.dump().c_str(),
              j.value("head_commands", 0ULL), j.value("head_commands_invalid", 0ULL));
  // The spoofer: every datagram counted and none believed (a 2.0 layout would break the parse).
  EXPECT_EQ(t["foreign_datagrams"].get<std::uint64_t>(), sent);
  EXPECT_EQ(t["parse_errors"].get<std::uint64_t>(), 0u);
  // Each kind of bad pose was seen and dropped (three 2 s cycles in the run; 12 frames each).
  EXPECT_GE(t["rejected_nonfinite"].get<std::uint64_t>(), 12u);
  EXPECT_GE(t["rejected_quaternion"].get<std::uint64_t>(), 24u);  // the hand's and the head's
  EXPECT_GE(t["rejected_too_fast"].get<std::uint64_t>(), 12u);
  EXPECT_GE(t["frames_rejected"].get<std::uint64_t>(), 12u);
  EXPECT_EQ(t["thread_faults"].get<std::uint64_t>(), 0u);
  // The real server still drives the station.
  EXPECT_GT(t["frames_in"].get<std::uint64_t>(), 300u);
  EXPECT_EQ(j["head_commands_invalid"].get<std::uint64_t>(), 0u);
  EXPECT_NE(local.stderr_text().find("tracking dropped"), std::string::npos)
      << "the status line does not report the drops";
  // Every force and fingertip the station logged is finite, and the fingertips were tracked.
  const CsvFile forces = read_csv_file(dir / "forces.csv");
  ASSERT_GT(forces.rows.size(), 1000u);
  std::size_t non_finite = 0;
  for (const auto& row : forces.rows) {
    ASSERT_GE(row.size(), 13u);
    for (const std::size_t c : {2u, 3u, 5u, 6u, 7u, 8u, 10u, 11u, 12u})
      non_finite += std::isfinite(std::stod(row[c])) ? 0 : 1;
  }
  EXPECT_EQ(non_finite, 0u);
  // Every body the tracker used (--log-tracking logs the frames it took) is the recording's good
  // pose: finite, of unit quaternion, the hand never where the 3 m jump put it.
  const CsvFile tracking = read_csv_file(dir / "tracking.csv");
  std::size_t hand_rows = 0, bad_rows = 0;
  for (const auto& row : tracking.rows) {
    ASSERT_EQ(row.size(), 10u);
    if (row[9] != "1") continue;
    double q2 = 0.0;
    for (const std::size_t c : {5u, 6u, 7u, 8u}) q2 += std::stod(row[c]) * std::stod(row[c]);
    const bool finite = std::isfinite(std::stod(row[2])) && std::isfinite(std::stod(row[3])) &&
                        std::isfinite(std::stod(row[4]));
    const bool hand_jumped = row[1] == "2" && std::abs(std::stod(row[2]) - 0.03) > 0.01;
    bad_rows += (!finite || std::abs(q2 - 1.0) > 1e-5 || hand_jumped) ? 1 : 0;
    hand_rows += row[1] == "2" ? 1 : 0;
  }
  std::printf("NatNetInputs: %zu tracked hand rows logged, %zu with a bad pose\n", hand_rows,
              bad_rows);
  EXPECT_GT(hand_rows, 300u);
  EXPECT_EQ(bad_rows, 0u);
}

// The simulator's press with --reach reaches the surface at that depth: the station feels the
// synthetic plane (0.8 m) through it, and without --reach (the fixed 0.25-0.55 m hand path) it
// does not, which is the mistake --reach exists to fix.
TEST(NatNetInputs, ThePressWithReachTouchesTheSurfaceAtThatDepth) {
  TELEX_REQUIRE_BINARIES("telex-local", "telex-remote", "telex-sim-natnet");
  const auto peak_pressure_N = [](const std::string& name, std::vector<std::string> reach) {
    const auto dir = scratch_dir(name);
    RemoteProcess remote(dir, {"--source", "synthetic:plane"});
    const std::uint16_t cmd_port = free_port();
    std::vector<std::string> sim_argv{built_binary("telex-sim-natnet").string(),
                                      "--command-port",
                                      std::to_string(cmd_port),
                                      "--rate",
                                      "120",
                                      "--duration",
                                      "60"};
    sim_argv.insert(sim_argv.end(), reach.begin(), reach.end());
    Process sim(sim_argv, dir / "sim.out", dir / "sim.err");
    // Two press periods (4 s each) after the first surface.
    Process local(local_args(remote.port, dir,
                             {"--hand", "natnet:127.0.0.1,unicast,cmd=" + std::to_string(cmd_port),
                              "--duration", "9"}),
                  dir / "local.out", dir / "local.err");
    const auto rc = local.wait(60s);
    sim.signal(SIGINT);
    EXPECT_EQ(rc.value_or(-1), 0) << local.stderr_text();
    const nlohmann::json j = summary_of(local);
    return j.value("peak_pressure_N", -1.0);
  };
  const double with_reach = peak_pressure_N("reach", {"--reach", "0.8"});
  const double without = peak_pressure_N("no_reach", {});
  std::printf("NatNetInputs: peak pressure %.2f N with --reach 0.8, %.2f N without\n", with_reach,
              without);
  EXPECT_GT(with_reach, 0.5) << "the press never reached the plane";
  EXPECT_EQ(without, 0.0) << "the fixed path reaches 0.8 m after all: the control is wrong";
}

// A station tracking a NatNet server that is not there (nothing listens on its command port)
// says so: a warning naming the server, its port and what to check, the status line while it
// lasts, and the line that ends the run, not only `tracker.frames_in` 0 in the JSON summary.
TEST(NatNetInputs, AServerThatSendsNothingIsNamedWhileTheStationRunsAndAtTheEnd) {
  TELEX_REQUIRE_BINARIES("telex-local", "telex-remote");
  const auto dir = scratch_dir("natnet_inputs_silent_server");
  RemoteProcess remote(dir, {"--source", "synthetic:plane"});
  const std::string cmd_port = std::to_string(free_port());
  Process local(
      local_args(remote.port, dir,
                 {"--hand", "natnet:127.0.0.1,unicast,cmd=" + cmd_port, "--duration", "6"}),
      dir / "local.out", dir / "local.err");
  // Said 2 s after the tracker starts; the bound leaves a loaded machine's start-up its time.
  EXPECT_TRUE(eventually(5s, [&] {
    return local.stderr_text().find("[warning] no NatNet frames") != std::string::npos;
  })) << local.stderr_text();
  const auto rc = local.wait(60s);
  ASSERT_EQ(rc.value_or(-1), 0) << local.stderr_text();
  const std::string err = local.stderr_text();
  const std::size_t warning = err.find("[warning] no NatNet frames");
  ASSERT_NE(warning, std::string::npos) << err;
  const std::string warning_line = err.substr(warning, err.find('\n', warning) - warning);
  for (const std::string& says : {std::string("127.0.0.1"), "command port " + cmd_port,
                                  std::string("Motive"), std::string("firewall")})
    EXPECT_NE(warning_line.find(says), std::string::npos) << says << ": " << warning_line;
  // The status line says it too, and the line that ends the run.
  EXPECT_NE(err.find("streaming | no NatNet frames"), std::string::npos) << err;
  const std::size_t done = err.find("[info] done:");
  ASSERT_NE(done, std::string::npos) << err;
  EXPECT_NE(err.find("no NatNet frames", done), std::string::npos) << err.substr(done);
  const nlohmann::json j = summary_of(local);
  EXPECT_EQ(j["tracker"]["frames_in"].get<std::uint64_t>(), 0u) << j.dump();
  EXPECT_NE(j["tracker"].value("silent", std::string()).find("no NatNet frames"), std::string::npos)
      << j.dump();
}

}  // namespace
}  // namespace telex::test
