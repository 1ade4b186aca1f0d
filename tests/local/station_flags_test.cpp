// SPDX-License-Identifier: MIT
// telex-local's flags (local_node/flags.cpp): parsed into the station's configuration, and bad
// values named.
#include <gtest/gtest.h>

#include <CLI/CLI.hpp>
#include <array>
#include <string>
#include <vector>

#include "flags.h"
#include "telex/cli/cli.h"
#include "telex/local/view/view_window.h"

namespace telex::local {
namespace {

// Parses `args` as telex-local would; throws what the parser or the resolution throws.
StationFlags parse(std::vector<std::string> args) {
  StationFlags flags;
  CLI::App app{"test"};
  add_station_options(app, flags);
  args.insert(args.begin(), "telex-local");
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  app.parse(static_cast<int>(argv.size()), argv.data());
  resolve_station_flags(flags);
  apply_station_switches(flags);
  return flags;
}

TEST(StationFlags, DefaultsConnectToTheLocalRemoteOverUdp) {
  const StationFlags f = parse({});
  EXPECT_EQ(f.cfg.client.host, "127.0.0.1");
  EXPECT_EQ(f.cfg.client.port, 7300);
  EXPECT_TRUE(f.cfg.client.use_udp);
  EXPECT_TRUE(f.cfg.surface.roi);
  EXPECT_TRUE(f.cfg.head_teleop);
  EXPECT_TRUE(f.cfg.view_warp);
  EXPECT_FALSE(parse({"--warp", "off"}).cfg.view_warp);
  EXPECT_TRUE(parse({"--warp", "on"}).cfg.view_warp);
}

TEST(StationFlags, ConnectTakesBracketedIpv6AndSwitchesReachTheConfig) {
  const StationFlags f = parse({"--connect", "[::1]:7000", "--transport", "tcp", "--full-frame",
                                "--no-head", "--elbow-bodies", "7,-1", "--quiet"});
  EXPECT_EQ(f.cfg.client.host, "::1");
  EXPECT_EQ(f.cfg.client.port, 7000);
  EXPECT_FALSE(f.cfg.client.use_udp);
  EXPECT_FALSE(f.cfg.surface.roi);
  EXPECT_FALSE(f.cfg.head_teleop);
  EXPECT_FALSE(f.cfg.head_captured_pose);
  EXPECT_EQ(f.cfg.tracker.left_elbow_body_id, 7);
  EXPECT_EQ(f.cfg.tracker.right_elbow_body_id, -1);
  EXPECT_FALSE(f.cfg.status_line);
}

TEST(StationFlags, EyeSizeReachesTheConfigAndDefaultsToTheVideos) {
  EXPECT_TRUE(parse({}).cfg.eye_size.empty());
  EXPECT_EQ(parse({"--eye-size", "1280x720"}).cfg.eye_size, cv::Size(1280, 720));
  EXPECT_EQ(parse({}).cfg.view_layout, "sbs");
  EXPECT_EQ(parse({"--view-layout", "fig7"}).cfg.view_layout, "fig7");
}

TEST(StationFlags, OpenXrViewTakesTheHeadsetAsTheHead) {
  EXPECT_EQ(parse({}).cfg.head_source, "natnet");
  const StationFlags f = parse({"--view", "openxr", "--head-source", "hmd"});
  EXPECT_EQ(f.cfg.view_spec, "openxr");
  EXPECT_EQ(f.cfg.head_source, "hmd");
  EXPECT_EQ(ViewSpec::parse(f.cfg.view_spec).kind, ViewSpec::Kind::OpenXr);
  EXPECT_TRUE(f.cfg.record_hmd_poses_csv.empty());
  const StationFlags r =
      parse({"--view", "openxr", "--hand", "natnet:127.0.0.1", "--record-hmd-poses", "poses.csv"});
  EXPECT_EQ(r.cfg.record_hmd_poses_csv, "poses.csv");
}

TEST(StationFlags, BadValuesNameTheFlag) {
  const struct {
    std::vector<std::string> args;
    const char* flag;
  } cases[] = {
      {{"--connect", "robot"}, "--connect"},
      {{"--connect", "robot:70000"}, "--connect"},
      {{"--connect", "::1:7000"}, "--connect"},
      {{"--elbow-bodies", "3"}, "--elbow-bodies"},
      {{"--rate", "5"}, "--rate"},
      {{"--transport", "sctp"}, "--transport"},
      {{"--warp", "yes"}, "--warp"},
      {{"--eye-size", "1280"}, "--eye-size"},
      {{"--eye-size", "1280x720x3"}, "--eye-size"},
      {{"--eye-size", "8x8"}, "--eye-size"},
      {{"--view-layout", "quad"}, "--view-layout"},
      {{"--view", "openxr:steamvr"}, "--view"},
      {{"--head-source", "eyes"}, "--head-source"},
      // The headset's pose exists only with the headset's view.
      {{"--head-source", "hmd", "--view", "png:/tmp"}, "--head-source"},
      {{"--record-hmd-poses", "p.csv", "--hand", "natnet:127.0.0.1"}, "--record-hmd-poses"},
      {{"--record-hmd-poses", "p.csv", "--view", "openxr"}, "--record-hmd-poses"},
  };
  for (const auto& c : cases) {
    try {
      parse(c.args);
      ADD_FAILURE() << c.args[1] << " was accepted";
    } catch (const CLI::ParseError& e) {
      EXPECT_NE(std::string(e.what()).find(c.flag), std::string::npos) << e.what();
    }
  }
}

TEST(StationFlags, HapticCpuMustBeOneThisProcessMayRunOn) {
  EXPECT_EQ(parse({"--haptic-cpu", "0"}).cfg.haptic_cpu, 0);
  EXPECT_EQ(parse({}).cfg.haptic_cpu, -1);
  try {
    parse({"--haptic-cpu", "4096"});
    FAIL() << "--haptic-cpu 4096 accepted";
  } catch (const CLI::ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("--haptic-cpu"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("may run on"), std::string::npos) << e.what();
  }
}

// A config file's text, read as telex-local reads the file (telex/cli/cli.h, parse_config_text).
TEST(StationFlags, ConfigTextIsReadAsTheFileIs) {
  const auto read = [](const std::string& file, const std::string& text) {
    StationFlags flags;
    CLI::App app{"test"};
    add_station_options(app, flags);
    cli::parse_config_text(app, file, text);
    return flags;
  };
  const StationFlags toml = read("/etc/telex/station.toml",
                                 "connect = \"10.0.0.2:7000\"\nmax-force = 2.5\nquiet = true\n"
                                 "log-forces = \"logs/forces.csv\"\n");
  EXPECT_EQ(toml.connect, "10.0.0.2:7000");
  EXPECT_DOUBLE_EQ(toml.cfg.haptic.max_force_N, 2.5);
  EXPECT_TRUE(toml.quiet);
  EXPECT_EQ(toml.cfg.log_forces_csv, "/etc/telex/logs/forces.csv");
  EXPECT_EQ(read("/x/s.json", R"({"transport": "tcp"})").transport, "tcp");
  for (const auto& [file, text, key] :
       std::vector<std::array<std::string, 3>>{{"/x/typo.toml", "duraton = 1\n", "'duraton'"},
                                               {"/x/flag.json", R"({"quiet": 3})", "'quiet'"}}) {
    try {
      read(file, text);
      ADD_FAILURE() << text << " was accepted";
    } catch (const CLI::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(read("/x/n.toml", "max-force = \"strong\"\n"), CLI::ParseError);
  // The rig the daemons look for before their flags, as the file gives it.
  EXPECT_EQ(cli::value_in_config_text("/x/a.toml", "rig = \"r.json\"\n", "rig"), "r.json");
  EXPECT_EQ(cli::value_in_config_text("/x/a.json", "{\"rig\": ", "rig"), "");
}

}  // namespace
}  // namespace telex::local
