// SPDX-License-Identifier: MIT
// Scripted hands: built-in gestures against their defined geometry, the file format, the tracker.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "process.h"
#include "telex/haptics/haptic_surface.h"
#include "telex/local/inputs/hand_script.h"
#include "telex/local/inputs/tracker_registry.h"

namespace telex::local {
namespace {

std::string error_of(std::string_view text) {
  try {
    HandScript::parse(text, "my.script");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(Script, PressMeetsTheSurfaceAtTheImageCentre) {
  const double d = 0.8;
  const HandScript s = HandScript::builtin("press", d);
  EXPECT_NEAR(s.duration_s(), 3.1 + 1.0 + 3.1, 1e-9);
  double z_max = 0.0, t_at_max = -1.0;
  for (int i = 0; i <= 7200; ++i) {
    const double t = i * 1e-3;
    const glm::dvec3 p = s.position(1, t);
    EXPECT_EQ(p.x, 0.0);
    EXPECT_EQ(p.y, 0.0);
    if (p.z > z_max + 1e-12) {
      z_max = p.z;
      t_at_max = t;
    }
  }
  EXPECT_NEAR(s.position(1, 0.0).z, d - 0.3, 1e-12);
  EXPECT_NEAR(z_max, d + 0.010, 1e-12);
  EXPECT_NEAR(t_at_max, 3.1, 1e-3);
  EXPECT_NEAR(s.position(1, 3.6).z, d + 0.010, 1e-12);  // holding
  EXPECT_NEAR(s.position(1, 7.2).z, d - 0.3, 1e-12);    // back
  HandState st;
  s.sample(1.0, st);
  EXPECT_TRUE(st.tips[1].valid);
  EXPECT_FALSE(st.tips[0].valid);
  EXPECT_FALSE(st.tips[2].valid);
  EXPECT_NEAR(st.tips[1].v_CameraFingertip.z, 0.1, 1e-9);  // approach speed
  s.sample(3.6, st);
  EXPECT_NEAR(glm::length(st.tips[1].v_CameraFingertip), 0.0, 1e-9);
  s.sample(5.0, st);
  EXPECT_NEAR(st.tips[1].v_CameraFingertip.z, -0.1, 1e-9);
  s.sample(0.0, st);  // forward difference at the start
  EXPECT_NEAR(st.tips[1].v_CameraFingertip.z, 0.1, 1e-9);
}

TEST(Script, StrokeSlidesOneHundredMillimetresAtFiveMillimetresDepth) {
  const double d = 1.1;
  const HandScript s = HandScript::builtin("stroke", d);
  double x_max = 0.0;
  for (double t = 0; t <= s.duration_s(); t += 1e-3) {
    const glm::dvec3 p = s.position(1, t);
    x_max = std::max(x_max, p.x);
    if (p.x > 1e-9) {
      EXPECT_NEAR(p.z, d + 0.005, 1e-12) << "slides at constant depth";
    }
  }
  EXPECT_NEAR(x_max, 0.100, 1e-9);
  HandState st;
  const double t_slide = 3.05 + 0.2 + 1.0;  // middle of the outward slide
  s.sample(t_slide, st);
  EXPECT_NEAR(st.tips[1].v_CameraFingertip.x, 0.05, 1e-9);
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.x, 0.05, 1e-9);
  EXPECT_NEAR(s.position(1, s.duration_s()).z, d - 0.3, 1e-12);
}

TEST(Script, TapCrossesTheSurfaceThreeTimes) {
  const double d = 0.7;
  const HandScript s = HandScript::builtin("tap", d);
  int crossings = 0;
  bool inside = false;
  double deepest = 0;
  for (double t = 0; t <= s.duration_s(); t += 1e-3) {
    const double z = s.position(1, t).z;
    deepest = std::max(deepest, z);
    if (!inside && z > d) ++crossings;
    inside = z > d;
  }
  EXPECT_EQ(crossings, 3);
  EXPECT_NEAR(deepest, d + 0.005, 1e-6);
}

TEST(Script, BuiltinRejectsUnknownNamesAndBadDepth) {
  try {
    HandScript::builtin("poke", 0.8);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("press, stroke, tap"), std::string::npos);
  }
  EXPECT_THROW(HandScript::builtin("press", 0.0), std::invalid_argument);
  EXPECT_THROW(HandScript::builtin("press", std::nan("")), std::invalid_argument);
}

TEST(Script, FileFormatParsesAndInterpolates) {
  const HandScript s = HandScript::parse(
      "# two fingers\n"
      "time_s finger x_m y_m z_m\n"
      "0.0 1 0.0 0.0 0.5\n"
      "1.0, 1, 0.1, 0.0, 0.7   # commas work too\n"
      "\n"
      "0.5 0 -0.05 0.02 0.6\n",
      "inline");
  EXPECT_DOUBLE_EQ(s.duration_s(), 1.0);
  EXPECT_TRUE(s.has_finger(0));
  EXPECT_TRUE(s.has_finger(1));
  EXPECT_FALSE(s.has_finger(2));
  const glm::dvec3 p = s.position(1, 0.25);
  EXPECT_NEAR(p.x, 0.025, 1e-12);
  EXPECT_NEAR(p.z, 0.55, 1e-12);
  EXPECT_NEAR(s.position(0, 0.9).x, -0.05, 1e-12);  // single key: constant
}

TEST(Script, ParseErrorsNameTheLine) {
  EXPECT_EQ(error_of("# c\ntime finger x y z\n"),
            "my.script line 2: expected the header 'time_s finger x_m y_m z_m'");
  EXPECT_EQ(error_of("time_s finger x_m y_m z_m\n0 1 0 0 0.5\n0.1 7 0 0 0.5\n"),
            "my.script line 3: finger '7' is not 0..4 (thumb..little)");
  EXPECT_EQ(error_of("time_s finger x_m y_m z_m\n1 1 0 0 0.5\n0.5 1 0 0 0.5\n"),
            "my.script line 3: time goes backwards for this finger");
  EXPECT_EQ(error_of("time_s finger x_m y_m z_m\n0 1 0 0\n"),
            "my.script line 2: expected 5 fields (time_s finger x_m y_m z_m), got 4");
  EXPECT_EQ(error_of("time_s finger x_m y_m z_m\n0 1 0 0 nan\n"),
            "my.script line 2: x_m, y_m, z_m must be finite numbers");
  EXPECT_EQ(error_of("time_s finger x_m y_m z_m\n"), "my.script line 2: no keys after the header");
  EXPECT_NE(error_of("").find("no header"), std::string::npos);
}

TEST(Script, TrackerRunsOnceOrRepeats) {
  ScriptTracker once(HandScript::builtin("press", 0.8), "script:press", false);
  HandState st;
  const std::int64_t t0 = 5'000'000'000;
  ASSERT_TRUE(once.poll(t0, st));
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.5, 1e-12);
  EXPECT_EQ(st.time_ns, t0);
  EXPECT_FALSE(once.poll(t0, st)) << "no newer state at the same time";
  ASSERT_TRUE(once.poll(t0 + 1'000'000'000, st));
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.6, 1e-9);
  ASSERT_TRUE(once.poll(t0 + 9'000'000'000, st));  // past the end: final state once
  EXPECT_TRUE(once.finished());
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.5, 1e-12);
  EXPECT_FALSE(once.poll(t0 + 9'001'000'000, st));
  EXPECT_EQ(once.stats().polls, 5u);
  EXPECT_EQ(once.stats().updates, 3u);

  ScriptTracker loop(HandScript::builtin("press", 0.8), "script:press", true);
  ASSERT_TRUE(loop.poll(0, st));
  ASSERT_TRUE(loop.poll(7'200'000'000 + 1'000'000'000, st));  // one period + 1 s
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.6, 1e-9);
  EXPECT_FALSE(loop.finished());
}

Surface plane_at(double z_m) {
  const Intrinsics k = kinect_v1_intrinsics();
  return make_surface(cv::Mat1f(k.height, k.width, static_cast<float>(z_m)), k, 0, 1);
}

// A press planned against 0.8 m meets a plane at 1.2 m: the gesture slides toward it while the
// fingertip is in front, never faster than the follow speed, and presses 10 mm into it.
TEST(Script, PressAimsAtTheSurfaceItIsShown) {
  const Surface plane = plane_at(1.2);
  ScriptTracker tracker(HandScript::builtin("press", 0.8), "script:press", false);
  const HandScript planned = HandScript::builtin("press", 0.8);
  HandState st;
  double z_max = 0.0, prev_offset = 0.0;
  for (std::int64_t i = 0; i <= 7200; ++i) {
    tracker.see_surface(&plane);
    ASSERT_TRUE(tracker.poll(i * 1'000'000, st));
    const double z = st.tips[1].p_CameraFingertip.z;
    z_max = std::max(z_max, z);
    EXPECT_NEAR(z - planned.position(1, i * 1e-3).z, tracker.aim_offset_m(), 1e-12);
    EXPECT_LE(std::abs(tracker.aim_offset_m() - prev_offset),
              ScriptTracker::kFollowSpeedMps * 1e-3 + 1e-12)
        << "at " << i << " ms";
    prev_offset = tracker.aim_offset_m();
  }
  EXPECT_NEAR(z_max, 1.2 + 0.010, 1e-6);
  EXPECT_NEAR(tracker.aim_offset_m(), 0.4, 1e-6);
}

// A surface that comes at the pressing fingertip does not push the gesture back; one that moves
// away is followed until the press is as deep as planned.
TEST(Script, PressHoldsWhileTouchingAndFollowsASurfaceThatMovedAway) {
  const Surface plane = plane_at(0.8), nearer = plane_at(0.7), farther = plane_at(0.9);
  ScriptTracker tracker(HandScript::builtin("press", 0.8), "script:press", false);
  HandState st;
  std::int64_t t_ms = 0;
  auto run_until = [&](std::int64_t end_ms, const Surface& s) {
    for (; t_ms <= end_ms; ++t_ms) {
      tracker.see_surface(&s);
      ASSERT_TRUE(tracker.poll(t_ms * 1'000'000, st));
    }
  };
  // Depths are floats in a surface: 1e-6 m is their rounding at 1 m.
  run_until(3500, plane);  // pressing 10 mm in, as planned
  EXPECT_NEAR(tracker.aim_offset_m(), 0.0, 1e-6);
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.81, 1e-6);
  const double pressing_offset_m = tracker.aim_offset_m();
  run_until(3600, nearer);  // the surface came at the fingertip: the press holds
  EXPECT_EQ(tracker.aim_offset_m(), pressing_offset_m);
  run_until(3700, farther);  // the surface moved away: 100 ms at the follow speed
  EXPECT_NEAR(tracker.aim_offset_m(), ScriptTracker::kFollowSpeedMps * 0.1, 1e-6);
  run_until(4100, farther);  // until the fingertip is 10 mm in again, as planned
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.91, 1e-6);
  // A tracker shown no surface plays the script as planned.
  ScriptTracker blind(HandScript::builtin("press", 0.8), "script:press", false);
  ASSERT_TRUE(blind.poll(0, st));
  ASSERT_TRUE(blind.poll(3'500'000'000, st));
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.81, 1e-12);
}

TEST(Script, MakeTrackerResolvesNamesAndFiles) {
  TrackerConfig cfg;
  cfg.surface_depth_m = 0.9;
  auto t = make_tracker("script:tap", cfg);
  EXPECT_EQ(t->name(), "script:tap");
  HandState st;
  ASSERT_TRUE(t->poll(0, st));
  EXPECT_NEAR(st.tips[1].p_CameraFingertip.z, 0.6, 1e-12);

  const auto path = ::telex::test::scratch_dir("script") / "script.txt";
  std::ofstream(path) << "time_s finger x_m y_m z_m\n0 2 0.01 0.02 0.4\n";
  auto f = make_tracker("script:" + path.string(), cfg);
  ASSERT_TRUE(f->poll(0, st));
  EXPECT_TRUE(st.tips[2].valid);
  EXPECT_NEAR(st.tips[2].p_CameraFingertip.y, 0.02, 1e-12);
  std::filesystem::remove(path);

  try {
    make_tracker("script:/nonexistent/x.txt", cfg);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/x.txt"), std::string::npos);
  }
  EXPECT_THROW(make_tracker("joystick:0", cfg), std::invalid_argument);
}

}  // namespace
}  // namespace telex::local
