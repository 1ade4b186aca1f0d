// SPDX-License-Identifier: MIT
// The shared depth-processing flags: defined once, used by both daemons and the telex tool.
#include "telex/cli/processing_flags.h"

#include "telex/cli/cli.h"

namespace telex::cli {

HoleFillOptions shipping_fill() { return HoleFillOptions{}; }

BilateralOptions shipping_bilateral() {
  BilateralOptions b;
  b.radius_px = 6;
  return b;
}

void add_fill_flags(CLI::App& app, HoleFillOptions& fill) {
  add(app, "--fill-window", fill.window_px, "Side of the mode fill's square window (odd)", "px")
      ->check(odd_in(kFillWindowMin, kFillWindowMax));
  add(app, "--fill-bin-mm", fill.bin_mm,
      "Depth bin of the mode fill: neighbours within one bin are one surface", "mm")
      ->check(CLI::Range(kFillBinMinMm, kFillBinMaxMm));
  // The old spelling, kept working but out of the help.
  app.add_option("--fill-bin", fill.bin_mm, "deprecated: --fill-bin-mm")
      ->check(CLI::Range(kFillBinMinMm, kFillBinMaxMm))
      ->group("");
  add(app, "--fill-passes", fill.max_passes, "Passes of the mode fill over the remaining holes",
      "passes")
      ->check(CLI::Range(kFillPassesMin, kFillPassesMax));
}

CLI::Option* add_bilateral_radius(CLI::App& app, int& radius_px) {
  return add(app, "--bilateral-radius", radius_px,
             "Bilateral window radius (6 = KinectFusion's 13x13: 4.1 % force error against 9.2 % "
             "at radius 2, docs/BENCHMARKS.md)",
             "px")
      ->check(CLI::Range(kBilateralRadiusMin, kBilateralRadiusMax));
}

void add_bilateral_sigmas(CLI::App& app, BilateralOptions& bilateral) {
  add(app, "--sigma-space-px", bilateral.sigma_space_px, "Bilateral spatial sigma", "px")
      ->check(CLI::Range(0.1, 100.0));
  app.add_option("--sigma-space", bilateral.sigma_space_px, "deprecated: --sigma-space-px")
      ->check(CLI::Range(0.1, 100.0))
      ->group("");
  add(app, "--sigma-depth-mm", bilateral.sigma_depth_mm, "Bilateral depth sigma", "mm")
      ->check(CLI::Range(0.1, 10000.0));
  app.add_flag("--noise-sigma", bilateral.sigma_from_noise_model,
               "Depth sigma per pixel from the Nguyen noise model (x --noise-factor)");
  add(app, "--noise-factor", bilateral.noise_sigma_factor, "Multiplier of the noise sigma",
      "sigmas")
      ->check(CLI::Range(0.1, 100.0));
}

void add_fill_flags(const CommandLine& cmd, HoleFillOptions& fill) {
  add_fill_flags(cmd.app(), fill);
}

Flag add_bilateral_radius(const CommandLine& cmd, int& radius_px) {
  return Flag(add_bilateral_radius(cmd.app(), radius_px));
}

void add_bilateral_sigmas(const CommandLine& cmd, BilateralOptions& bilateral) {
  add_bilateral_sigmas(cmd.app(), bilateral);
}

}  // namespace telex::cli
