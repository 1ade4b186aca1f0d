// SPDX-License-Identifier: MIT
// The daemons' one log setup: spdlog's default logger on stderr, named for the program, with one
// format ("[time] [program] [level] message"). Output for the user (summaries, live values) stays
// on stdout.
#pragma once

#include <string>

namespace telex {

// Call once at the top of main, before any thread logs.
void init_logging(const std::string& program);

}  // namespace telex
