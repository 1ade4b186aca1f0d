// SPDX-License-Identifier: MIT
// `telex warp --check`: the view's depth-image-based warp on a synthetic room with ground truth,
// the operator's head yawing and the robot head lagging; the angular error of world points in the
// displayed image with and without the warp, and the warp's time per eye. Exit 1 when the warp
// misses its bound (0.5 deg), 2 for bad flags.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "command.h"
#include "telex/local/view/warp_check.h"

namespace telex::tool {
namespace {

struct Options {
  bool check = false;
  bool json = false;
  local::WarpCheckOptions check_options;
  double bound_deg = 0.5;
};

// With --pair-gap-ms: the error when the video is warped from the depth's pose instead of its own.
std::string gap_line(const Options& o, const local::WarpCheckResult& r) {
  if (o.check_options.pair_gap_ms <= 0.0) return {};
  char line[160];
  std::snprintf(line, sizeof line,
                "  the depth %.4g ms before the pair: with the depth's pose for the video "
                "%.3f deg mean\n",
                o.check_options.pair_gap_ms, r.error_deg_depth_pose);
  return line;
}

int run(const Options& o) {
  if (!o.check) {
    std::fprintf(stderr, "telex warp: nothing to do: give --check (see telex warp --help)\n");
    return 2;
  }
  const local::WarpCheckResult r = local::run_warp_check(o.check_options);
  const bool pass = r.points_measured > 0 && r.error_deg_with <= o.bound_deg;
  if (o.json) {
    // The keys and their order are the (29): scripts read them as they are.
    nlohmann::ordered_json j;
    const auto number = [](double v) {  // 60, not 60.0, for a whole number
      return v == std::trunc(v) && std::abs(v) < 1e15 ? nlohmann::ordered_json(std::int64_t(v))
                                                      : nlohmann::ordered_json(v);
    };
    j["yaw_deg_s"] = number(o.check_options.yaw_deg_s);
    j["lag_ms"] = number(o.check_options.lag_ms);
    j["error_deg_with"] = r.error_deg_with;
    j["error_deg_without"] = r.error_deg_without;
    j["warp_ms_per_eye"] = r.warp_ms_per_eye;
    // The case of a depth frame and an eye pair captured apart (--pair-gap-ms), after the five.
    if (o.check_options.pair_gap_ms > 0.0) {
      j["pair_gap_ms"] = number(o.check_options.pair_gap_ms);
      j["error_deg_depth_pose"] = r.error_deg_depth_pose;
    }
    std::printf("%s\n", j.dump().c_str());
  } else {
    std::printf(
        "warp check: %dx%d eyes, yaw %.4g deg/s, robot head %.4g ms behind, %d frames\n"
        "  world points measured      %d (%d in view but not found)\n"
        "  error with the warp        %.3f deg mean, %.3f deg max (bound %.3g)\n"
        "  error without the warp     %.3f deg mean\n"
        "%s"
        "  warp per eye               %.2f ms (median)\n"
        "%s\n",
        o.check_options.width, o.check_options.height, o.check_options.yaw_deg_s,
        o.check_options.lag_ms, o.check_options.frames, r.points_measured, r.points_missed,
        r.error_deg_with, r.max_error_deg_with, o.bound_deg, r.error_deg_without,
        gap_line(o, r).c_str(), r.warp_ms_per_eye, pass ? "PASS" : "FAIL");
  }
  return pass ? 0 : 1;
}

const RegisterCommand kRegister{
    "warp",
    "The view's reprojection warp: --check measures world points' angular error on a synthetic "
    "room",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto o = std::make_shared<Options>();
      local::WarpCheckOptions& c = o->check_options;
      app.add_flag("--check", o->check,
                   "run the ground-truth case (exit 1 when the error with the warp exceeds "
                   "--bound-deg)");
      app.add_flag("--json", o->json,
                   "print {\"yaw_deg_s\",\"lag_ms\",\"error_deg_with\",\"error_deg_without\","
                   "\"warp_ms_per_eye\"} instead of the table (with --pair-gap-ms also "
                   "\"pair_gap_ms\",\"error_deg_depth_pose\")");
      app.add_option("--yaw-deg-s", c.yaw_deg_s, "the operator's head's yaw rate, deg/s")
          ->check(cli::Range(-720.0, 720.0))
          ->capture_default_str();
      app.add_option("--lag-ms", c.lag_ms, "how far the robot head lags the operator's, ms")
          ->check(cli::Range(0.0, 1000.0))
          ->capture_default_str();
      app.add_option("--pair-gap-ms", c.pair_gap_ms,
                     "the depth drawn with each eye pair was captured this long before it: the "
                     "video is warped from the pair's own head pose, and for comparison from the "
                     "depth's (error_deg_depth_pose)")
          ->check(cli::Range(0.0, 1000.0))
          ->capture_default_str();
      app.add_option_function(
          "--eye-size",
          [&c](const std::string& text) {
            int w = 0, h = 0;
            char x = 0, extra = 0;
            if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x' ||
                w < 64 || h < 64 || w > 8192 || h > 8192)
              cli::throw_validation_error("--eye-size",
                                          "'" + text + "' is not WxH with each in 64..8192");
            c.width = w;
            c.height = h;
          },
          "each eye's size WxH (default 1280x720)");
      app.add_option("--frames", c.frames, "displayed frames per eye (the first is not timed)")
          ->check(cli::Range(2, 1000))
          ->capture_default_str();
      app.add_option("--grid-step", c.warp.grid_step_px, "one mesh vertex per this many pixels")
          ->check(cli::Range(1, 64))
          ->capture_default_str();
      app.add_option("--bound-deg", o->bound_deg, "the error allowed with the warp, deg")
          ->check(cli::Range(0.0, 90.0))
          ->capture_default_str();
      return [o] { return run(*o); };
    }};

}  // namespace
}  // namespace telex::tool
