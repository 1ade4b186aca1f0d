// SPDX-License-Identifier: MIT
// The daemons as processes for integration tests.
#include "daemons.h"

#include <signal.h>

#include <chrono>
#include <sstream>

#include "test_support.h"

namespace telex::test {

namespace {
std::vector<std::string> remote_argv(std::uint16_t port, std::vector<std::string> extra) {
  // The full stats line: tests read its counters (the default line shows only those not zero).
  std::vector<std::string> a{built_binary("telex-remote").string(), "--listen",
                             "127.0.0.1:" + std::to_string(port), "--stats", "full"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}
}  // namespace

RemoteProcess::RemoteProcess(const std::filesystem::path& dir, std::vector<std::string> extra)
    : RemoteProcess(dir, std::move(extra), free_port()) {}

RemoteProcess::RemoteProcess(const std::filesystem::path& dir, std::vector<std::string> extra,
                             std::uint16_t on_port)
    : port(on_port),
      proc(remote_argv(port, std::move(extra)), dir / "remote.out", dir / "remote.err") {}

RemoteProcess::~RemoteProcess() {
  proc.signal(SIGINT);
  proc.wait(std::chrono::seconds(5));
}

std::vector<std::string> local_args(std::uint16_t port, const std::filesystem::path& dir,
                                    std::vector<std::string> extra) {
  std::vector<std::string> a{built_binary("telex-local").string(),
                             "--connect",
                             "127.0.0.1:" + std::to_string(port),
                             "--haptics",
                             "sim",
                             "--log-forces",
                             (dir / "forces.csv").string(),
                             "--json-summary",
                             "--stale-limit",
                             "1.0"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

nlohmann::json summary_of(const Process& p) {
  // The last line that opens an object (the summary may hold nested objects).
  const std::string out = p.stdout_text();
  std::size_t at = std::string::npos;
  for (std::size_t pos = 0; pos < out.size();) {
    const std::size_t end = out.find('\n', pos);
    if (out[pos] == '{') at = pos;
    if (end == std::string::npos) break;
    pos = end + 1;
  }
  if (at == std::string::npos) return {};
  return nlohmann::json::parse(out.substr(at, out.find('\n', at) - at), nullptr, false);
}

std::string haptic_rate_problem(const nlohmann::json& j, double duration_s) {
  if (!j.is_object() || !j.contains("haptic_span_s")) return "no JSON summary with haptic_span_s";
  const double rate = j["nominal_rate_hz"].get<double>();
  const double span = j["haptic_span_s"].get<double>();
  const double ticks = j["ticks"].get<double>();
  const double missed = j["missed_ticks"].get<double>();
  const double measured = j["haptic_rate_hz"].get<double>();
  const double deadlines = span * rate + 1;
  std::ostringstream why;
  why << "ticks " << ticks << ", missed " << missed << ", span " << span << " s at nominal " << rate
      << " Hz (" << deadlines << " deadlines), measured " << measured << " Hz: ";
  // The loop starts at the first surface (under a couple of seconds on a loaded machine).
  if (span < duration_s - 2.5) return why.str() + "the loop ran for too little of the run";
  // The span runs from the first deadline to the last, and the timer keeps its grid through a
  // miss: every deadline is a tick or a counted miss, exactly (half a tick for the rounding of
  // the span). A tick lost between the loop and the log would show here.
  if (ticks + missed > deadlines + 0.5) return why.str() + "more ticks than deadlines";
  if (ticks + missed + 0.5 < deadlines) return why.str() + "deadlines neither ticked nor missed";
  // The loop as shipped tries SCHED_FIFO; where the machine refuses it (a container without
  // CAP_SYS_NICE), a 2-core machine busy with both daemons wakes the loop late often enough to
  // cost ~10 % of its ticks, so the floor there is 0.8 x nominal (still far above a loop at half
  // rate).
  const bool realtime = j.value("scheduling", "").rfind("SCHED_FIFO", 0) == 0;
  const double floor = realtime ? 0.9 : 0.8;
  if (measured < floor * rate)
    return why.str() + "measured rate below " + std::to_string(floor) + " x nominal (" +
           j.value("scheduling", "?") + ")";
  return {};
}

std::string path_scheduling_problem(const nlohmann::json& j, bool realtime) {
  if (!j.is_object() || !j.contains("thread_scheduling")) return "no thread_scheduling in summary";
  const nlohmann::json& t = j["thread_scheduling"];
  for (const char* name : {"haptic", "surface", "network"})
    if (!t.contains(name)) return std::string("no ") + name + " thread in " + t.dump();
  if (!realtime) {
    for (const auto& [name, how] : t.items())
      if (how != "default scheduling") return name + " thread: " + how.dump();
    return {};
  }
  // Where the machine refuses SCHED_FIFO (no CAP_SYS_NICE), every thread says so.
  if (t["haptic"].get<std::string>().rfind("default scheduling (SCHED_FIFO refused", 0) == 0) {
    for (const auto& [name, how] : t.items())
      if (how.get<std::string>().find("refused") == std::string::npos)
        return name + " thread: " + how.dump() + " while the haptic thread was refused";
    return {};
  }
  if (t["haptic"] != "SCHED_FIFO priority 80") return "haptic thread: " + t["haptic"].dump();
  for (const auto& [name, how] : t.items())
    if (name != "haptic" && how != "SCHED_FIFO priority 70") return name + " thread: " + how.dump();
  return {};
}

}  // namespace telex::test
