// SPDX-License-Identifier: MIT
// The haptic displays by --haptics spec: the simulated display, the Gravity Grabber, the UDP
// display. The registry is the one place that knows them all; haptic_display.h is only the
// interface and the spec's grammar.
#pragma once

#include <memory>
#include <string>

#include "telex/local/displays/haptic_display.h"

namespace telex::local {

// Spec grammar (docs/HARDWARE.md): "sim", "sim:CSV", "gravity-grabber:HIDPATH|VID:PID[:SERIAL]",
// "udp:HOST[:PORT]".
// Throws std::invalid_argument for a malformed spec (naming it and the valid forms) and
// std::runtime_error when the device or file cannot be opened (naming it and what to try).
std::unique_ptr<HapticDisplay> make_display(const std::string& spec, const DisplayConfig& config);

}  // namespace telex::local
