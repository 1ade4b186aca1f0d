// SPDX-License-Identifier: MIT
// The link's refused messages: each counted by its reason in ClientStats, and the warning that
// names the reason and the totals (the surface client says it at most once a second).
#pragma once

#include <string>

#include "telex/local/link/client_stats.h"
#include "telex/proto/messages.h"
#include "telex/proto/seal.h"

namespace telex::local {

// A sealed datagram that did not open, as the parse result the counters take.
proto::Result unopened(proto::OpenError why);

// Adds `r` (a message the link refused) to its reason's counter.
void count_link_drop(ClientStats& stats, const proto::Result& r);

// "dropped a UDP message from the remote: REASON (DETAIL); totals: ..."
std::string link_drop_warning(const ClientStats& stats, const proto::Result& r,
                              const char* transport);

}  // namespace telex::local
