// SPDX-License-Identifier: MIT
// The remote's stats line (issue 50): short by default, with only the problem counters that are
// not zero; the full form keeps every counter.
#include <gtest/gtest.h>

#include "telex/remote/daemon.h"

namespace telex::remote {
namespace {

DaemonStats running() {
  DaemonStats s;
  s.frames_in = 300;
  s.frames_sent = 290;
  s.bytes_sent = 8'000'000;
  s.video_bytes_sent = 3'000'000;
  s.video_frames = 290;
  s.client = ClientState::Connected;
  s.eyes = EyeState::Live;
  return s;
}

TEST(StatsLine, ShortByDefaultWithOnlyTheProblemsThatHappened) {
  DaemonStats before;
  const DaemonStats now = running();
  const std::string line = format_stats_short(now, before, 10.0);
  EXPECT_EQ(line,
            "in 30.0 out 29.0 fps | depth 4.00 Mbit/s | video 290 pairs 2.40 Mbit/s | station "
            "connected | registration none | realtime 0/0 | eyes live");
  DaemonStats bad = now;
  bad.malformed_in = 3;
  bad.auth_failed = 1;
  bad.source_ended = true;
  const std::string said = format_stats_short(bad, before, 10.0);
  EXPECT_NE(said.find(" | depth source ended | malformed 3, auth-failed 1 | registration"),
            std::string::npos)
      << said;
  const std::string full = format_stats_line(now, before, 10.0);
  EXPECT_LT(line.size() * 5, full.size()) << line << "\n" << full;
  EXPECT_NE(full.find("auth-failed 0"), std::string::npos);
}

TEST(StatsLine, ANoVideoRemoteSaysEyesOff) {
  DaemonStats s = running();
  s.video_frames = 0;
  s.video_bytes_sent = 0;
  s.eyes = EyeState::Off;
  const std::string line = format_stats_short(s, DaemonStats{}, 1.0);
  EXPECT_NE(
      line.find("no video sent | station connected | registration none | realtime 0/0 | eyes off"),
      std::string::npos)
      << line;
}

}  // namespace
}  // namespace telex::remote
