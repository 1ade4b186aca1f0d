// SPDX-License-Identifier: MIT
// The trackers by --hand spec: a script, a NatNet server (with gloves), a 5DT glove alone. The
// registry is the one place that knows them all; tracker.h is only the interface.
#pragma once

#include <memory>
#include <string>

#include "telex/local/inputs/tracker.h"

namespace telex::local {

// Spec grammar (docs/HARDWARE.md):
//   script:press | script:stroke | script:tap | script:FILE
//   natnet:SERVER_IP[,multicast|,unicast][,local=IP][,cmd=PORT][,data=PORT][,version=X.Y]
//                                                          (glove from config.glove_spec)
//   5dt-usb[:HIDPATH] | 5dt-serial:DEV                     (glove alone, wrist fixed)
// Throws std::invalid_argument naming the spec and the valid forms; std::runtime_error when a
// device cannot be opened (the message names it and says what to try).
std::unique_ptr<HandTracker> make_tracker(const std::string& spec, const TrackerConfig& config);

// The spec's grammar alone, before anything starts (no device is opened, a script file is only
// checked to exist): throws std::invalid_argument as make_tracker would.
void check_hand_spec(const std::string& spec);

}  // namespace telex::local
