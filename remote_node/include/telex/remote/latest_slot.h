// SPDX-License-Identifier: MIT
// The newest-wins mailbox, shared with the local node (it lives in common/).
#pragma once

#include "telex/common/latest_slot.h"

namespace telex::remote {
using telex::LatestSlot;
}  // namespace telex::remote
