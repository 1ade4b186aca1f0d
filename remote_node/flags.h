// SPDX-License-Identifier: MIT
// telex-remote's flag values that need more than CLI11's own checks: text -> pipeline config.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <string_view>

#include "telex/common/rig.h"
#include "telex/remote/pipeline.h"

namespace telex::remote {

// "none" | "shift" | "full"; throws std::invalid_argument naming the valid values.
RegisterMode parse_register_mode(std::string_view text);

// Builds a RegistrationConfig from the command line's text: mode, eye centre "X,Y,Z" (metres, in
// the depth camera's frame), rotation "RX,RY,RZ" (degrees, applied about x, then y, then z),
// eye intrinsics "FX,FY,CX,CY,W,H" ("" = the source's). Throws std::invalid_argument naming the
// flag and the expected form.
RegistrationConfig parse_registration(std::string_view mode, std::string_view eye_centre_m,
                                      std::string_view rotation_deg, std::string_view eye,
                                      double nominal_depth_m);

// Which registration flags the command line gave (they override the rig).
struct RegistrationFlagsGiven {
  bool mode = false, centre = false, rotation = false, eye = false;
};

// The rig's registration (docs/RIG.md): the right eye's intrinsics (eyes.right), the depth-to-eye
// extrinsics (extrinsics.right_eye_from_depth), the depth's calibrated intrinsics (depth). With
// the extrinsics and no --register, the mode becomes full. Flags given win.
void apply_rig(const Rig& rig, const RegistrationFlagsGiven& given, RegistrationConfig& reg);

// What the rig sets, as the registration flags' defaults in --help (docs/RIG.md: `--help` with
// `--rig` shows the rig's values), and as one line for the start-up log.
void show_rig_defaults(CLI::App& app, const Rig& rig);
std::string describe_rig(const Rig& rig);

}  // namespace telex::remote
