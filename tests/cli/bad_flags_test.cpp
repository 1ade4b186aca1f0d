// SPDX-License-Identifier: MIT
// Every program and subcommand keeps the command-line contract: an unknown flag, a value of the
// wrong type and a value out of range each exit 2 with a message that names the flag.
#include <gtest/gtest.h>

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "process.h"
#include "test_support.h"

namespace telex {
namespace {

using namespace std::chrono_literals;

struct BadFlag {
  std::string flag;   // named in the message
  std::string value;  // "" for the unknown flag itself
};

// One row per program or subcommand; adding a program is one row.
struct ProgramCase {
  std::string binary;                   // the built program (test::built_binary)
  std::vector<std::string> words;       // subcommand words before the flags
  std::string unknown, suggestion;      // an unknown flag and the name it should suggest ("" none)
  BadFlag wrong_type;                   // a value that is not of the option's type
  std::optional<BadFlag> out_of_range;  // a value outside the option's range
};

const std::vector<ProgramCase>& cases() {
  static const std::vector<ProgramCase> all = {
      {"telex-remote",
       {},
       "--duraton",
       "--duration",
       {"--zip-level", "abc"},
       {{"--zip-level", "10"}}},
      {"telex-remote",
       {},
       "--fill-windw",
       "--fill-window",
       {"--fill-window", "x"},
       {{"--fill-window", "4"}}},
      {"telex-local",
       {},
       "--stifness",
       "--stiffness",
       {"--stiffness", "abc"},
       {{"--stiffness", "-5"}}},
      {"telex-sim-natnet", {}, "--rat", "--rate", {"--rate", "abc"}, {{"--rate", "0"}}},
      {"telex-sim-dynamixel",
       {},
       "--bogus",
       "",
       {"--operating-mode", "x"},
       {{"--operating-mode", "99"}}},
      {"telex-sim-impair", {}, "--bogus", "", {"--loss", "x"}, {{"--loss", "2"}}},
      {"telex-sim-display", {}, "--apend", "--append", {"--duration", "x"}, {{"--duration", "-1"}}},
      {"telex",
       {"bench"},
       "--quik",
       "--quick",
       {"--config", "nope"},
       {{"--session", "/nonexistent/session.bag"}}},
      {"telex", {"body"}, "--sed", "--seed", {"--seed", "abc"}, std::nullopt},
      {"telex",
       {"calibrate", "stereo"},
       "--min-view",
       "--min-views",
       {"--min-views", "x"},
       {{"--min-views", "2"}}},
      {"telex",
       {"calibrate", "depth-eye"},
       "--square",
       "--square-mm",
       {"--square-mm", "x"},
       {{"--square-mm", "-3"}}},
      {"telex", {"calibrate", "render"}, "--view", "--views", {"--views", "x"}, {{"--views", "0"}}},
      {"telex",
       {"calibrate", "body"},
       "--secnds",
       "--seconds",
       {"--seconds", "x"},
       {{"--seconds", "0"}}},
      {"telex",
       {"calibrate", "glove"},
       "--sensor",
       "--sensors",
       {"--sensors", "x"},
       {{"--sensors", "7"}}},
      {"telex", {"capture"}, "--frame", "--frames", {"--frames", "x"}, {{"--frames", "0"}}},
      {"telex", {"codec"}, "--rnus", "--runs", {"--runs", "x"}, {{"--runs", "0"}}},
      {"telex", {"devices"}, "--usb", "--usb-id", {"--usb-id", "nope"}, std::nullopt},
      {"telex",
       {"process"},
       "--fill-windw",
       "--fill-window",
       {"--fill-window", "x"},
       {{"--fill-window", "4"}}},
      {"telex",
       {"replay"},
       "--stifness",
       "--stiffness",
       {"--stiffness", "x"},
       {{"--stiffness", "0"}}},
      {"telex",
       {"stability"},
       "--random-tick",
       "--random-ticks",
       {"--random-ticks", "x"},
       {{"--random-ticks", "0"}}},
  };
  return all;
}

struct Outcome {
  int exit_code = -1;
  std::string out, err;
};

Outcome run(const ProgramCase& c, const std::vector<std::string>& flags) {
  std::vector<std::string> argv = {test::built_binary(c.binary).string()};
  argv.insert(argv.end(), c.words.begin(), c.words.end());
  argv.insert(argv.end(), flags.begin(), flags.end());
  test::Process p(argv, test::scratch_file("out.txt"), test::scratch_file("err.txt"));
  const auto rc = p.wait(60s);
  return {rc.value_or(-1), p.stdout_text(), p.stderr_text()};
}

std::string label(const ProgramCase& c) {
  std::string s = c.binary;
  for (const auto& w : c.words) s += " " + w;
  return s;
}

void expect_usage_error(const ProgramCase& c, const std::vector<std::string>& flags,
                        const std::string& named) {
  const Outcome o = run(c, flags);
  EXPECT_EQ(o.exit_code, 2) << label(c) << " " << flags.front() << ": " << o.err;
  EXPECT_NE(o.err.find(named), std::string::npos) << label(c) << ": " << o.err;
  EXPECT_EQ(o.err.rfind(label(c) + ": ", 0), 0u)
      << "message not prefixed by the program: " << o.err;
  EXPECT_TRUE(o.out.empty()) << label(c) << " wrote to stdout: " << o.out;
}

TEST(BadFlags, UnknownFlagExitsTwoWithASuggestion) {
  for (const auto& c : cases()) {
    expect_usage_error(c, {c.unknown}, c.unknown);
    if (!c.suggestion.empty()) {
      const Outcome o = run(c, {c.unknown});
      EXPECT_NE(o.err.find("did you mean " + c.suggestion + "?"), std::string::npos)
          << label(c) << ": " << o.err;
    }
  }
}

TEST(BadFlags, WrongTypeExitsTwoNamingTheFlag) {
  for (const auto& c : cases())
    expect_usage_error(c, {c.wrong_type.flag, c.wrong_type.value}, c.wrong_type.flag);
}

TEST(BadFlags, OutOfRangeExitsTwoNamingTheFlag) {
  for (const auto& c : cases())
    if (c.out_of_range)
      expect_usage_error(c, {c.out_of_range->flag, c.out_of_range->value}, c.out_of_range->flag);
}

TEST(BadFlags, UnknownSubcommandIsSuggested) {
  const ProgramCase telex{"telex", {}, "procss", "process", {"", ""}, std::nullopt};
  const Outcome o = run(telex, {"procss"});
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_NE(o.err.find("telex: procss: unknown subcommand (did you mean process?)"),
            std::string::npos)
      << o.err;
}

TEST(BadFlags, UnknownFlagWinsOverAMissingRequiredOne) {
  // telex-sim-impair requires --listen; a mistyped flag is the error to report.
  const ProgramCase impair{"telex-sim-impair", {}, "", "", {"", ""}, std::nullopt};
  const Outcome o = run(impair, {"--bogus"});
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_NE(o.err.find("--bogus: unknown flag"), std::string::npos) << o.err;
  EXPECT_EQ(o.err.find("--listen"), std::string::npos) << o.err;
}

}  // namespace
}  // namespace telex
