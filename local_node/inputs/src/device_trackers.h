// SPDX-License-Identifier: MIT
// The trackers over devices (tracker_registry.cpp makes them by spec): a NatNet server's rigid
// bodies with gloves for the fingers, and a 5DT glove alone with the wrist held still.
#pragma once

#include <memory>
#include <string>

#include "telex/local/inputs/glove.h"
#include "telex/local/inputs/tracker.h"

namespace telex::local {

// spec: natnet:SERVER_IP[,options] (docs/HARDWARE.md); gloves from cfg.glove_spec and
// cfg.other_glove_spec.
std::unique_ptr<HandTracker> make_natnet_tracker(const std::string& spec, const TrackerConfig& cfg);

// A glove alone: the fingers from its bends, the wrist where the configuration puts it.
std::unique_ptr<HandTracker> make_glove_tracker(std::unique_ptr<GloveDevice> glove,
                                                const TrackerConfig& cfg);

}  // namespace telex::local
