// SPDX-License-Identifier: MIT
// Config files are strict (an unknown key or a wrong shape exits 2 naming the key and the file, in
// TOML and in JSON), a good one is used and logged, and --json-summary writes only JSON to stdout.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "daemons.h"
#include "process.h"
#include "test_support.h"

namespace telex {
namespace {

using namespace std::chrono_literals;

using test::Outcome;
using test::run;

std::string write_file(const std::string& name, const std::string& text) {
  const auto path = test::scratch_file(name);
  std::ofstream(path) << text;
  return path.string();
}

struct ConfigCase {
  std::string file_name, text, named;  // the file, its text, what the message must name
};

TEST(RemoteConfig, UnknownKeysAndWrongShapesExitTwoNamingKeyAndFile) {
  const std::vector<ConfigCase> cases = {
      {"typo.toml", "duraton = 1\n", "'duraton'"},
      {"typo.json", R"({"duraton": 1})", "'duraton'"},
      // JSON chosen by content, whatever the extension.
      {"typo_json.conf", R"({"no-stat": true})", "'no-stat'"},
      {"section.toml", "[pipeline]\nfill = true\n", "[pipeline]"},
      {"flag_not_bool.json", R"({"no-stats": 3})", "'no-stats'"},
      {"list_for_one.json", R"({"duration": [1, 2]})", "'duration'"},
      {"negative.toml", "duration = -1\n", "duration"},
      {"negative.json", R"({"duration": -1})", "duration"},
      {"not_a_number.toml", "duration = \"soon\"\n", "duration"},
      {"broken.json", "{\"duration\": ", "line 1, column 14: not valid JSON"},
  };
  for (const auto& c : cases) {
    const std::string file = write_file(c.file_name, c.text);
    const Outcome o = run("telex-remote", {"--config", file, "--listen", "127.0.0.1:0"});
    EXPECT_EQ(o.exit_code, 2) << c.file_name << ": " << o.err;
    EXPECT_NE(o.err.find(c.named), std::string::npos) << c.file_name << ": " << o.err;
    EXPECT_NE(o.err.find(file), std::string::npos) << c.file_name << " not named: " << o.err;
  }
  // The typo gets a suggestion.
  const Outcome typo = run("telex-remote", {"--config", write_file("t.toml", "duraton = 1\n")});
  EXPECT_NE(typo.err.find("did you mean 'duration'?"), std::string::npos) << typo.err;
}

TEST(RemoteConfig, AGoodFileInEitherFormatIsUsedAndLogged) {
  const std::vector<ConfigCase> cases = {
      {"good.toml", "duration = 0.3\nlisten = \"127.0.0.1:0\"\nno-realtime = true\n", ""},
      {"good.json", R"({"duration": 0.3, "listen": "127.0.0.1:0", "no-realtime": true})", ""},
  };
  for (const auto& c : cases) {
    const std::string file = write_file(c.file_name, c.text);
    const Outcome o = run("telex-remote", {"--config", file, "--source", "synthetic"});
    EXPECT_EQ(o.exit_code, 0) << c.file_name << ": " << o.err;
    EXPECT_NE(o.err.find("from " + file + ": duration=0.3"), std::string::npos) << o.err;
  }
}

TEST(RemoteConfig, HelpShowsTheConfigValuesAsDefaults) {
  const std::string file = write_file("help.toml", "duration = 7.5\n");
  const Outcome o = run("telex-remote", {"--config", file, "--help"});
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_NE(o.out.find("=7.5"), std::string::npos) << o.out;
}

TEST(StationConfig, UnknownKeysAndBadValuesExitTwoNamingKeyAndFileInEitherFormat) {
  const std::vector<ConfigCase> cases = {
      {"typo.toml", "stiffnes = 300\n", "'stiffnes'"},
      {"typo.json", R"({"stiffnes": 300})", "'stiffnes'"},
      {"negative.toml", "stiffness = -5\n", "stiffness"},
      {"negative.json", R"({"stiffness": -5})", "stiffness"},
  };
  for (const auto& c : cases) {
    const std::string file = write_file(c.file_name, c.text);
    const Outcome o = run("telex-local", {"--config", file, "--duration", "0.1"});
    EXPECT_EQ(o.exit_code, 2) << c.file_name << ": " << o.err;
    EXPECT_NE(o.err.find(c.named), std::string::npos) << c.file_name << ": " << o.err;
    EXPECT_NE(o.err.find(file), std::string::npos) << c.file_name << " not named: " << o.err;
  }
}

TEST(StationSpecs, AreCheckedBeforeAnythingStarts) {
  // No remote is listening: a bad spec must be named before the station tries to connect.
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--hand", "leap"}, "--hand: tracker spec 'leap'"},
      {{"--hand", "natnet:1.2.3.4,bogus"}, "unknown option 'bogus'"},
      {{"--hand", "script:no_such_script.csv"}, "no file no_such_script.csv"},
      {{"--view", "png:/proc/nope/x"}, "--view: png:/proc/nope/x: cannot create"},
      {{"--view", "goggles"}, "--view"},
      // Not an address: a flag's mistake (exit 2), not a device's.
      {{"--hand", "natnet:999.1.1.1"}, "'999.1.1.1' is not an IPv4 or IPv6 address"},
      {{"--hand", "natnet:127.0.0.1,local=eth0"}, "local=eth0"},
      {{"--hand", "5dt-serial:/dev/ttyUSB0,wired"}, "5dt-serial:DEV,wireless"},
      // A glove gives a NatNet wrist its fingers; with another hand it would be ignored.
      {{"--glove", "5dt-usb"}, "--glove: 5dt-usb gives finger bends to a NatNet hand"},
      {{"--hand", "natnet:127.0.0.1", "--glove", "5dt-bluetooth"}, "glove spec '5dt-bluetooth'"},
      {{"--other-glove", "5dt-usb"}, "--other-glove"},
  };
  for (const auto& [args, says] : cases) {
    std::vector<std::string> argv = args;
    argv.insert(argv.end(), {"--connect", "127.0.0.1:1", "--duration", "5"});
    const Outcome o = run("telex-local", argv);
    EXPECT_EQ(o.exit_code, 2) << args[1] << ": " << o.err;
    EXPECT_NE(o.err.find(says), std::string::npos) << args[1] << ": " << o.err;
    EXPECT_EQ(o.err.find("connecting"), std::string::npos) << args[1] << ": started anyway";
  }
}

TEST(StationDevices, AMissingGloveIsNamedBeforeAnythingConnects) {
  // No remote is listening and no glove is plugged in: the glove is what the station must name
  // (exit 1, a device's failure), before it tries to connect.
  const std::string absent_tty = test::scratch_file("ttyUSB-absent").string();
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--hand", "natnet:127.0.0.1,unicast", "--glove", "5dt-usb"}, "5DT USB glove"},
      {{"--hand", "5dt-usb"}, "5DT USB glove"},
      {{"--hand", "5dt-serial:" + absent_tty}, "5DT serial glove: cannot open " + absent_tty},
  };
  for (const auto& [args, says] : cases) {
    std::vector<std::string> argv = args;
    argv.insert(argv.end(), {"--connect", "127.0.0.1:1", "--duration", "5", "--no-supervisor"});
    const Outcome o = run("telex-local", argv);
    EXPECT_EQ(o.exit_code, 1) << args.back() << ": " << o.err;
    EXPECT_NE(o.err.find(says), std::string::npos) << args.back() << ": " << o.err;
    EXPECT_EQ(o.err.find("connecting"), std::string::npos) << args.back() << ": " << o.err;
    EXPECT_EQ(o.err.find("is telex-remote running"), std::string::npos)
        << args.back() << ": " << o.err;
  }
}

