// SPDX-License-Identifier: MIT
// The daemons as processes for integration tests: a remote on a free loopback port, the station's
// usual arguments, and the JSON summary a daemon prints at exit.
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "process.h"

namespace telex::test {

// telex-remote listening on a free loopback port with `extra` arguments (a --source among them);
// stopped with SIGINT when the test ends.
struct RemoteProcess {
  RemoteProcess(const std::filesystem::path& dir, std::vector<std::string> extra);
  ~RemoteProcess();
  std::uint16_t port;
  Process proc;
};

// telex-local's arguments for a station connecting to `port` on loopback, with the sim display,
// forces logged to dir/forces.csv, the JSON summary, default scheduling, and a stale limit that
// tolerates a loaded machine's slow frames (the force model is what these tests check; the
// stale-surface fade has its own test), then `extra`.
std::vector<std::string> local_args(std::uint16_t port, const std::filesystem::path& dir,
                                    std::vector<std::string> extra);

// The JSON object a daemon printed last on stdout (empty when there is none).
nlohmann::json summary_of(const Process& p);

}  // namespace telex::test
