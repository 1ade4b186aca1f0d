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
  // On a port chosen beforehand (a forwarder already points at it).
  RemoteProcess(const std::filesystem::path& dir, std::vector<std::string> extra,
                std::uint16_t on_port);
  ~RemoteProcess();
  std::uint16_t port;
  Process proc;
};

// telex-local's arguments for a station connecting to `port` on loopback, with the sim display,
// forces logged to dir/forces.csv, the JSON summary, and a stale limit that
// tolerates a loaded machine's slow frames (the force model is what these tests check; the
// stale-surface fade has its own test), then `extra`. The haptic loop runs as shipped: SCHED_FIFO
// where the machine grants it.
std::vector<std::string> local_args(std::uint16_t port, const std::filesystem::path& dir,
                                    std::vector<std::string> extra);

// The JSON object a daemon printed last on stdout (empty when there is none).
nlohmann::json summary_of(const Process& p);

// Checks telex-local's summary `j` for a haptic loop that kept its rate over a run of
// `duration_s`: it ticked for most of the run, every deadline of that span was either a tick or a
// counted miss (ticks + missed_ticks = span x nominal rate + 1, to three ticks at the ends and the
// fraction each realignment after a miss drops), and the measured rate is at least 0.9 x the
// nominal rate (0.8 x where SCHED_FIFO was refused). Returns a description of the first failure,
// empty when all hold.
std::string haptic_rate_problem(const nlohmann::json& j, double duration_s);

// Checks telex-local's summary `j` for the scheduling of its depth-to-force threads: with
// `realtime`, where the haptic thread got SCHED_FIFO 80, the surface and network threads got 70;
// without, every thread says "default scheduling". Empty when that holds.
std::string path_scheduling_problem(const nlohmann::json& j, bool realtime);

}  // namespace telex::test
