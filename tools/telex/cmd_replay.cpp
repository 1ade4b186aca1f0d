// SPDX-License-Identifier: MIT
// `telex replay FILE.bag`: re-runs the surface build and the force model on a recorded session
// (telex-local --record) with its own parameters or others, and compares with what was recorded.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>

#include "command.h"
#include "telex/cli/processing_flags.h"
#include "telex/local/record/recorder.h"

namespace telex::tool {
namespace {

struct Options {
  std::string bag;
  bool json = false;
  std::optional<double> stiffness, mu_static, mu_dynamic, max_force, max_force_step, ramp,
      stale_limit, damping;
  std::vector<double> friction;
  int bilateral_radius = cli::shipping_bilateral().radius_px;
  bool bilateral_radius_given = false;
  bool no_bilateral = false;
};

// On a terminal (stderr a tty): one line rewritten in place, "telex replay: 42 % (12 s left)",
// cleared at the end. Elsewhere (a log, a pipe, a test) nothing.
local::ReplayProgress progress_line() {
  if (::isatty(STDERR_FILENO) == 0) return {};
  const auto start = std::chrono::steady_clock::now();
  return [start](double done) {
    if (done >= 1.0) {
      std::fprintf(stderr, "\r\033[K");
      return;
    }
    const double elapsed_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double left_s = done > 0.0 ? elapsed_s * (1.0 - done) / done : 0.0;
    std::fprintf(stderr, "\r\033[Ktelex replay: %.0f %% (%.0f s left)", 100.0 * done, left_s);
    std::fflush(stderr);
  };
}

int run(const Options& o) {
  HapticParams haptic;
  local::SurfaceOptions surface;
  double rate_hz = 1000.0;
  local::read_session_config(o.bag, haptic, surface, rate_hz);
  if (!o.friction.empty()) {
    haptic.mu_static = o.friction.at(0);
    haptic.mu_dynamic = o.friction.at(1);
  }
  if (o.stiffness) haptic.stiffness_N_per_m = *o.stiffness;
  if (o.mu_static) haptic.mu_static = *o.mu_static;
  if (o.mu_dynamic) haptic.mu_dynamic = *o.mu_dynamic;
  if (o.max_force) haptic.max_force_N = *o.max_force;
  if (o.max_force_step) haptic.max_force_step_N = *o.max_force_step;
  if (o.ramp) haptic.startup_ramp_s = *o.ramp;
  if (o.stale_limit) haptic.stale_limit_s = *o.stale_limit;
  if (o.damping) haptic.virtual_damping_Ns_per_m = *o.damping;
  if (o.bilateral_radius_given) surface.bilateral_options.radius_px = o.bilateral_radius;
  if (o.no_bilateral) surface.bilateral = false;
  try {
    haptic.validate();
  } catch (const std::invalid_argument& e) {
    std::cerr << "telex replay: " << e.what() << "\n";
    return 2;
  }
  const local::ReplayResult r = local::replay_session(o.bag, haptic, surface, progress_line());
  if (o.json) {
    nlohmann::json j{{"rows", r.rows},
                     {"rms_diff_N", r.rms_diff_N},
                     {"max_diff_N", r.max_diff_N},
                     {"peak_N", r.peak_N},
                     {"recorded_peak_N", r.recorded_peak_N},
                     {"ticks", r.ticks},
                     {"surfaces", r.surfaces},
                     {"unmatched", r.unmatched},
                     {"stiffness_N_per_m", haptic.stiffness_N_per_m},
                     {"mu_static", haptic.mu_static},
                     {"mu_dynamic", haptic.mu_dynamic}};
    std::cout << j.dump() << "\n";
  } else {
    std::printf(
        "%s: %llu ticks on %llu surfaces (stiffness %.1f N/m, friction %.2f/%.2f)\n"
        "  %llu force samples compared: RMS difference %.4f N, max %.4f N\n"
        "  peak |F| replayed %.3f N, recorded %.3f N; %llu recorded samples had no tick\n",
        o.bag.c_str(), static_cast<unsigned long long>(r.ticks),
        static_cast<unsigned long long>(r.surfaces), haptic.stiffness_N_per_m, haptic.mu_static,
        haptic.mu_dynamic, static_cast<unsigned long long>(r.rows), r.rms_diff_N, r.max_diff_N,
        r.peak_N, r.recorded_peak_N, static_cast<unsigned long long>(r.unmatched));
  }
  return 0;
}

const RegisterCommand kRegister{
    "replay",
    "Re-run the surface build and force model on a recorded session (telex-local --record) and "
    "compare with the recorded forces",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto o = std::make_shared<Options>();
      app.add_option("bag", o->bag, "the session, FILE.bag")
          ->required()
          ->check(cli::ExistingFile());
      app.add_flag("--json", o->json,
                   "one JSON object: rows, rms_diff_N, peak_N, recorded_peak_N, ...");
      app.add_option("--stiffness", o->stiffness, "surface stiffness, N/m")
          ->check(cli::Range(1.0, 1e7));
      app.add_option("--friction", o->friction, "MU_S,MU_D: static and dynamic friction")
          ->delimiter(',')
          ->expected(2)
          ->check(cli::Range(0.0, 5.0));
      app.add_option("--mu-static", o->mu_static, "static friction coefficient")
          ->check(cli::Range(0.0, 5.0));
      app.add_option("--mu-dynamic", o->mu_dynamic, "dynamic friction coefficient")
          ->check(cli::Range(0.0, 5.0));
      app.add_option("--max-force", o->max_force, "force clamp, N")->check(cli::Range(0.01, 100.0));
      app.add_option("--max-force-step", o->max_force_step, "force rate limit per tick, N")
          ->check(cli::Range(1e-4, 100.0));
      app.add_option("--ramp", o->ramp, "start-up force ramp, s")->check(cli::Range(0.0, 60.0));
      app.add_option("--stale-limit", o->stale_limit, "surface/tracking age that fades out, s")
          ->check(cli::Range(0.01, 10.0));
      app.add_option("--damping", o->damping, "virtual damping in contact, N s/m")
          ->check(cli::Range(0.0, 1e4));
      cli::add_bilateral_radius(app, o->bilateral_radius)
          ->default_str("the session's")
          ->each([o](const std::string&) { o->bilateral_radius_given = true; });
      app.add_flag("--no-bilateral", o->no_bilateral, "skip the bilateral filter");
      return [o] { return run(*o); };
    }};

}  // namespace
}  // namespace telex::tool
