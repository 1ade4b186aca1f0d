// SPDX-License-Identifier: MIT
// A tracker input that delivers nothing is said once it has been silent 2 s, on the status line
// while it lasts, and in the summary when the run ends silent; one that delivers is not.
#include "input_watch.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace telex::local {
namespace {

constexpr std::int64_t kS = 1'000'000'000;

std::vector<TrackerInput> natnet(std::uint64_t frames) {
  return {
      {frames, "NatNet frames from 10.0.0.5 (unicast, command port 1510)", "is Motive streaming?"}};
}

TEST(InputWatch, AnInputSilentFor2sIsSaidOnTheStatusLineAndInTheSummary) {
  InputWatch w;
  w.update(0, natnet(0));
  w.update(kS, natnet(0));
  EXPECT_EQ(w.status(kS), "");
  w.update(2 * kS, natnet(0));
  EXPECT_EQ(w.status(3 * kS),
            " | no NatNet frames from 10.0.0.5 (unicast, command port 1510) for 3 s");
  EXPECT_EQ(w.summary(3 * kS),
            "no NatNet frames from 10.0.0.5 (unicast, command port 1510) in the whole run: is "
            "Motive streaming?");
}

TEST(InputWatch, AnInputThatDeliversIsNotSaidAndOneThatStopsIsSaidAsSuch) {
  InputWatch w;
  w.update(0, natnet(0));
  for (int i = 1; i <= 10; ++i) w.update(i * kS / 2, natnet(static_cast<std::uint64_t>(i)));
  EXPECT_EQ(w.status(5 * kS), "");
  EXPECT_EQ(w.summary(5 * kS), "");
  // Frames stop at 5 s: silent from 7 s, and said as the last seconds of the run.
  w.update(7 * kS, natnet(10));
  EXPECT_EQ(w.summary(8 * kS),
            "no NatNet frames from 10.0.0.5 (unicast, command port 1510) for the last 3 s of the "
            "run: is Motive streaming?");
  // They come again: nothing to say.
  w.update(9 * kS, natnet(11));
  EXPECT_EQ(w.status(9 * kS), "");
  EXPECT_EQ(w.summary(9 * kS), "");
}

TEST(InputWatch, ATrackerWithoutDeviceInputsSaysNothing) {
  InputWatch w;
  w.update(0, {});
  w.update(10 * kS, {});
  EXPECT_EQ(w.status(10 * kS), "");
  EXPECT_EQ(w.summary(10 * kS), "");
}

}  // namespace
}  // namespace telex::local