TEST(JsonSummary, TheStationsStdoutIsOneJsonDocument) {
  test::RemoteProcess remote(test::scratch_dir("remote"), {"--source", "synthetic:plane"});
  const Outcome o = run("telex-local", {"--connect", "127.0.0.1:" + std::to_string(remote.port),
                                        "--haptics", "sim", "--duration", "1", "--json-summary"});
  ASSERT_EQ(o.exit_code, 0) << o.err;
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(o.out)) << o.out;
  EXPECT_GT(j.value("surfaces", 0), 0) << o.out;
}

TEST(JsonSummary, StdoutIsOneJsonDocument) {
  // The proxy forwards nothing here; what matters is that stdout holds only its JSON summary.
  const Outcome o = run("telex-sim-impair", {"--listen", "127.0.0.1:0", "--forward", "127.0.0.1:9",
                                             "--duration", "0.2", "--json-summary"});
  ASSERT_EQ(o.exit_code, 0) << o.err;
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(o.out)) << o.out;
  EXPECT_TRUE(j.is_object()) << o.out;
}

TEST(HelpJson, EveryProgramDescribesItsOptionsAsJson) {
  for (const char* program : {"telex-remote", "telex-local", "telex", "telex-sim-natnet",
                              "telex-sim-dynamixel", "telex-sim-impair", "telex-sim-display"}) {
    const Outcome o = run(program, {"--help-json"});
    ASSERT_EQ(o.exit_code, 0) << program << ": " << o.err;
    nlohmann::json j;
    ASSERT_NO_THROW(j = nlohmann::json::parse(o.out)) << program;
    EXPECT_EQ(j.at("program"), program);
    EXPECT_FALSE(j.at("options").empty()) << program;
  }
}

}  // namespace
}  // namespace telex
