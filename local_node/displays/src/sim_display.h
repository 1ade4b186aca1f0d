// SPDX-License-Identifier: MIT
// The simulated display (--haptics sim[:CSV]): keeps what a display would have rendered and, with
// a CSV path, writes it from its own thread (the haptic tick only copies into a ring).
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "telex/local/displays/haptic_display.h"

namespace telex::local {

std::unique_ptr<HapticDisplay> open_sim_display(const std::string& csv_path,
                                                std::size_t ring_capacity);

}  // namespace telex::local
