// SPDX-License-Identifier: MIT
// The depth-processing flags the daemons, `telex process`, `telex bench` and `telex replay` share:
// one name, one default (the shipping chain's, what the daemons run), one range each.
#pragma once

#include "telex/cli/command_line.h"
#include "telex/common/bilateral.h"
#include "telex/common/hole_fill.h"

namespace telex::cli {

// The shipping chain's defaults: the remote's mode fill, the station's bilateral (radius 6,
// KinectFusion's 13x13 window, docs/BENCHMARKS.md "Defaults").
HoleFillOptions shipping_fill();
BilateralOptions shipping_bilateral();

inline constexpr int kFillWindowMin = 3, kFillWindowMax = 15;
inline constexpr int kFillBinMinMm = 1, kFillBinMaxMm = 1000;
inline constexpr int kFillPassesMin = 1, kFillPassesMax = 64;
inline constexpr int kBilateralRadiusMin = 1, kBilateralRadiusMax = 15;

// --fill-window (odd, px), --fill-bin-mm (hidden alias --fill-bin), --fill-passes. `fill` holds
// the defaults shown (pass shipping_fill()).
void add_fill_flags(CLI::App& app, HoleFillOptions& fill);
void add_fill_flags(const CommandLine& cmd, HoleFillOptions& fill);

// --bilateral-radius (px). Returns it so a caller may say where its default comes from.
CLI::Option* add_bilateral_radius(CLI::App& app, int& radius_px);
Flag add_bilateral_radius(const CommandLine& cmd, int& radius_px);

// --sigma-space-px (alias --sigma-space), --sigma-depth-mm, --noise-sigma, --noise-factor.
void add_bilateral_sigmas(CLI::App& app, BilateralOptions& bilateral);
void add_bilateral_sigmas(const CommandLine& cmd, BilateralOptions& bilateral);

}  // namespace telex::cli
